"""Relative blur from radial power profiles: the profile against a NumPy reference, known blurs recovered despite
a translation and a contrast change, the blur against OpenCV, bad input."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from models.dcf import image_noise_std
from models.tracking.blur import RadialPowerProfile, gaussian_blur, radial_power_profile, relative_blur


def _textured(h: int, w: int, seed: int) -> np.ndarray:
    """Random texture with detail at several scales and sharp-edged rectangles, float64 around 128."""
    rng = np.random.default_rng(seed)
    image = sum(cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), s) * s for s in (0.7, 1.5, 4.0))
    image = 128 + 30 * image / image.std()
    for _ in range(20):
        x, y = rng.integers(0, w - 20), rng.integers(0, h - 20)
        image[y : y + rng.integers(5, 20), x : x + rng.integers(5, 20)] += rng.uniform(-60, 60)
    return image


def _profile(image: np.ndarray) -> torch.Tensor:
    return radial_power_profile(torch.from_numpy(image)[None, None])


def _numpy_profile(image: np.ndarray, bins: int) -> np.ndarray:
    """The same profile by NumPy: Hann window, rfft2, rings by np.bincount."""
    h, w = image.shape
    window = np.outer(np.hanning(h), np.hanning(w))
    centred = image - (image * window).sum() / window.sum()
    power = np.abs(np.fft.rfft2(centred * window)) ** 2
    radius = np.hypot(*np.meshgrid(np.fft.fftfreq(h), np.fft.rfftfreq(w), indexing="ij")) * 2 * np.pi
    ring = np.floor(radius * bins / np.pi).astype(int).ravel()
    inside = ring < bins
    count = np.maximum(np.bincount(ring[inside], minlength=bins), 1)
    mean_power = np.bincount(ring[inside], power.ravel()[inside], bins) / count
    mean_radius2 = np.bincount(ring[inside], (radius**2).ravel()[inside], bins) / count
    noise_var = max(float(image_noise_std(torch.from_numpy(image)[None, None], 4)) ** 2, 1 / 12)
    return np.stack([mean_power, np.full(bins, noise_var * (window**2).sum()), mean_radius2])


def test_profile_equals_numpy_reference():
    images = [_textured(61, 90, 0), _textured(61, 90, 1) * 0.5]
    got = radial_power_profile(torch.from_numpy(np.stack(images))[:, None], bins=16)
    assert got.shape == (2, 3, 16)
    for image, profile in zip(images, got.numpy(), strict=True):
        np.testing.assert_allclose(profile, _numpy_profile(image, 16), rtol=1e-9)
    np.testing.assert_allclose(RadialPowerProfile(bins=16)(torch.from_numpy(images[0])[None, None]), got[:1])


@pytest.mark.parametrize("variance", [1.0, 3.0, 8.0])
def test_recovers_a_known_blur_despite_translation_contrast_and_noise(variance):
    rng = np.random.default_rng(2)
    sharp = _textured(200, 260, 3)
    blurred = cv2.GaussianBlur(np.roll(sharp, (7, -12), (0, 1)), (0, 0), np.sqrt(variance)) * 0.6 + 30
    noisy = [f + rng.normal(0, 1.0, f.shape) for f in (sharp, blurred)]
    forward = float(relative_blur(_profile(noisy[0]), _profile(noisy[1])))
    backward = float(relative_blur(_profile(noisy[1]), _profile(noisy[0])))
    assert forward == pytest.approx(variance, rel=0.05)
    assert backward == pytest.approx(-variance, rel=0.05)


def test_no_blur_between_two_views_of_one_scene_and_none_from_flat_frames():
    sharp = _textured(200, 260, 4)
    moved = np.roll(sharp, (3, 5), (0, 1)) * 1.3 - 10
    assert abs(float(relative_blur(_profile(sharp), _profile(moved)))) < 0.1
    flat = np.full((64, 64), 100.0)
    assert float(relative_blur(_profile(flat), _profile(flat + 1))) == 0.0  # nothing above the noise: no change


def test_batched_comparison_equals_one_by_one():
    frames = [_textured(80, 100, s) for s in (5, 6)]
    blurred = [cv2.GaussianBlur(f, (0, 0), s) for f, s in zip(frames, (1.0, 2.0), strict=True)]
    batch = relative_blur(radial_power_profile(torch.from_numpy(np.stack(frames))[:, None]),
                          radial_power_profile(torch.from_numpy(np.stack(blurred))[:, None]))
    single = [float(relative_blur(_profile(f), _profile(b))) for f, b in zip(frames, blurred, strict=True)]
    np.testing.assert_allclose(batch.numpy(), single, rtol=1e-9)


@pytest.mark.parametrize("variance", [0.3, 2.0, 9.0])
def test_gaussian_blur_equals_opencv(variance):
    image = _textured(50, 70, 7).astype(np.float32)
    got = gaussian_blur(torch.from_numpy(image)[None, None], variance)[0, 0].numpy()
    np.testing.assert_allclose(got, cv2.GaussianBlur(image, (0, 0), np.sqrt(variance)), atol=2e-4)


def test_bad_input():
    image = torch.zeros(1, 1, 32, 32)
    assert gaussian_blur(image, 0.0) is image
    with pytest.raises(InputError, match="variance"):
        gaussian_blur(image, -1.0)
    with pytest.raises(InputError, match="radial_power_profile"):
        radial_power_profile(torch.zeros(32, 32))
    with pytest.raises(InputError, match="radial_power_profile"):
        radial_power_profile(torch.zeros(1, 3, 32, 32))
    with pytest.raises(InputError, match="bins"):
        radial_power_profile(image, bins=2)
    with pytest.raises(InputError, match="one shape"):
        relative_blur(radial_power_profile(image), radial_power_profile(image, bins=32))

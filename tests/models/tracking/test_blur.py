"""Relative blur from radial power profiles: the profile against a NumPy reference, known blurs recovered despite
a translation and a contrast change, the blur against OpenCV, bad input."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from models.dcf import image_noise_std
from models.tracking.blur import RadialPowerProfile, block_mean, gaussian_blur, radial_power_profile, relative_blur


def textured(h: int, w: int, seed: int, rectangles: int = 20) -> np.ndarray:
    """Random texture with detail at several scales and ``rectangles`` sharp-edged rectangles, float64 around
    128."""
    rng = np.random.default_rng(seed)
    image = sum(cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), s) * s for s in (0.7, 1.5, 4.0))
    image = 128 + 30 * image / image.std()
    for _ in range(rectangles):
        x, y = rng.integers(0, w - 20), rng.integers(0, h - 20)
        image[y : y + rng.integers(5, 20), x : x + rng.integers(5, 20)] += rng.uniform(-60, 60)
    return image


def _profile(image: np.ndarray) -> torch.Tensor:
    return radial_power_profile(torch.from_numpy(image)[None, None])


def _numpy_profile(image: np.ndarray, bins: int, reduce: int) -> np.ndarray:
    """The same profile by NumPy: block means, Hann window, rfft2, linearly weighted rings by np.bincount."""
    h, w = image.shape[0] // reduce, image.shape[1] // reduce
    image = image[: h * reduce, : w * reduce].reshape(h, reduce, w, reduce).mean((1, 3))
    window = np.outer(np.hanning(h), np.hanning(w))
    centred = image - (image * window).sum() / window.sum()
    power = np.abs(np.fft.rfft2(centred * window)) ** 2
    radius = np.hypot(*np.meshgrid(np.fft.fftfreq(h), np.fft.rfftfreq(w), indexing="ij")) * 2 * np.pi
    position = (radius * bins / np.pi).ravel()
    lower = np.floor(position).astype(int)
    weights = [(lower, 1 - (position - lower)), (lower + 1, position - lower)]  # the two nearest ring centres
    inside = position <= bins - 1
    count, mean_power, mean_radius2 = (sum(np.bincount(i[inside], w[inside] * v.ravel()[inside], bins + 1)
                                           for i, w in weights)[:bins]
                                       for v in (np.ones_like(power), power, radius**2))
    mean_power, mean_radius2 = mean_power / count, mean_radius2 / count / reduce**2
    noise_var = max(float(image_noise_std(torch.from_numpy(image)[None, None], 4)) ** 2, 1 / 12 / reduce**2)
    return np.stack([mean_power, np.full(bins, noise_var * (window**2).sum()), mean_radius2])


@pytest.mark.parametrize(("reduce", "size"), [(1, (97, 131)), (2, (96, 128)), (3, (111, 129))])
def test_profile_equals_numpy_reference(reduce, size):
    images = [textured(*size, 0), textured(*size, 1) * 0.5]
    got = radial_power_profile(torch.from_numpy(np.stack(images))[:, None], bins=16, reduce=reduce)
    assert got.shape == (2, 3, 16)
    for image, profile in zip(images, got.numpy(), strict=True):
        np.testing.assert_allclose(profile, _numpy_profile(image, 16, reduce), rtol=1e-9)
    module = RadialPowerProfile(bins=16, reduce=reduce)
    np.testing.assert_allclose(module(torch.from_numpy(images[0])[None, None]), got[:1])


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize(("reduce", "shape"), [(2, (2, 1, 37, 50)), (3, (1, 2, 31, 62)), (4, (1, 1, 16, 19))])
def test_block_mean_equals_average_pooling(monkeypatch, dtype, reduce, shape):
    # eager strided slices and the exported pooling against F.avg_pool2d itself; on the CPU equal to the bit
    from models.tracking import blur

    image = (torch.rand(shape, generator=torch.Generator().manual_seed(reduce)) * 255).to(dtype)
    expected = torch.nn.functional.avg_pool2d(image, reduce)
    assert torch.equal(block_mean(image, reduce), expected)
    monkeypatch.setattr(blur, "exporting", lambda: True)
    assert torch.equal(block_mean(image, reduce), expected)


@pytest.mark.parametrize("variance", [1.0, 3.0, 8.0])
@pytest.mark.parametrize(("reduce", "tolerance"), [(1, 0.05), (2, 0.2)])
def test_recovers_a_known_blur_despite_translation_contrast_and_noise(variance, reduce, tolerance):
    """Within a few per cent on the full-resolution spectrum; the 2 x 2 block means (the default) read about
    0.1-0.2 px^2 low."""
    rng = np.random.default_rng(2)
    sharp = textured(200, 260, 3)
    blurred = cv2.GaussianBlur(np.roll(sharp, (7, -12), (0, 1)), (0, 0), np.sqrt(variance)) * 0.6 + 30
    sharp, blurred = (torch.from_numpy(f + rng.normal(0, 1.0, f.shape))[None, None] for f in (sharp, blurred))
    profiles = [radial_power_profile(f, reduce=reduce) for f in (sharp, blurred)]
    forward, backward = float(relative_blur(*profiles)), float(relative_blur(*profiles[::-1]))
    assert forward == pytest.approx(variance, rel=tolerance)
    assert backward == pytest.approx(-variance, rel=tolerance)


def test_no_blur_between_two_views_of_one_scene_and_none_from_flat_frames():
    sharp = textured(200, 260, 4)
    moved = np.roll(sharp, (3, 5), (0, 1)) * 1.3 - 10
    assert abs(float(relative_blur(_profile(sharp), _profile(moved)))) < 0.1
    flat = np.full((64, 64), 100.0)
    assert float(relative_blur(_profile(flat), _profile(flat + 1))) == 0.0  # nothing above the noise: no change


def test_batched_comparison_equals_one_by_one():
    frames = [textured(80, 100, s) for s in (5, 6)]
    blurred = [cv2.GaussianBlur(f, (0, 0), s) for f, s in zip(frames, (1.0, 2.0), strict=True)]
    batch = relative_blur(radial_power_profile(torch.from_numpy(np.stack(frames))[:, None]),
                          radial_power_profile(torch.from_numpy(np.stack(blurred))[:, None]))
    single = [float(relative_blur(_profile(f), _profile(b))) for f, b in zip(frames, blurred, strict=True)]
    np.testing.assert_allclose(batch.numpy(), single, rtol=1e-9)


@pytest.mark.parametrize("variance", [0.3, 2.0, 9.0])
def test_gaussian_blur_equals_opencv(variance):
    image = textured(50, 70, 7).astype(np.float32)
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
    with pytest.raises(InputError, match="reduce"):
        radial_power_profile(image, reduce=5)
    with pytest.raises(InputError, match="one shape"):
        relative_blur(radial_power_profile(image), radial_power_profile(image, bins=32))

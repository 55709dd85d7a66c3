"""The straight motion blur of a frame from its power cepstrum: known streaks recovered in length and direction
despite noise and a translation, no streak found in sharp, defocused or (heavily) compressed frames, batches, the
exported graph's matrix-product cepstrum against the FFTs, bad input."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from core.streak import streak_blur, streak_found
from models.tracking import motion_blur
from models.tracking.motion_blur import MotionBlurStreak, motion_blur_streak
from tests.models.tracking.test_blur import textured


def _textured(h: int, w: int, seed: int) -> np.ndarray:
    return textured(h, w, seed, rectangles=30).astype(np.float32)


def _camera(image: np.ndarray, seed: int) -> torch.Tensor:
    """Sensor noise of std 1 and 8-bit rounding, as a (1, 1, H, W) tensor."""
    noisy = image + np.random.default_rng(seed).normal(0, 1, image.shape)
    return torch.from_numpy(np.clip(noisy, 0, 255).round().astype(np.float32))[None, None]


@pytest.mark.parametrize(("length", "angle"), [(6.0, 0.0), (9.0, 0.6), (14.0, 2.2), (20.0, np.pi / 2)])
def test_recovers_a_known_streak(length, angle):
    image = np.roll(_textured(240, 320, 1), (9, -14), (0, 1))
    got_length, got_angle, score, rival = motion_blur_streak(_camera(streak_blur(image, length, angle), 2))[0].tolist()
    assert got_length == pytest.approx(length, abs=0.6)
    assert abs((got_angle - angle + np.pi / 2) % np.pi - np.pi / 2) < 0.08
    assert score < -10 and rival > -5 and streak_found(got_length, got_angle, score, rival, -10)


def _jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    encoded = cv2.imencode(".jpg", image.clip(0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, quality])[1]
    return cv2.imdecode(encoded, cv2.IMREAD_GRAYSCALE).astype(np.float32)


def test_no_streak_in_sharp_defocused_or_compressed_frames():
    """The block grid of quality 3 leaves deep cepstral minima, but at lattice points in several directions."""
    image = _textured(240, 320, 3)
    for frame in (image, cv2.GaussianBlur(image, (0, 0), 2.0), _jpeg(image, 20)):
        assert motion_blur_streak(_camera(frame, 4))[0, 2] > -10
    for seed in range(3):
        reading = motion_blur_streak(torch.from_numpy(_jpeg(_textured(240, 320, seed), 3))[None, None])[0]
        assert not streak_found(*reading.tolist(), -10)


def test_batches_and_module():
    images = [streak_blur(_textured(200, 260, 5), 10.0, 1.0), _textured(200, 260, 6)]
    batch = torch.cat([_camera(f, 7) for f in images])
    together = motion_blur_streak(batch)
    for i in range(2):
        torch.testing.assert_close(together[i], motion_blur_streak(batch[i : i + 1])[0])
    torch.testing.assert_close(MotionBlurStreak()(batch), together)


@pytest.mark.parametrize(("h", "w"), [(64, 80), (63, 81), (150, 203)])
def test_cepstrum_by_products_equals_the_ffts(h, w):
    """The power cepstrum of the exported graph (matrix products, only the columns read) against ``rfft2`` of the
    log of ``fft2``'s power, in float64, at even and odd sizes."""
    image = torch.randn(2, h, w, dtype=torch.float64, generator=torch.Generator().manual_seed(h))
    noise = torch.tensor([0.5, 20.0], dtype=torch.float64)
    spectrum = torch.fft.fft2(image)
    want = torch.fft.rfft2(torch.log(spectrum.real.square() + spectrum.imag.square() + noise[:, None, None])).real
    got = motion_blur._cepstrum_by_products(image, noise, 26)
    assert got.shape == (2, h, 26)
    torch.testing.assert_close(got, want[..., :26], rtol=0, atol=1e-9 * float(want.abs().max()))


def test_export_path_reads_the_same_streak(monkeypatch):
    """:func:`motion_blur_streak` with the export path's cepstrum gives the eager path's reading, streak or none."""
    frames = [_camera(streak_blur(_textured(150, 203, 3), 11.0, 0.7), 1), _camera(_textured(97, 131, 4), 2)]
    want = [motion_blur_streak(f) for f in frames]
    monkeypatch.setattr(motion_blur, "exporting", lambda: True)
    for frame, reading in zip(frames, want, strict=True):
        torch.testing.assert_close(motion_blur_streak(frame), reading, rtol=1e-3, atol=1e-3)
    assert want[0][0, 2] < -10 < want[1][0, 2]  # the first has a streak, the second none


def test_bad_input():
    with pytest.raises(InputError, match="larger than 48"):
        motion_blur_streak(torch.zeros(1, 1, 40, 200))
    with pytest.raises(InputError, match="gray"):
        motion_blur_streak(torch.zeros(1, 3, 100, 100))
    with pytest.raises(InputError, match="min_length"):
        motion_blur_streak(torch.zeros(1, 1, 100, 100), min_length=30, max_length=24)

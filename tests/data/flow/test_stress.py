"""Stress conditions for point tracking: seeded, each one a real change of the plain sequence, ground truth that
holds (blur centred on it, hidden points removed), bad names refused."""

import math

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.flow import STRESS_CONDITIONS, stress_frames, stress_sequence, synthetic_sequence
from tests.data.flow.test_synthetic import photometric_errors

SIZE = (96, 128)


@pytest.mark.parametrize("condition", STRESS_CONDITIONS)
def test_seeded_and_different_from_the_moderate_base(condition):
    a = stress_sequence(condition, frames=4, size=SIZE, seed=2)
    b = stress_sequence(condition, frames=4, size=SIZE, seed=2)
    np.testing.assert_array_equal(a.frames, b.frames)
    assert a.frames.dtype == np.float32 and a.frames.min() >= 0 and a.frames.max() <= 255
    base = synthetic_sequence(frames=len(a.frames), size=SIZE, seed=2, max_motion=8.0)
    if condition != "long":  # long is the base itself, only longer
        assert not np.array_equal(a.frames, base.frames)
    assert len(a.frames) == (60 if condition == "long" else 4)


def test_dark_and_low_contrast_reduce_the_contrast():
    base = synthetic_sequence(frames=3, size=SIZE, seed=1, max_motion=8.0).frames
    dark = stress_sequence("dark", frames=3, size=SIZE, seed=1).frames
    low = stress_sequence("low_contrast", frames=3, size=SIZE, seed=1).frames
    assert dark.mean() < 0.3 * base.mean() and dark.std() < 0.3 * base.std()
    assert abs(low.mean() - base.mean()) < 0.3 * base.std() and low.std() < 0.3 * base.std()


def test_motion_blur_is_centred_on_the_ground_truth():
    """Exposure blurs along the motion but keeps every point's intensity where the ground truth says it is,
    better than one pixel off (noise, defocus and gain off)."""
    seq = synthetic_sequence(frames=5, size=(128, 160), max_motion=12.0, blur=0, noise=0, brightness=0, seed=5,
                             exposure=0.6)
    sharp = synthetic_sequence(frames=5, size=(128, 160), max_motion=12.0, blur=0, noise=0, brightness=0, seed=5)

    def gradient(frames):
        return np.abs(np.diff(frames, axis=1)).mean() + np.abs(np.diff(frames, axis=2)).mean()

    assert gradient(seq.frames[1:-1]) < 0.85 * gradient(sharp.frames[1:-1])
    points = np.random.default_rng(1).uniform(30, 100, (2000, 2))
    for t, (err, off) in enumerate(photometric_errors(seq, points, (1.0, 1.0)), 1):
        assert err < off, (t, err, off)


def test_occluded_points_lose_their_ground_truth():
    seq = stress_sequence("occlusion", frames=6, size=(128, 160), seed=3)
    assert seq.occluder.shape == seq.frames.shape and seq.occluder.any()
    points = np.random.default_rng(0).uniform(0, 127, (3000, 2))
    tracks, valid = seq.track(points)
    hidden = seq.hidden(tracks)
    for t in range(6):  # brute force: a point is hidden where the occluder covers its nearest pixel
        for p in range(0, 3000, 37):
            x, y = np.rint(tracks[t, p]).astype(int)
            inside = 0 <= x < 160 and 0 <= y < 128
            assert hidden[t, p] == (inside and seq.occluder[t, y, x])
    assert not (valid & np.logical_or.accumulate(hidden, axis=0)).any()  # once hidden, never valid again
    assert hidden.any(0).sum() > 30  # the discs really cover points


def test_unknown_condition_and_bad_exposure():
    with pytest.raises(InputError, match="unknown stress condition"):
        stress_sequence("fog")
    with pytest.raises(InputError, match="exposure"):
        synthetic_sequence(frames=2, exposure=1.5)


def test_stress_frames_degrade_real_frames_as_the_stress_sequences():
    """``stress_frames`` gives a sequence's frames exactly the stress sequence's degradation; on a flat gray frame
    the dark condition has the closed-form mean ``0.15 s`` and variance ``0.6 (0.15 s) + 1.5^2``."""
    for condition, render in (("low_contrast", {}), ("illumination", {"brightness": 0.0}), ("jpeg", {})):
        base = synthetic_sequence(frames=3, size=SIZE, seed=4, max_motion=8.0, **render)
        np.testing.assert_array_equal(stress_frames(base.frames, condition, seed=4),
                                      stress_sequence(condition, frames=3, size=SIZE, seed=4).frames)
    flat = np.full((2, 200, 200), 100.0)
    dark = stress_frames(flat, "dark", seed=1)
    assert dark.dtype == np.float32 and dark.shape == flat.shape
    assert abs(dark.mean() - 15.0) < 0.1 and abs(dark.var() - (0.6 * 15 + 1.5**2)) < 0.3
    np.testing.assert_array_equal(dark, stress_frames(flat, "dark", seed=1))  # seeded
    assert not np.array_equal(dark, stress_frames(flat, "dark", seed=2))


def test_dark_jpeg_is_the_dark_condition_thinned_by_the_codec():
    """On a flat gray frame ``dark_jpeg`` keeps the dark condition's mean ``0.15 s`` and most of its noise (std
    ``sqrt(0.6 (0.15 s) + 1.5^2)``), but a noise estimate from the finest pixel differences (the median absolute
    response to the 3 x 3 Laplacian difference, ``6 * 0.6745 sigma`` for white noise of std ``sigma``) reads under
    half of it: the codec removed the noise's highest frequencies. Its frames are JPEG's: coded again at quality
    90 they hardly change."""
    flat = np.full((2, 200, 200), 100.0)
    frames = stress_frames(flat, "dark_jpeg", seed=1)
    noise = math.sqrt(0.6 * 15 + 1.5**2)
    assert abs(frames.mean() - 15.0) < 0.3 and 0.7 * noise < frames.std() < 0.95 * noise, frames.std()
    kernel = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])

    def finest(frame: np.ndarray) -> float:
        return float(np.median(np.abs(cv2.filter2D(frame.astype(np.float64), -1, kernel)[1:-1, 1:-1]))) / (6 * 0.6745)

    dark = finest(stress_frames(flat, "dark", seed=1)[0])
    assert finest(frames[0]) < 0.5 * dark and abs(dark - noise) < 0.05 * noise, (finest(frames[0]), dark)
    frame = frames[0].astype(np.uint8)
    again = cv2.imdecode(cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 90])[1], cv2.IMREAD_GRAYSCALE)
    assert np.abs(again.astype(int) - frame).mean() < 0.5


def test_stress_frames_refuse_motion_conditions_and_bad_shapes():
    with pytest.raises(InputError, match="photometric stress condition 'fast_motion'"):
        stress_frames(np.zeros((2, 8, 8)), "fast_motion")
    with pytest.raises(InputError, match=r"\(T, H, W\).*\(8, 8\)"):
        stress_frames(np.zeros((8, 8)), "dark")

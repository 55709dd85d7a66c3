"""Synthetic sequences: seeded, large motion, and ground truth that is photometrically consistent."""

import numpy as np
import pytest

from core.errors import InputError
from data.flow import sample_bilinear, synthetic_sequence


def test_seeded_and_large_motion():
    a = synthetic_sequence(frames=20, size=(96, 128), seed=3)
    b = synthetic_sequence(frames=20, size=(96, 128), seed=3)
    c = synthetic_sequence(frames=20, size=(96, 128), seed=4)
    assert a.frames.shape == (20, 96, 128)
    np.testing.assert_array_equal(a.frames, b.frames)
    assert not np.array_equal(a.frames, c.frames)
    points = np.random.default_rng(0).uniform(10, 80, (200, 2))
    tracks, valid = a.track(points)
    motion = np.linalg.norm(np.diff(tracks, axis=0), axis=2)
    assert 20 < motion.max() < 50
    assert valid[0].all() and not valid[-1].all()  # large motion carries some points out of view


def photometric_errors(seq, points: np.ndarray, offset: tuple[float, float]) -> list[tuple[float, float]]:
    """Per frame after the first: the mean intensity change of the points followed along their ground truth, and
    the same with the ground truth moved by ``offset`` px (over the points valid in that frame)."""
    tracks, valid = seq.track(points)
    start = sample_bilinear(seq.frames[0], points)
    out = []
    for t in range(1, len(seq.frames)):
        v = valid[t]
        err = np.abs(sample_bilinear(seq.frames[t], tracks[t]) - start)[v].mean()
        off = np.abs(sample_bilinear(seq.frames[t], tracks[t] + np.asarray(offset)) - start)[v].mean()
        out.append((err, off))
    return out


def test_ground_truth_is_photometrically_consistent():
    seq = synthetic_sequence(frames=6, size=(128, 160), blur=0, noise=0, brightness=0, seed=5)
    points = np.random.default_rng(1).uniform(20, 100, (2000, 2))
    for t, (err, off) in enumerate(photometric_errors(seq, points, (0.3, 0.0)), 1):
        assert err < 0.5 * off, (t, err, off)


def test_bad_arguments():
    with pytest.raises(InputError, match="at least 2 frames"):
        synthetic_sequence(frames=1)
    with pytest.raises(InputError, match="shape"):
        synthetic_sequence(frames=2, size=(64, 64)).track(np.zeros((3, 3)))

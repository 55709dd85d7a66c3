"""``core.good_features``: OpenCV's Shi-Tomasi start points, checked against where the corners are."""

import numpy as np
import pytest

from core.errors import InputError
from core.good_features import good_features


def _rectangles() -> np.ndarray:
    image = np.zeros((80, 120), np.float32)
    image[20:50, 30:90] = 200.0  # corners at (29.5 | 89.5, 19.5 | 49.5)
    return image


def test_the_corners_of_a_rectangle_are_found_strongest_first():
    points = good_features(_rectangles(), 10)
    assert points.shape == (4, 2) and points.dtype == np.float64  # a rectangle has 4 corners and nothing else
    corners = np.array([[x, y] for x in (29.5, 89.5) for y in (19.5, 49.5)])
    distance = np.linalg.norm(points[:, None] - corners[None], axis=-1)
    assert (distance.min(1) <= 1.5).all() and len(set(distance.argmin(1))) == 4
    assert len(good_features(_rectangles(), 2)) == 2


def test_points_keep_their_distance_and_the_count():
    frame = np.random.default_rng(0).uniform(0, 255, (64, 64))
    points = good_features(frame, 50, min_distance=6)
    assert len(points) == 50
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(50) * 1e9
    assert gaps.min() >= 6


@pytest.mark.parametrize(("frame", "count", "message"), [
    (np.zeros((40, 40)), 5, "no good features"),
    (np.zeros((40, 40, 3)), 5, "gray"),
    (_rectangles(), 0, "positive number"),
])
def test_bad_input_is_named(frame, count, message):
    with pytest.raises(InputError, match=message):
        good_features(frame, count)

"""camera_turn: the closed form against a brute-force weighted least-squares fit (numpy), exact similarities,
translations and bad input."""

import math

import numpy as np
import pytest
import torch

from core.errors import InputError
from models.tracking.turn import CameraTurn, camera_turn, fit_similarity


def _similar(points: np.ndarray, angle: float, scale: float, shift: tuple[float, float]) -> np.ndarray:
    c, s = scale * math.cos(angle), scale * math.sin(angle)
    return points @ np.array([[c, s], [-s, c]]) + np.array(shift)


def _reference(start: np.ndarray, moved: np.ndarray, weight: np.ndarray) -> float:
    """The 4-parameter similarity by a weighted least-squares solve, and the share of the steps' spread about
    the mean step that it removes."""
    rows, targets = [], []
    for (x, y), (u, v) in zip(start, moved, strict=True):
        rows += [[x, -y, 1, 0], [y, x, 0, 1]]
        targets += [u, v]
    root = np.sqrt(np.repeat(weight, 2))
    a, b, tx, ty = np.linalg.lstsq(np.array(rows) * root[:, None], np.array(targets) * root, rcond=None)[0]
    fitted = start @ np.array([[a, b], [-b, a]]) + [tx, ty]
    left = (weight * ((moved - fitted) ** 2).sum(1)).sum()
    steps = moved - start
    mean_step = (weight[:, None] * steps).sum(0) / weight.sum()
    spread = (weight * ((steps - mean_step) ** 2).sum(1)).sum()
    return (1 - left / spread) * math.hypot(math.atan2(b, a), math.log(math.hypot(a, b)))


def test_matches_a_weighted_least_squares_solve():
    rng = np.random.default_rng(0)
    start = rng.uniform(0, 300, (3, 40, 2))
    moved = np.stack([_similar(p, a, s, (5.0, -3.0)) for p, a, s in zip(start, (0.05, -0.12, 0.0), (1.03, 0.9, 1.0),
                                                                          strict=True)])
    moved += rng.normal(0, 1.5, moved.shape)  # tracking errors: the fit explains only part of the steps
    weight = (rng.uniform(size=(3, 40)) > 0.2) * rng.uniform(0.5, 2.0, (3, 40))
    turn = camera_turn(*(torch.from_numpy(x) for x in (start, moved, weight)))
    expected = [_reference(*args) for args in zip(start, moved, weight, strict=True)]
    np.testing.assert_allclose(turn.numpy(), expected, rtol=1e-9)
    assert 0 < turn[2] < 0.02 < turn[0] < turn[1]  # the unturned batch reads only its noise


@pytest.mark.parametrize(("dtype", "rel"), [(torch.float32, 1e-4), (torch.float64, 1e-10)])
def test_an_exact_similarity_turns_by_its_angle_and_log_scale(dtype, rel):
    rng = np.random.default_rng(1)
    start = rng.uniform(-100, 100, (25, 2))
    moved = _similar(start, math.radians(6.0), 1.05, (12.0, 7.0))
    turn = CameraTurn()(*(torch.tensor(x, dtype=dtype) for x in (start, moved, np.ones(25))))
    assert turn.dtype == dtype
    assert turn.item() == pytest.approx(math.hypot(math.radians(6.0), math.log(1.05)), rel=rel)


def test_a_translation_or_a_single_point_does_not_turn():
    start = torch.rand(30, 2, dtype=torch.float64) * 100
    assert camera_turn(start, start + torch.tensor([4.0, -2.0], dtype=torch.float64), torch.ones(30)).item() == 0
    weight = torch.zeros(30)
    weight[3] = 1
    turned = torch.tensor(_similar(start.numpy(), 0.3, 1.2, (0.0, 0.0)))
    assert camera_turn(start, turned, weight).item() == 0
    assert camera_turn(start, turned, torch.zeros(30)).item() == 0


def test_fewer_points_than_asked_do_not_turn():
    """``min_points`` counts the points that weigh in: 9 of 30 read 0 where 10 are asked, 10 read the turn of those
    10 alone (the same as with every other weight 0 and no minimum)."""
    start = torch.rand(30, 2, dtype=torch.float64) * 100
    turned = torch.tensor(_similar(start.numpy(), 0.1, 1.05, (3.0, -1.0)))
    for count in (9, 10):
        weight = (torch.arange(30) < count).double()
        plain = camera_turn(start, turned, weight)
        assert plain.item() == pytest.approx(math.hypot(0.1, math.log(1.05)), rel=1e-9)
        assert camera_turn(start, turned, weight, 10).item() == (0 if count < 10 else plain.item())
        assert CameraTurn(10)(start, turned, weight).item() == camera_turn(start, turned, weight, 10).item()


def test_bad_shapes_refused():
    with pytest.raises(InputError, match="start and moved"):
        camera_turn(torch.zeros(5, 2), torch.zeros(5, 3), torch.ones(5))
    with pytest.raises(InputError, match="weight"):
        camera_turn(torch.zeros(5, 2), torch.zeros(5, 2), torch.ones(4))


def test_fit_similarity_maps_the_points_as_cv2_estimates():
    """An exact similarity is recovered, and on noisy steps the fit equals OpenCV's least-squares estimate
    (``cv2.estimateAffinePartial2D`` with every point an inlier, refined by Levenberg-Marquardt)."""
    import cv2

    rng = np.random.default_rng(3)
    start = rng.uniform(0, 200, (50, 2))
    exact = _similar(start, 0.2, 1.1, (4.0, -6.0))
    matrix = fit_similarity(torch.from_numpy(start), torch.from_numpy(exact), torch.ones(50, dtype=torch.float64))
    np.testing.assert_allclose((start @ matrix[:, :2].numpy().T) + matrix[:, 2].numpy(), exact, atol=1e-9)
    noisy = exact + rng.normal(0, 0.5, exact.shape)
    fitted = fit_similarity(torch.from_numpy(start), torch.from_numpy(noisy), torch.ones(50, dtype=torch.float64))
    reference, inliers = cv2.estimateAffinePartial2D(start, noisy, method=cv2.LMEDS, refineIters=100)
    assert inliers.all()
    np.testing.assert_allclose(fitted.numpy(), reference, atol=1e-5)  # OpenCV stops its refinement near 1e-6

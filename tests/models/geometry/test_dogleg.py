import numpy as np
import pytest
import torch

from data.sfm.synthetic import synthetic_cube_scene
from models.geometry import TriangulateDogleg, triangulate_dogleg, triangulate_midpoint, triangulate_polynomial
from models.geometry.projection import reprojection_cost


def levenberg_marquardt_reference(P: np.ndarray, x: np.ndarray, X0: np.ndarray, iterations: int = 50) -> np.ndarray:
    """Independent fp64 Levenberg-Marquardt in numpy (analytic Jacobian, np.linalg.solve), vectorised over points.

    P: (N, 3, 4) shared cameras; x: (B, N, 2); X0: (B, 3). Returns the final cost (B,).
    """

    def residuals(X):
        Xh = np.concatenate((X, np.ones((len(X), 1))), 1)
        p = np.einsum("nij,bj->bni", P, Xh)
        return p[..., :2] / p[..., 2:] - x, p

    X = X0.copy()
    mu = np.full(len(X), 1e-3)
    r, p = residuals(X)
    cost = (r**2).sum((1, 2))
    for _ in range(iterations):
        w = p[..., 2:]
        J = (P[None, :, :2, :3] - (p[..., :2] / w)[..., None] * P[None, :, 2:3, :3]) / w[..., None]
        J = J.reshape(len(X), -1, 3)
        g = np.einsum("bki,bk->bi", J, r.reshape(len(X), -1))
        H = np.einsum("bki,bkj->bij", J, J)
        step = -np.linalg.solve(H + mu[:, None, None] * np.eye(3), g[..., None])[..., 0]
        r_new, p_new = residuals(X + step)
        cost_new = (r_new**2).sum((1, 2))
        better = cost_new < cost
        X = np.where(better[:, None], X + step, X)
        r = np.where(better[:, None, None], r_new, r)
        p = np.where(better[:, None, None], p_new, p)
        cost = np.where(better, cost_new, cost)
        mu = np.where(better, mu / 10, mu * 10)
    return cost


@pytest.mark.slow
def test_dogleg_reaches_the_optimum():
    """Must show 2: on 1e5 3-view points (sigma 1 px), >= 99.9 % within 1e-6 of a 50-iteration fp64 LM."""
    s = synthetic_cube_scene(100_000, num_views=3, noise_px=1.0, seed=11)
    start = triangulate_midpoint(s.cameras, s.observations).points
    reference = levenberg_marquardt_reference(s.cameras[0].numpy(), s.observations.numpy(), start.numpy())
    result = triangulate_dogleg(s.cameras, s.observations)
    rel = (result.cost.numpy() - reference) / reference
    assert (rel <= 1e-6).mean() >= 0.999
    assert result.converged.float().mean() >= 0.999
    # fp32 ends at the same optimum up to fp32 rounding of the inputs.
    r32 = triangulate_dogleg(s.cameras.float(), s.observations.float())
    cost32 = reprojection_cost(s.cameras, r32.points.double(), s.observations).numpy()
    assert (np.abs(cost32 - reference) / reference <= 1e-4).mean() >= 0.999


def test_dogleg_beats_two_view_methods_and_midpoint():
    s = synthetic_cube_scene(20_000, num_views=3, noise_px=1.0, seed=5)
    dog = triangulate_dogleg(s.cameras, s.observations)
    mid3 = triangulate_midpoint(s.cameras, s.observations)
    poly = triangulate_polynomial(s.cameras[:, :2], s.observations[:, :2])

    def median_error(points):
        return (points - s.points).norm(dim=-1).median()

    assert median_error(dog.points) < median_error(poly.points)
    assert (dog.cost <= mid3.cost + 1e-9).all()


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_module_with_fixed_iterations_and_per_point_cameras(dtype):
    s = synthetic_cube_scene(300, num_views=4, noise_px=0.5, seed=2, dtype=dtype)
    P = s.cameras.expand(300, -1, -1, -1).contiguous()
    a = TriangulateDogleg(iterations=5)(P, s.observations)
    b = triangulate_dogleg(s.cameras, s.observations, iterations=5, early_exit=False)
    torch.testing.assert_close(a.points, b.points)
    assert a.points.dtype == dtype and a.valid.all() and a.converged.all()


def test_bad_input_is_flagged_not_crashing():
    s = synthetic_cube_scene(6, num_views=3, noise_px=1.0)
    x = s.observations.clone()
    P = s.cameras.expand(6, -1, -1, -1).clone()
    x[0, 1, 0] = float("nan")
    P[1, 2] = float("inf")
    P[2, 0] = -P[2, 0]  # point behind that camera
    result = triangulate_dogleg(P, x)
    assert result.valid.tolist() == [False, False, False, True, True, True]
    assert torch.isfinite(result.points).all()
    with pytest.raises(ValueError, match="at least 2 views"):
        triangulate_dogleg(P[:, :1], x[:, :1])
    with pytest.raises(ValueError, match=r"\(B, N, 3, 4\)"):
        triangulate_dogleg(P[..., :3], x)
    with pytest.raises(ValueError, match="batch size"):
        triangulate_dogleg(P[:2], x)
    with pytest.raises(ValueError, match="dtype"):
        triangulate_dogleg(P.float(), x)

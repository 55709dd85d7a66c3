import cv2
import numpy as np
import pytest
import torch

from data.sfm.synthetic import synthetic_cube_scene
from models.geometry import correct_matches, fundamental_from_cameras, triangulate_polynomial
from models.geometry.projection import reprojection_cost


def test_fundamental_matrix_satisfies_epipolar_constraint():
    s = synthetic_cube_scene(200, num_views=2, noise_px=0.0)
    F = fundamental_from_cameras(s.cameras[:, 0], s.cameras[:, 1])[0]
    F = F / F.norm()
    ones = torch.ones(200, 1, dtype=torch.float64)
    x1, x2 = torch.cat((s.clean[:, 0], ones), 1), torch.cat((s.clean[:, 1], ones), 1)
    residual = torch.einsum("bi,ij,bj->b", x2, F, x1) / (x1.norm(dim=1) * x2.norm(dim=1))
    assert residual.abs().max() < 1e-12


@pytest.mark.slow
def test_correction_agrees_with_opencv_correct_matches():
    """Must show 3: within 1e-4 px of cv2.correctMatches on at least 99.9 % of 1e5 points."""
    s = synthetic_cube_scene(100_000, num_views=2, noise_px=1.0, seed=7)
    F = fundamental_from_cameras(s.cameras[:, 0], s.cameras[:, 1])
    y1, y2 = correct_matches(F.expand(100_000, 3, 3), s.observations[:, 0], s.observations[:, 1])
    c1, c2 = cv2.correctMatches(F[0].numpy(), s.observations[None, :, 0].numpy(), s.observations[None, :, 1].numpy())
    diff = np.maximum(np.abs(c1[0] - y1.numpy()).max(1), np.abs(c2[0] - y2.numpy()).max(1))
    assert (diff < 1e-4).mean() >= 0.999


def test_polynomial_is_optimal_for_two_views():
    """Its cost is the two-view minimum: no dense grid of nearby points does better."""
    s = synthetic_cube_scene(20, num_views=2, noise_px=2.0, seed=3)
    result = triangulate_polynomial(s.cameras, s.observations)
    assert result.valid.all()
    offsets = torch.stack(torch.meshgrid(*[torch.linspace(-2e-3, 2e-3, 9, dtype=torch.float64)] * 3, indexing="ij"), -1)
    candidates = (result.points[:, None] + offsets.reshape(1, -1, 3)).reshape(-1, 3)
    P = s.cameras
    x = s.observations.repeat_interleave(offsets.numel() // 3, dim=0)
    grid_cost = reprojection_cost(P, candidates, x).reshape(20, -1).min(dim=1).values
    assert (result.cost <= grid_cost + 1e-9).all()

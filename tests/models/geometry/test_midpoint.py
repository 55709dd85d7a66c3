import math

import pytest
import torch

from data.sfm.synthetic import synthetic_cube_scene
from models.geometry import TriangulateMidpoint, triangulate_dlt, triangulate_midpoint


@pytest.mark.parametrize("views", [2, 3, 5])
def test_noise_free_points_are_exact(views):
    s = synthetic_cube_scene(500, num_views=views, noise_px=0.0, seed=views)
    for result in (triangulate_midpoint(s.cameras, s.observations), triangulate_dlt(s.cameras, s.observations)):
        torch.testing.assert_close(result.points, s.points, rtol=0, atol=1e-9)
        assert result.valid.all()
        assert result.cost.max() < 1e-12


def _closest_point_midpoint(c1, d1, c2, d2):
    """Brute-force two-ray midpoint: solve for the ray parameters of the shortest connecting segment."""
    out = []
    for a, u, b, v in zip(c1, d1, c2, d2, strict=True):
        M = torch.stack((u, -v), 1)
        s, t = torch.linalg.lstsq(M, (b - a).unsqueeze(1)).solution.squeeze(1)
        out.append(0.5 * (a + s * u + b + t * v))
    return torch.stack(out)


def test_two_view_midpoint_matches_segment_midpoint():
    s = synthetic_cube_scene(50, num_views=2, noise_px=3.0, seed=1)
    P = s.cameras[0]
    centres, directions = [], []
    for i in range(2):
        M, p4 = P[i, :, :3], P[i, :, 3]
        centres.append((-torch.linalg.solve(M, p4)).expand(50, 3))
        xh = torch.cat((s.observations[:, i], torch.ones(50, 1, dtype=torch.float64)), 1)
        directions.append(torch.linalg.solve(M, xh.T).T)
    expected = _closest_point_midpoint(centres[0], directions[0], centres[1], directions[1])
    result = TriangulateMidpoint()(s.cameras, s.observations)
    torch.testing.assert_close(result.points, expected, rtol=0, atol=1e-9)


def test_near_parallel_and_behind_camera_are_flagged():
    s = synthetic_cube_scene(4, num_views=2, noise_px=0.0)
    x = s.observations.clone()
    P = s.cameras.expand(4, -1, -1, -1).clone()
    # Point 0: both views identical cameras and observations -> parallel rays.
    P[0, 1] = P[0, 0]
    x[0, 1] = x[0, 0]
    # Point 1: flip one camera's sign so the point is behind it.
    P[1, 1] = -P[1, 1]
    result = triangulate_midpoint(P, x)
    assert not result.valid[0] and not result.valid[1]
    assert result.valid[2:].all()
    # The flag follows the angle threshold.
    assert not triangulate_midpoint(s.cameras, s.observations, min_parallax=math.radians(40)).valid.any()

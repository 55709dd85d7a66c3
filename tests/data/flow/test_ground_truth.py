"""Ground-truth tracks from flow: exact motion for affine flows, occlusion and divergence removal."""

import numpy as np

from data.flow import divergent_flow_mask, tracks_from_flow


def _affine_flow(h: int, w: int, M: np.ndarray, t: np.ndarray) -> np.ndarray:
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    p = np.stack([xs, ys], -1)
    return (p @ M.T + t).astype(np.float32)


def test_chained_affine_flows_are_exact():
    h, w = 60, 80
    M = np.array([[0.01, -0.02], [0.015, 0.005]])
    flows = [_affine_flow(h, w, M, np.array([1.5, -0.75])), _affine_flow(h, w, -M, np.array([-0.5, 2.0]))]
    points = np.array([[20.3, 30.7], [40.0, 25.5], [55.25, 10.5]])
    tracks, valid = tracks_from_flow(points, flows, threshold=5.0)
    p1 = points + points @ M.T + [1.5, -0.75]
    p2 = p1 + p1 @ (-M).T + [-0.5, 2.0]
    np.testing.assert_allclose(tracks[1], p1, atol=1e-4)
    np.testing.assert_allclose(tracks[2], p2, atol=1e-4)
    assert valid.all()


def test_occluded_divergent_and_leaving_points_are_dropped():
    h, w = 40, 60
    flow = np.zeros((h, w, 2), np.float32)
    flow[:, 30:, 0] = 4.0  # motion boundary at x = 29.5
    bad = np.zeros((h, w), bool)
    bad[5:10, 5:10] = True
    points = np.array([[10.0, 20.0], [29.0, 20.0], [7.0, 7.0], [45.0, 20.0], [57.5, 30.0]])
    tracks, valid = tracks_from_flow(points, [flow], [bad], radius=3, threshold=1.0)
    assert valid[1].tolist() == [True, False, False, True, False]
    np.testing.assert_allclose(tracks[1, 3], [49.0, 20.0])
    mask = divergent_flow_mask(flow, 3, 1.0)
    assert mask[:, 27:33].all() and not mask[:, :26].any() and not mask[:, 34:].any()

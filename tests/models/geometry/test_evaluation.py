"""evaluate_reconstruction: the tracks of a reconstruction triangulated and compared with its points, on a
hand-built ring of cameras in the Bundler/BAL camera model; bad requests are named."""

import math

import pytest
import torch

from core.errors import InputError
from data.sfm.reconstruction import Reconstruction
from models.geometry.evaluation import evaluate_reconstruction


def ring_reconstruction(points: int = 40, cameras: int = 4, noise_px: float = 0.0, seed: int = 0) -> Reconstruction:
    """Points in the cube [-1, 1]^3 seen by ``cameras`` cameras 6 units from the origin, looking at it down their
    -Z axis (``X_c = R X + t``, ``p = -X_c / X_c.z``, no distortion); every point is seen by every camera."""
    g = torch.Generator().manual_seed(seed)
    X = (torch.rand(points, 3, generator=g, dtype=torch.float64) - 0.5) * 2
    focal = 800.0
    rotation, translation, obs_camera, obs_point, obs_xy = [], [], [], [], []
    for c in range(cameras):
        a = 0.4 * c
        z = torch.tensor([math.sin(a), 0.0, math.cos(a)], dtype=torch.float64)  # camera +Z: from the origin out
        x = torch.tensor([math.cos(a), 0.0, -math.sin(a)], dtype=torch.float64)
        R = torch.stack([x, torch.linalg.cross(z, x), z])
        rotation.append(R)
        translation.append(-R @ (6.0 * z))
    for i in range(points):
        for c in range(cameras):
            Xc = rotation[c] @ X[i] + translation[c]
            obs_camera.append(c)
            obs_point.append(i)
            obs_xy.append(-focal * Xc[:2] / Xc[2])
    xy = torch.stack(obs_xy)
    xy = xy + noise_px * torch.randn(xy.shape, generator=g, dtype=torch.float64)
    return Reconstruction(focal=torch.full((cameras,), focal, dtype=torch.float64),
                          radial=torch.zeros(cameras, 2, dtype=torch.float64), rotation=torch.stack(rotation),
                          translation=torch.stack(translation), points=X,
                          colors=torch.zeros(points, 3, dtype=torch.uint8), obs_camera=torch.tensor(obs_camera),
                          obs_point=torch.tensor(obs_point), obs_xy=xy)


@pytest.mark.parametrize(("method", "views"), [("dogleg", 3), ("dogleg", 4), ("midpoint", 3), ("dlt", 3),
                                               ("polynomial", 2)])
def test_noise_free_tracks_give_the_points_back(method, views):
    recon = ring_reconstruction()
    report, result, index = evaluate_reconstruction(recon, views, method)
    assert report["method"] == method and report["views"] == views
    assert report["count"] == report["valid"] == 40 and index.tolist() == list(range(40))
    assert report["err3d_median_rel"] < 1e-9 and report["err3d_mean_rel"] < 1e-9 and report["reproj_rms"] < 1e-6
    torch.testing.assert_close(result.points, recon.points, rtol=0, atol=1e-9)
    assert report["points_per_s"] > 0


def test_dogleg_has_the_lowest_reprojection_error_on_noisy_tracks():
    recon = ring_reconstruction(points=200, noise_px=1.0, seed=3)
    clean = ring_reconstruction(points=200, noise_px=0.0, seed=3)  # the same points and cameras
    at_truth = float((recon.obs_xy - clean.obs_xy).square().sum(1).mean().sqrt())  # RMS at the true points
    reports = {m: evaluate_reconstruction(recon, 4, m)[0] for m in ("dogleg", "midpoint", "dlt")}
    assert reports["dogleg"]["reproj_rms"] <= min(reports["midpoint"]["reproj_rms"], reports["dlt"]["reproj_rms"])
    assert reports["dogleg"]["reproj_rms"] < at_truth  # the optimum fits the noise better than the truth does
    expected = math.sqrt(2 * (8 - 3) / 8)  # sigma 1 px per coordinate, 3 of 8 degrees of freedom per track fitted
    assert 0.85 * expected < reports["dogleg"]["reproj_rms"] < 1.15 * expected
    assert reports["dogleg"]["err3d_median_rel"] < 0.01


def test_bad_requests_are_named():
    recon = ring_reconstruction(points=5)
    with pytest.raises(InputError, match="unknown method 'nope'"):
        evaluate_reconstruction(recon, 3, "nope")
    with pytest.raises(InputError, match="takes exactly 2 views, not 3"):
        evaluate_reconstruction(recon, 3, "polynomial")
    with pytest.raises(InputError, match="no track of the reconstruction has 5 registered views"):
        evaluate_reconstruction(recon, 5, "dogleg")

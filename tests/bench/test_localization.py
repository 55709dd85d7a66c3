"""bench/localization.py on a tiny map: report fields, accuracy of ground-truth profiles, plot, bad DEM."""

import json

import numpy as np
import pytest

from bench.localization import _table, main, plot, run
from data.world.dem import Dem, generate_archipelago, save_dem


def test_run_reports_every_field(tmp_path, monkeypatch):
    import bench.localization

    monkeypatch.setattr(bench.localization, "demo_horizon_checkpoint", lambda kind: None)  # no trained networks
    dem = generate_archipelago(size_m=1200, cell=10, seed=7, feature_scale_m=400, land_fraction=0.15)
    spacing = 20
    outcome = run(dem, spacing=spacing, count=20, bins=128, max_range=600, kinds=("gt_profiles", "networks"),
                  speed_locations=4096, margin=40, progress=False, finder=None, segmenter=None)
    report = outcome["report"]
    json.dumps(report)  # serialisable
    gt = report["gt_profiles"]
    for key in ("err_mean_m", "err_median_m", "err_std_m", "fail_rate", "heading_err_median_deg", "locations_per_s"):
        assert np.isfinite(gt[key])
    # The errors are those of the returned estimates, and better than snapping each pose to its nearest bank
    # location: every pose matches its own grid cell or a neighbour, and the sub-grid refinement gains on that.
    poses, result, locations = outcome["poses"], outcome["results"]["gt_profiles"], outcome["bank"].locations()
    err = np.linalg.norm(result.xy - poses[:, :2], axis=1)
    assert gt["err_mean_m"] == pytest.approx(err.mean()) and gt["err_median_m"] == pytest.approx(np.median(err))
    assert gt["fail_rate"] == 0.0 and gt["queries"] == len(poses) == 20
    nearest = np.linalg.norm(locations[None] - poses[:, None, :2], axis=-1).min(1)
    assert (np.linalg.norm(locations[result.index] - poses[:, :2], axis=1) <= spacing * np.sqrt(2)).all()
    assert gt["err_mean_m"] < nearest.mean() <= spacing / np.sqrt(2)
    assert gt["err_median_m"] < spacing  # within one grid step
    assert report["bank_bytes"] > 0 and report["bank_build_s"] > 0
    assert report["speed"]["numpy_loop_locations_per_s"] > 0
    assert set(report["networks"]) == {"pending"} and "networks_checkpoints" not in report
    assert "networks" not in outcome["results"]
    assert "gt_profiles" in _table(report)
    plot(outcome, tmp_path / "loc.png")
    assert (tmp_path / "loc.png").stat().st_size > 10000


def test_main_rejects_a_bad_dem(tmp_path, capsys):
    (tmp_path / "bad.tif").write_bytes(b"no tiff")
    assert main(["--dem", str(tmp_path / "bad.tif"), "--json"]) == 2
    assert "not a readable GeoTIFF" in capsys.readouterr().err
    save_dem(tmp_path / "land.npz", Dem(np.full((40, 40), 5.0, dtype=np.float32), y0=400.0, cell=10.0))
    assert main(["--dem", str(tmp_path / "land.npz"), "--json"]) == 2
    assert "has no water" in capsys.readouterr().err

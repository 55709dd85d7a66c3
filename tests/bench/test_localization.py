"""bench/localization.py on a tiny map: report fields, accuracy of ground-truth profiles, plot, bad DEM."""

import json

import numpy as np

from bench.localization import _table, main, plot, run
from data.world.dem import Dem, generate_archipelago, save_dem


def test_run_reports_every_field(tmp_path):
    dem = generate_archipelago(size_m=1200, cell=10, seed=7, feature_scale_m=400, land_fraction=0.15)
    outcome = run(dem, spacing=20, count=20, bins=128, max_range=600, kinds=("gt_profiles", "networks"),
                  speed_locations=4096, margin=40, progress=False, finder=None, segmenter=None)
    report = outcome["report"]
    json.dumps(report)  # serialisable
    gt = report["gt_profiles"]
    for key in ("err_mean_m", "err_median_m", "err_std_m", "fail_rate", "heading_err_median_deg", "locations_per_s"):
        assert np.isfinite(gt[key])
    assert gt["err_median_m"] < 20  # within one grid step
    assert report["bank_bytes"] > 0 and report["bank_build_s"] > 0
    assert report["speed"]["numpy_loop_locations_per_s"] > 0
    assert "pending" in report["networks"] or "err_mean_m" in report["networks"]
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

import json

import pytest

from bench import triangulation


def test_benchmark_prints_one_json_object_with_every_method(tmp_path, capsys):
    plot = tmp_path / "tri.png"
    triangulation.main(["--points", "3000", "--repeats", "1", "--pycolmap-points", "200", "--json",
                        "--plot", str(plot)])
    report = json.loads(capsys.readouterr().out)
    methods = report["methods"]
    expected = {"dogleg", "midpoint3", "midpoint2", "polynomial", "kornia_dlt", "opencv_dlt", "opencv_optimal"}
    assert expected <= set(methods)
    for entry in methods.values():
        assert {"views", "points_per_s", "err3d_median", "err3d_mean", "err3d_p95", "reproj_rms"} <= set(entry)
    # Must show 4: three views beat two, and the optimal solver does not lose to its own start.
    assert methods["dogleg"]["err3d_median"] < methods["polynomial"]["err3d_median"]
    assert methods["dogleg"]["err3d_median"] < methods["midpoint2"]["err3d_median"]
    assert methods["dogleg"]["reproj_rms"] <= methods["midpoint3"]["reproj_rms"]
    assert plot.stat().st_size > 10_000


@pytest.mark.slow  # uses an exported bundle
def test_runtime_dogleg_is_a_method(triangulation_bundle, capsys):
    triangulation.main(["--points", "2000", "--repeats", "1", "--methods", "dogleg", "ort_dogleg", "opencv_dlt",
                        "--bundle", str(triangulation_bundle), "--json"])
    methods = json.loads(capsys.readouterr().out)["methods"]
    assert set(methods) == {"dogleg", "ort_dogleg", "opencv_dlt"} and methods["ort_dogleg"]["speed_vs_opencv_dlt"] > 0
    assert methods["ort_dogleg"]["err3d_median"] == pytest.approx(methods["dogleg"]["err3d_median"], rel=1e-4)

"""``infer.py triangulate`` on a written Bundler file and on the shared Balbianello reconstruction; bad arguments
end in one line and exit code 2."""

import json
from pathlib import Path

import pytest
import torch

import infer
from data.sfm.synthetic import synthetic_cube_scene


def write_bundler(path: Path, views: int = 3, points: int = 50) -> torch.Tensor:
    """A Bundler v0.3 file of the synthetic cube in Bundler's camera model (no distortion); returns the points."""
    scene = synthetic_cube_scene(points, num_views=views, noise_px=0.0, seed=4)
    K = scene.intrinsics
    lines = ["# Bundle file v0.3", f"{views} {points}"]
    for P in scene.cameras[0]:
        Rt = torch.linalg.solve(K, P)  # [R | t] in the OpenCV convention (z forward, y down)
        flip = torch.diag(torch.tensor([1.0, -1.0, -1.0], dtype=torch.float64))  # Bundler: -z forward, +y up
        Rt = flip @ Rt
        lines.append(f"{K[0, 0].item()} 0 0")
        lines += [" ".join(f"{v:.17g}" for v in row) for row in Rt[:, :3].tolist()]
        lines.append(" ".join(f"{v:.17g}" for v in Rt[:, 3].tolist()))
    for X, x in zip(scene.points, scene.observations, strict=True):
        lines.append(" ".join(f"{v:.17g}" for v in X.tolist()))
        lines.append("10 20 30")
        centred = (x - K[:2, 2]) * torch.tensor([1.0, -1.0], dtype=torch.float64)
        lines.append(f"{views} " + " ".join(f"{i} {i} {u:.17g} {v:.17g}" for i, (u, v) in enumerate(centred.tolist())))
    path.write_text("\n".join(lines) + "\n")
    return scene.points


def test_triangulate_json_on_a_written_bundler_file(tmp_path, capsys):
    truth = write_bundler(tmp_path / "cube.out")
    ply = tmp_path / "points.ply"
    assert infer.main(["triangulate", "--bundler", str(tmp_path / "cube.out"), "--json", "--out", str(ply)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) >= {"method", "views", "count", "err3d_median_rel", "err3d_mean_rel", "reproj_rms",
                           "points_per_s"}
    assert report["count"] == 50 and report["valid"] == 50
    assert report["err3d_median_rel"] < 1e-9 and report["reproj_rms"] < 1e-6  # noise-free data
    assert ply.read_text().splitlines()[2] == "element vertex 50"
    assert len(truth) == 50


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["triangulate"], "one of the arguments --bundler --bal is required"),
        (["triangulate", "--bundler", "missing.out"], "missing.out: no such file"),
        (["triangulate", "--bundler", "{cube}", "--views", "1"], "--views must be at least 2"),
        (["triangulate", "--bundler", "{cube}", "--method", "polynomial"], "takes exactly 2 views"),
        (["triangulate", "--bundler", "{cube}", "--method", "nope"], "invalid choice"),
        (["triangulate", "--bundler", "{cube}", "--views", "4"], "no track of the reconstruction has 4"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys, argv, message):
    write_bundler(tmp_path / "cube.out")
    argv = [a.replace("{cube}", str(tmp_path / "cube.out")) for a in argv]
    try:
        code = infer.main(argv)
    except SystemExit as exit_:  # argparse errors
        code = exit_.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_balbianello_dogleg_beats_midpoint_and_dlt(shared_data, capsys):
    """Must show 6: lower median 3D distance than midpoint and DLT, reprojection RMS <= 0.5 px."""
    reports = {}
    for method in ("dogleg", "midpoint", "dlt"):
        infer.main(["triangulate", "--bundler", str(shared_data / "sfm" / "Balbianello.out"), "--method", method,
                    "--json"])
        reports[method] = json.loads(capsys.readouterr().out)
    assert reports["dogleg"]["err3d_median_rel"] < reports["midpoint"]["err3d_median_rel"]
    assert reports["dogleg"]["err3d_median_rel"] < reports["dlt"]["err3d_median_rel"]
    assert reports["dogleg"]["reproj_rms"] <= 0.5


@pytest.mark.slow  # uses an exported bundle
def test_triangulate_with_a_bundle_runs_the_runtime(triangulation_bundle, tmp_path, capsys):
    from runtime.triangulation import triangulate_file

    write_bundler(tmp_path / "cube.out")
    argv = ["triangulate", "--bundler", str(tmp_path / "cube.out"), "--onnx", str(triangulation_bundle), "--json"]
    assert infer.main([*argv, "--out", str(tmp_path / "cli.ply")]) == 0
    report = json.loads(capsys.readouterr().out)
    expected = triangulate_file(triangulation_bundle, tmp_path / "cube.out", out=tmp_path / "runtime.ply")
    assert report["method"] == "dogleg_onnx" and report["count"] == expected["count"] == 50
    assert (tmp_path / "cli.ply").read_text() == (tmp_path / "runtime.ply").read_text()
    assert infer.main([*argv, "--method", "dlt"]) == 2
    assert "has no graph" in capsys.readouterr().err

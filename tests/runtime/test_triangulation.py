"""The runtime's triangulation: its command, run without torch, against PyTorch's float32 dogleg on the same
reconstruction (points rtol 1e-4), chunked and single-point calls, inputs that do not fit the bundle."""

import json

import numpy as np
import pytest
import torch

from core.errors import InputError
from data.sfm.bundler import read_bundler
from data.sfm.synthetic import synthetic_cube_scene
from models.geometry.dogleg import TriangulateDogleg
from models.geometry.evaluation import evaluate_reconstruction
from runtime.triangulation import Triangulator, lower_median
from tests.cli.test_triangulate import write_bundler

pytestmark = pytest.mark.slow  # uses an exported bundle


def _ply_points(path) -> np.ndarray:
    lines = path.read_text().splitlines()
    return np.array([[float(v) for v in line.split()[:3]] for line in lines[lines.index("end_header") + 1 :]])


def _check_against_pytorch(torch_free, bundle, reconstruction, tmp_path) -> dict:
    ply = tmp_path / "points.ply"
    proc = torch_free("runtime.triangulation", "--bundle", bundle, "--bundler", reconstruction, "--json", "--out", ply)
    report = json.loads(proc.stdout)
    ref_report, ref, _ = evaluate_reconstruction(read_bundler(reconstruction), 3, "dogleg", torch.float32)
    np.testing.assert_allclose(_ply_points(ply), ref.points[ref.valid].double().numpy(), rtol=1e-4, atol=1e-6)
    assert report["count"] == ref_report["count"] and report["valid"] == ref_report["valid"]
    assert report["err3d_median_rel"] == pytest.approx(ref_report["err3d_median_rel"], rel=1e-3, abs=1e-6)
    return report


def test_command_without_torch_matches_pytorch(torch_free, triangulation_bundle, tmp_path) -> None:
    write_bundler(tmp_path / "cube.out", points=50)
    report = _check_against_pytorch(torch_free, triangulation_bundle, tmp_path / "cube.out", tmp_path)
    assert report["count"] == 50 and report["reproj_rms"] < 1e-2  # noise-free data, float32


def test_shared_reconstruction_without_torch_matches_pytorch(torch_free, triangulation_bundle, shared_data,
                                                              tmp_path) -> None:
    report = _check_against_pytorch(torch_free, triangulation_bundle, shared_data / "sfm" / "Balbianello.out",
                                    tmp_path)
    assert report["count"] == 225


def test_chunks_shared_cameras_and_a_single_point(triangulation_bundle) -> None:
    scene = synthetic_cube_scene(1000, noise_px=1.0, seed=2, dtype=torch.float32)
    expected = TriangulateDogleg(5)(scene.cameras, scene.observations).points.numpy()
    solver = Triangulator(triangulation_bundle, threads=1, chunk=333)  # 3 full chunks and a lone point
    shared = solver(scene.cameras.numpy(), scene.observations.numpy())
    per_point = solver(scene.cameras.expand(1000, -1, -1, -1).numpy(), scene.observations.numpy())
    for result in (shared, per_point):
        np.testing.assert_allclose(result.points, expected, rtol=1e-4, atol=1e-5)
        assert result.valid.all() and result.converged.mean() > 0.99
    with pytest.raises(InputError, match="exported for 3 views"):
        solver(scene.cameras[:, :2].numpy(), scene.observations[:, :2].numpy())
    with pytest.raises(InputError, match="cameras must be"):
        solver(np.zeros((7, 3, 3, 4)), scene.observations.numpy())


def test_steps_stop_when_every_point_converged(triangulation_bundle) -> None:
    scene = synthetic_cube_scene(2000, noise_px=1.0, seed=3, dtype=torch.float32)
    solver = Triangulator(triangulation_bundle, threads=1, chunk=1000)
    calls = []
    step = solver.step
    solver.step = lambda *state: calls.append(1) or step(*state)
    result = solver(scene.cameras.numpy(), scene.observations.numpy())
    assert result.converged.all() and 2 <= len(calls) < 2 * solver.iterations  # two chunks, each stopped early


def test_lower_median_is_torchs() -> None:
    values = torch.tensor([4.0, 1.0, 3.0, 2.0])
    assert lower_median(values.numpy()) == values.median().item()

import numpy as np
import pytest
import torch

from data.sfm.synthetic import synthetic_cube_scene
from export.triangulation import export_dogleg
from models.geometry.dogleg import TriangulateDogleg
from models.onnx_graph import onnx_session, run_onnx

pytestmark = pytest.mark.slow  # ONNX export


def test_dogleg_onnx_matches_pytorch(tmp_path):
    """Must show 7: fixed-iteration dogleg in onnxruntime within 1e-4 relative of PyTorch, any number of points."""
    path = export_dogleg(tmp_path / "dogleg.onnx", views=3, iterations=5)
    session = onnx_session(path)
    for count in (5, 3000):
        scene = synthetic_cube_scene(count, noise_px=1.0, seed=count, dtype=torch.float32)
        points, cost, valid, converged = run_onnx(session, scene.cameras, scene.observations)
        expected = TriangulateDogleg(iterations=5)(scene.cameras, scene.observations)
        np.testing.assert_allclose(points, expected.points.numpy(), rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(cost, expected.cost.numpy(), rtol=1e-4, atol=1e-4)
        np.testing.assert_array_equal(valid, expected.valid.numpy())
        assert converged.mean() >= 0.99

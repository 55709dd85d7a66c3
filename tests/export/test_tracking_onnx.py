"""The per-frame tracking step exports to ONNX (dynamic frame size and point count) and matches PyTorch in
onnxruntime."""

import numpy as np
import pytest
import torch

from export.tracking_onnx import example_inputs, export_tracking_step
from models.onnx_graph import onnx_session, run_onnx
from models.tracking import PointTracker

pytestmark = pytest.mark.slow  # ONNX export


@pytest.mark.parametrize("method", ["ccot"])
def test_tracking_step_onnx_parity(tmp_path, method):
    path = export_tracking_step(tmp_path / "step.onnx", method, height=96, width=128, points=8)
    session = onnx_session(path)
    tracker = PointTracker(method).eval()
    for height, width, points in ((96, 128, 8), (120, 176, 40)):  # another size and point count than exported
        args = example_inputs(tracker, height, width, points, seed=3)
        with torch.no_grad():
            ref = tracker(*args)
        out = run_onnx(session, *args)
        np.testing.assert_array_equal(out[1], ref[1].numpy())  # lost flags
        for got, want in zip(out[:1] + out[2:], (ref[0], *ref[2:]), strict=True):
            np.testing.assert_allclose(got, want.numpy(), rtol=1e-4, atol=1e-4 * float(want.abs().max()))
        assert (~ref[1]).sum() > points // 2  # most points really tracked, so the comparison is meaningful

"""The matching step (profile in, PSR over a bank block out) exports to ONNX and matches PyTorch in onnxruntime,
with a band-limited bank and dropped harmonics."""

import numpy as np
import pytest
import torch

from core.errors import InputError
from export.localization_onnx import example_inputs, export_matcher
from models.horizon.matching import BandPsr
from runtime.session import Graph

pytestmark = pytest.mark.slow  # ONNX export


def test_matcher_onnx_matches_pytorch(tmp_path):
    graph = Graph(export_matcher(tmp_path / "matcher.onnx", bins=128, frequencies=40, band_deg=6.0, drop_harmonics=1))
    model = BandPsr(band_deg=6.0, drop_harmonics=1)
    for locations, batch, seed in ((300, 3, 1), (17, 1, 2)):  # other sizes than the exported example
        inputs = example_inputs(128, 40, locations, batch, seed)
        with torch.no_grad():
            psr, heading = model(*inputs)
        onnx_psr, onnx_heading = graph(*(t.numpy() for t in inputs))
        assert onnx_psr.shape == (batch, locations)
        np.testing.assert_allclose(onnx_psr, psr.numpy(), rtol=1e-4, atol=1e-4)
        diff = (onnx_heading - heading.numpy() + 180) % 360 - 180
        np.testing.assert_allclose(diff, 0, atol=1e-3)
    with pytest.raises(InputError, match="--frequencies must be in"):
        export_matcher(tmp_path / "x.onnx", bins=64, frequencies=99)

"""ONNX export of HorizonFinder, HorizonSegmenter and the levelling warp: onnxruntime matches PyTorch."""

import numpy as np
import pytest
import torch

from core.errors import InputError
from export.horizon_onnx import example_inputs, export_horizon, parity
from models.builders import horizon_network

SMALL = {"backbone": "resnet18", "stage": "layer2", "heads": 2, "head_channels": 8, "channels": 16}


@pytest.mark.slow
@pytest.mark.parametrize("which", ["finder", "segmenter", "level"])
def test_onnx_matches_pytorch(which, tmp_path):
    torch.manual_seed(0)
    model = horizon_network(which, **({} if which == "level" else SMALL))
    if which != "level":  # give batch norm non-trivial statistics
        for module in model.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                module.running_mean.uniform_(-0.1, 0.1)
                module.running_var.uniform_(0.5, 1.5)
    path = export_horizon(which, model, tmp_path / f"{which}.onnx", height=64, width=256)
    for width, batch in ((256, 2), (384, 1)):  # the exported width and batch are dynamic
        inputs = example_inputs(which, 64, width, batch=batch, seed=3)
        with torch.no_grad():
            scale = float(np.abs(model(*inputs).numpy()).max())
        assert parity(which, model, path, inputs) <= 1e-4 * max(scale, 1.0)


def test_export_bad_input(tmp_path):
    with pytest.raises(InputError, match="multiples of the backbone stride"):
        export_horizon("finder", horizon_network("finder", **SMALL), tmp_path / "x.onnx", height=64, width=250)
    with pytest.raises(InputError, match="missing.ckpt does not exist"):
        horizon_network("segmenter", tmp_path / "missing.ckpt")
    with pytest.raises(InputError, match="must be one of finder, segmenter, level"):
        horizon_network("localizer")

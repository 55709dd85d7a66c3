"""The horizon bundle: each network graph matches PyTorch in onnxruntime at other widths and batch sizes, the chain
matches on rendered panoramas, the int8 export quantizes the networks and reports their accuracy, bad input."""

import numpy as np
import pytest
import torch

from core.errors import InputError
from export.horizon_onnx import example_inputs, export_bundle, export_horizon, parity, render_panoramas
from models.builders import horizon_network
from runtime.bundle import Bundle
from runtime.horizon import HorizonChain
from tests.conftest import SMALL_HORIZON

pytestmark = pytest.mark.slow  # ONNX export


def test_graphs_match_pytorch(horizon_setup) -> None:
    bundle = Bundle(horizon_setup["bundle"], "horizon")
    models = {"finder": horizon_setup["finder"], "segmenter": horizon_setup["segmenter"],
              "level": horizon_network("level")}
    for which, model in models.items():
        graph = bundle.graph(which)
        for width, batch in ((256, 2), (384, 1)):  # the exported width and batch are dynamic
            inputs = example_inputs(which, 32, width, batch=batch, seed=3)
            with torch.no_grad():
                expected = model(*inputs).numpy()
            got = graph(*(t.numpy() for t in inputs))
            assert np.abs(got - expected).max() <= 1e-4 * max(float(np.abs(expected).max()), 1.0), which


def test_chain_parity_and_int8_report(horizon_setup, tmp_path) -> None:
    images, truth = render_panoramas(tmp_path / "rendered", 4, 32, 256, seed=3)
    assert images.shape == (4, 3, 32, 256) and truth["pitch"].shape == (4,)
    check = parity(HorizonChain(horizon_setup["bundle"]), horizon_setup["finder"], horizon_setup["segmenter"], images)
    assert check["angle_deg_max"] < 0.01 and check["profile_px_max"] < 0.05
    report = export_bundle(tmp_path / "int8", horizon_setup["finder"], horizon_setup["segmenter"], 32, 256, 256, 64,
                           int8=True, calibration=4)
    manifest = Bundle(tmp_path / "int8", "horizon").manifest
    assert manifest["precision"] == "int8" and manifest["int8"] == report["int8"]
    for graph in ("finder", "segmenter"):
        assert report["int8"]["graphs"][graph]["int8_bytes"] < report["int8"]["graphs"][graph]["fp32_bytes"] / 2
    assert set(report["int8"]["accuracy"]["int8"]) == {"pitch_deg_median", "roll_deg_median", "horizon_px_median"}


def test_export_bad_input(tmp_path) -> None:
    with pytest.raises(InputError, match="multiples of the backbone stride"):
        export_horizon("finder", horizon_network("finder", **SMALL_HORIZON), tmp_path / "x.onnx", height=64,
                       width=250)
    with pytest.raises(InputError, match="at least twice as wide"):
        export_bundle(tmp_path / "b", None, None, height=64, width=100)
    with pytest.raises(InputError, match="missing.ckpt does not exist"):
        horizon_network("segmenter", tmp_path / "missing.ckpt")
    with pytest.raises(InputError, match="must be one of finder, segmenter, level"):
        horizon_network("localizer")

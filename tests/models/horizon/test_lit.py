"""HorizonFinder / HorizonSegmenter networks, column pooling, and their Lightning systems end to end."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from lightning.pytorch.cli import LightningCLI

import infer
from core.cylinder import row_tangents
from data.horizon.datamodule import HorizonDataModule
from export.horizon_onnx import export_horizon
from models.builders import horizon_finder
from models.horizon.column_pool import ColumnPool, row_height_grid, row_tangent_grid
from models.horizon.finder import HorizonFinder, fourier_pool, sincos_to_angles
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem
from models.horizon.segmenter import HorizonSegmenter, PanoramaSegmenter


def test_row_tangent_grid_is_the_mean_of_the_input_rows():
    height, width, stride = 64, 512, 8
    rows = row_tangents(height, width, torch.float64).reshape(height // stride, stride).mean(1)
    assert torch.allclose(row_tangent_grid(height // stride, width // stride, torch.float64, None), rows)
    centre_heights = ((height - 1) / 2 - (torch.arange(height // stride) + 0.5) * stride + 0.5) / (height / 2)
    assert torch.allclose(row_height_grid(height // stride, torch.float64, None), centre_heights.double())


def test_fourier_pool_matches_a_loop():
    x = torch.randn(2, 3, 10, dtype=torch.float64)
    out = fourier_pool(x).reshape(2, 3, 3)
    for j, weight in enumerate((lambda p: 1.0, lambda p: 2 * math.cos(p), lambda p: 2 * math.sin(p))):
        expected = sum(x[..., c] * weight(2 * math.pi * (c + 0.5) / 10) for c in range(10)) / 10
        assert torch.allclose(out[:, j], expected)


def test_column_pool_finds_the_row_of_a_single_bright_row():
    pool = ColumnPool(1, heads=1, head_channels=2).double()
    with torch.no_grad():
        pool.score.weight.fill_(50.0)
        pool.score.bias.zero_()
    features = torch.zeros(1, 1, 8, 16, dtype=torch.float64)
    features[0, 0, 5] = 1.0
    _, position = pool(features)
    assert torch.allclose(position, torch.full_like(position, math.pi * (8 - 2 * 5 - 1) / 16), atol=1e-6)
    pool.full_panorama = False  # heights in half-image-heights: row 5 of 8 is centred 3/8 below the centre
    _, position = pool(features)
    assert torch.allclose(position, torch.full_like(position, -3 / 8), atol=1e-6)


@pytest.mark.parametrize("width", [256, 320])
def test_networks_take_any_width(width):
    """Any width; the segmenter gives the same rows for a crop as for the whole panorama (away from the cut)."""
    finder = HorizonFinder("resnet18", stage="layer2").eval()
    segmenter = HorizonSegmenter("resnet18", stage="layer2").eval()
    image = torch.rand(2, 3, 32, width)
    out = finder(image)
    assert out.shape == (2, 4)
    assert torch.allclose(out.reshape(2, 2, 2).norm(dim=-1), torch.ones(2, 2), atol=1e-5)
    pitch, roll = sincos_to_angles(out)
    assert pitch.shape == roll.shape == (2,)
    whole = segmenter(image)
    assert whole.shape == (2, 2, width)
    with torch.no_grad():
        crop = segmenter(image[..., : width // 2])
    inner = slice(48, width // 2 - 48)
    assert (crop[..., inner] - whole[..., inner]).abs().max() < 0.05 * whole.abs().max()
    # Deployed form: tan elevation = half-image-heights * (H / 2) / (W / 2 pi) for a whole panorama.
    tangent = PanoramaSegmenter(segmenter)(image)
    assert torch.allclose(tangent, whole * 16 / (width / (2 * math.pi)), atol=1e-6)


@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("horizon")
    data = dict(root=str(root / "train"), test_root=str(root / "test"), input_width=256, batch_size=4, count=10,
                test_count=4, width=256, height=32, dem_size_m=3000.0, dem_cell_m=10.0, degraded_fraction=0.0,
                test_degraded_fraction=0.5)
    HorizonDataModule(**data).prepare_data()
    return data


@pytest.fixture(scope="module")
def trained(tiny_data, tmp_path_factory):
    """Both systems fitted for one epoch through LightningCLI, tested; returns test metrics and checkpoints."""
    results = {}
    for system, task in ((HorizonFinderSystem, "finder"), (HorizonSegmenterSystem, "segmenter")):
        root = tmp_path_factory.mktemp(task)
        model = {"backbone": "resnet18", "stage": "layer1", "heads": 2, "head_channels": 4, "channels": 8}
        data = dict(tiny_data, task=task, val_fraction=0.3)
        if task == "segmenter":
            data["crop_width"] = 128
        trainer = {"max_epochs": 1, "default_root_dir": str(root), "enable_progress_bar": False,
                   "num_sanity_val_steps": 0, "accelerator": "cpu"}
        cli = LightningCLI(system, HorizonDataModule, run=False, save_config_callback=None,
                           args={"model": model, "data": data, "trainer": trainer, "seed_everything": 0})
        cli.trainer.fit(cli.model, cli.datamodule)
        metrics = cli.trainer.test(cli.model, cli.datamodule, verbose=False)[0]
        results[task] = (metrics, next(root.rglob("*.ckpt")))
    return results


@pytest.mark.parametrize("task, key", [("finder", "test/all/pitch_deg_median"),
                                       ("segmenter", "test/all/horizon_px_median")])
def test_systems_fit_and_test_through_the_cli(trained, task, key):
    metrics, _ = trained[task]
    assert math.isfinite(metrics[key]) and "test/degraded/classical_failure_rate" in metrics
    assert 0 <= metrics["test/all/failure_rate"] <= 1


def test_infer_horizon_with_checkpoints_and_onnx(trained, tiny_data, tmp_path, capsys):
    image = str(Path(tiny_data["test_root"]) / "images" / "000000.png")
    finder, segmenter = trained["finder"][1], trained["segmenter"][1]
    args = ["horizon", "--image", image, "--input-width", "256", "--json", "--out", str(tmp_path / "p.npz")]
    assert infer.main([*args, "--finder", str(finder), "--segmenter", str(segmenter)]) == 0
    from_ckpt = json.loads(capsys.readouterr().out)
    saved = np.load(tmp_path / "p.npz")
    assert saved["horizon"].shape == (256,) and abs(math.degrees(saved["pitch"]) - from_ckpt["pitch_deg"]) < 1e-9
    onnx_path = tmp_path / "finder.onnx"
    export_horizon("finder", horizon_finder(ckpt=finder), onnx_path, height=32, width=256)
    assert infer.main([*args, "--finder", str(onnx_path), "--segmenter", str(segmenter)]) == 0
    from_onnx = json.loads(capsys.readouterr().out)
    assert abs(from_onnx["pitch_deg"] - from_ckpt["pitch_deg"]) < 1e-3
    assert infer.main([*args[:-2], "--input-width", "250", "--finder", str(finder),
                       "--segmenter", str(segmenter)]) == 2
    assert "multiple of 32" in capsys.readouterr().err

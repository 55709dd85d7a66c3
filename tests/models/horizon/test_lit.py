"""HorizonFinderSystem / HorizonSegmenterSystem: both fitted for one epoch through LightningCLI and tested."""

import math

import pytest
from lightning.pytorch.cli import LightningCLI

from data.horizon.datamodule import HorizonDataModule
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem

pytestmark = pytest.mark.slow  # LightningCLI fits


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

"""train.py: DDP (2 CPU processes, gloo) fits a tiny FRTM and a tiny HorizonFinder, and ``test`` under DDP prints
the metrics of one process on the same checkpoint; ``--ckpt_path`` is checked before Lightning starts."""

import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml

import train
from data.horizon.dataset import DatasetSettings, write_dataset
from data.world.dem import generate_archipelago
from models.horizon.lit import HorizonFinderSystem
from models.vos.lit import FRTMSegmentation
from tests.models.test_checkpoint import save_checkpoint

ROOT = Path(__file__).resolve().parents[1]
SMALL_FINDER = {"backbone": "resnet18", "stage": "layer2", "heads": 2, "head_channels": 8, "channels": 16}
TRACKER = {"channels": 8, "num_aug": 2, "memory_size": 4, "init_schedule": [2], "update_schedule": [2]}


def train_py(*args: str) -> str:
    """stdout + stderr of ``python train.py args`` (asserting exit code 0)."""
    proc = subprocess.run([sys.executable, "train.py", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout + proc.stderr


def metrics(output: str) -> dict[str, float]:
    """``test/...`` values of Lightning's result table."""
    return {k: float(v) for k, v in re.findall(r"(test/[\w/&]+)[\s│|]+([-+0-9.eE]+)", output)}


DDP = ["--trainer.accelerator", "cpu", "--trainer.strategy", "ddp", "--trainer.devices", "2"]
SINGLE = ["--trainer.accelerator", "cpu", "--trainer.devices", "1"]


@pytest.fixture(scope="module")
def finder_config(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("finder")
    dem = generate_archipelago(size_m=3000, cell=10, seed=3)
    write_dataset(root / "data", dem, DatasetSettings(count=10, width=256, height=32, render_bins=512,
                                                      label_bins=256, degraded_fraction=0.3, seed=4),
                  batch=5, progress=False)
    config = root / "finder.yaml"
    config.write_text(f"""seed_everything: 0
trainer: {{max_steps: 2, logger: false, enable_checkpointing: false, enable_progress_bar: false,
          enable_model_summary: false, num_sanity_val_steps: 0, default_root_dir: {root / 'runs'}}}
model:
  class_path: models.horizon.lit.HorizonFinderSystem
  init_args: {SMALL_FINDER}
data:
  class_path: data.horizon.datamodule.HorizonDataModule
  init_args: {{root: {root / 'data'}, test_root: {root / 'data'}, task: finder, input_width: 256, create: false,
              val_fraction: 0.3, batch_size: 3}}
""")
    torch.manual_seed(1)
    return config, save_checkpoint(HorizonFinderSystem(**SMALL_FINDER), root / "finder.ckpt")


@pytest.fixture(scope="module")
def frtm_config(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("frtm")
    config = root / "frtm.yaml"
    config.write_text(f"""seed_everything: 0
trainer: {{max_steps: 2, logger: false, enable_checkpointing: false, enable_progress_bar: false,
          enable_model_summary: false, num_sanity_val_steps: 0, limit_val_batches: 0,
          default_root_dir: {root / 'runs'}, inference_mode: false}}
model:
  class_path: models.vos.lit.FRTMSegmentation
  init_args: {{mdim: 8, train_channels: 8, train_num_aug: 2, train_schedule: [2], tracker: {TRACKER}}}
data:
  class_path: data.vos.datamodule.SyntheticVOSDataModule
  init_args: {{train_samples: 8, val_videos: 2, test_videos: 3, n_frames: 4, height: 48, width: 64,
              batch_size: 2, n_distractors: 0}}
""")
    torch.manual_seed(1)
    return config, save_checkpoint(FRTMSegmentation(mdim=8, train_channels=8, train_num_aug=2, train_schedule=[2],
                                               tracker=TRACKER), root / "frtm.ckpt")


@pytest.mark.slow
@pytest.mark.parametrize("system", ["finder", "frtm"])
def test_ddp_fit_and_test_equal_one_process(system, request) -> None:
    config, ckpt = request.getfixturevalue(f"{system}_config")
    train_py("fit", "--config", str(config), *DDP)
    one = metrics(train_py("test", "--config", str(config), "--ckpt_path", str(ckpt), *SINGLE))
    two = metrics(train_py("test", "--config", str(config), "--ckpt_path", str(ckpt), *DDP))
    key = "test/all/pitch_deg_median" if system == "finder" else "test/jf"
    assert key in one and one.keys() - {"test/fps"} == two.keys() - {"test/fps"}
    for name in one.keys() - {"test/fps"}:
        assert two[name] == pytest.approx(one[name], rel=1e-6, abs=1e-9), name


def test_ckpt_path_of_another_system_is_refused_before_lightning(finder_config, frtm_config, capsys) -> None:
    from train import run

    assert run(["test", "--config", str(finder_config[0]), "--ckpt_path", str(frtm_config[1])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("train.py: error: --ckpt_path") and "FRTMSegmentation checkpoint" in err[-1]


@pytest.mark.slow
def test_killed_fit_resumes_from_last_ckpt(finder_config, tmp_path) -> None:
    """A fit killed after its first epoch's ``last.ckpt`` continues from it (``--ckpt_path last``) and ends where an
    uninterrupted fit of the same config ends: two epochs of steps."""
    import os
    import signal
    import time

    config, _ = finder_config
    run = ["fit", "--config", str(config), *SINGLE, "--trainer.max_steps", "-1", "--trainer.max_epochs", "2",
           "--trainer.enable_checkpointing", "true", "--trainer.default_root_dir", str(tmp_path),
           "--trainer.callbacks+=ModelCheckpoint", "--trainer.callbacks.save_last=true",
           "--trainer.callbacks.dirpath", str(tmp_path / "ckpt")]
    last = tmp_path / "ckpt" / "last.ckpt"
    proc = subprocess.Popen([sys.executable, "train.py", *run], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    while proc.poll() is None and not last.is_file():
        time.sleep(0.05)
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    first = torch.load(last, weights_only=False)
    output = train_py(*run, "--ckpt_path", "last")
    second = torch.load(last, weights_only=False)
    assert "Restoring states from the checkpoint path" in output and first["epoch"] == 0
    assert second["epoch"] == 1 and second["global_step"] == 2 * first["global_step"] > 0


@pytest.mark.parametrize("config", sorted(str(p) for p in Path("configs").rglob("*.yaml")
                                          if p.parent.name != "ablations" and p.name != "ddp.yaml"))
def test_every_config_parses(config: str, capsys) -> None:
    """Every shipped config resolves to a known model and data module (LightningCLI --print_config)."""
    with pytest.raises(SystemExit) as stop:
        train.main(["fit", "--config", config, "--print_config"])
    assert stop.value.code in (0, None) and "class_path" in capsys.readouterr().out


#: The CPU training configs of the VOS chapters, and whether their data is DAVIS from ../shared/data.
CPU_VOS_CONFIGS = {"configs/demo/frtm.yaml": False, "configs/frtm_lite0_synthetic_cpu.yaml": False,
                   "configs/frtm_davis2016_cpu.yaml": True, "configs/frtm_lite0_davis2016_cpu.yaml": True,
                   "configs/davos_davis2016_cpu.yaml": True}


@pytest.mark.parametrize("config", sorted(CPU_VOS_CONFIGS))
def test_cpu_vos_configs_deliver_training_batches(config: str, request) -> None:
    """The data module of each CPU config, as the config builds it (on its first three training sequences), gives
    its first two training batches (every source, mirroring, crops and zooms as configured): a sample those
    settings cannot make fails here, not minutes into a fit."""
    from jsonargparse import ArgumentParser
    from lightning.pytorch import LightningDataModule

    if CPU_VOS_CONFIGS[config]:
        request.getfixturevalue("shared_data")
    parser = ArgumentParser()
    parser.add_subclass_arguments(LightningDataModule, "data")
    data = yaml.safe_load(Path(config).read_text())["data"]
    data["init_args"]["num_workers"] = 0
    for key, keep in (("train_sequences", 3), ("val_sequences", 1)):  # fewer videos to read, the same settings
        if key in data["init_args"]:
            data["init_args"][key] = data["init_args"][key][:keep]
    module = parser.instantiate_classes(parser.parse_object({"data": data})).data
    module.setup("fit")
    batches, args = iter(module.train_dataloader()), data["init_args"]
    for _ in range(2):
        batch = next(batches)
        b = batch["ref_image"].shape[0]
        assert b == args["batch_size"] and batch["test_masks"].shape[:2] == (b, args["n_test_frames"])
        assert torch.isfinite(batch["ref_image"]).all() and (batch["ref_mask"].flatten(1).sum(1) > 0).all()


@pytest.mark.parametrize("overlay", sorted(str(p) for p in Path("configs/ablations").glob("*.yaml")))
def test_ablation_overlays_parse_over_the_davos_config(overlay: str, capsys) -> None:
    with pytest.raises(SystemExit):
        train.main(["fit", "--config", "configs/davos_davis2016_cpu.yaml", "--config", overlay, "--print_config"])
    out = capsys.readouterr().out
    assert ("distractors: false" in out) == overlay.endswith("lwl.yaml")
    assert ("soft_loss: false" in out) == overlay.endswith("hard_loss.yaml")


@pytest.mark.slow
def test_weight_averaged_frtm_checkpoint_loads_the_average(frtm_config, tmp_path) -> None:
    """A fit with ``EMAWeightAveraging`` (as the lite0 DAVIS config) saves the average as ``state_dict`` and the
    trained weights apart; the project's loader (bench, infer) gets the average."""
    from models.checkpoint import load_system, read_checkpoint

    config, _ = frtm_config
    train_py("fit", "--config", str(config), *SINGLE, "--trainer.max_steps", "3",
             "--trainer.enable_checkpointing", "true", "--trainer.default_root_dir", str(tmp_path),
             "--trainer.callbacks+=ModelCheckpoint", "--trainer.callbacks.save_last=true",
             "--trainer.callbacks.dirpath", str(tmp_path / "ckpt"),
             "--trainer.callbacks+=lightning.pytorch.callbacks.EMAWeightAveraging", "--trainer.callbacks.decay=0.5",
             "--trainer.callbacks.update_starting_at_step=0")
    content = read_checkpoint(tmp_path / "ckpt" / "last.ckpt")
    averaged, trained = content["state_dict"], content["current_model_state"]
    learnt = [name for name, value in trained.items() if value.is_floating_point() and "decoder" in name]
    assert learnt and any(not torch.equal(averaged[name], trained[name]) for name in learnt)
    loaded = load_system(FRTMSegmentation, tmp_path / "ckpt" / "last.ckpt").state_dict()
    assert all(torch.equal(loaded[name], averaged[name]) for name in learnt)

"""models.checkpoint: checkpoints load on the CPU in eval mode; missing, corrupt and foreign files are named."""

import lightning as L
import pytest
import torch

from core.errors import InputError
from models.checkpoint import datamodule_settings, load_system, newest_checkpoint, read_checkpoint
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem

SMALL = {"backbone": "resnet18", "stage": "layer2", "heads": 2, "head_channels": 8, "channels": 16}


def save_checkpoint(system: L.LightningModule, path, **extra):
    """A checkpoint as LightningCLI writes it (state dict, hyper-parameters with the class path, version);
    returns ``path``."""
    hparams = {**system.hparams, "_class_path": f"{type(system).__module__}.{type(system).__name__}"}
    torch.save({"state_dict": system.state_dict(), "hyper_parameters": hparams,
                "pytorch-lightning_version": L.__version__, **extra}, path)
    return path


def test_load_system_restores_the_weights(tmp_path) -> None:
    torch.manual_seed(0)
    system = HorizonFinderSystem(**SMALL)
    save_checkpoint(system, tmp_path / "finder.ckpt", datamodule_hyper_parameters={"input_width": 256})
    loaded = load_system(HorizonFinderSystem, tmp_path / "finder.ckpt")
    assert not loaded.training
    for key, value in system.state_dict().items():
        torch.testing.assert_close(loaded.state_dict()[key], value)
    assert datamodule_settings(tmp_path / "finder.ckpt") == {"input_width": 256}


def test_bad_checkpoints_are_named(tmp_path) -> None:
    with pytest.raises(InputError, match="checkpoint .*missing.ckpt does not exist"):
        read_checkpoint(tmp_path / "missing.ckpt")
    (tmp_path / "text.ckpt").write_text("hello")
    with pytest.raises(InputError, match="text.ckpt is not a readable Lightning checkpoint"):
        read_checkpoint(tmp_path / "text.ckpt")
    torch.save({"weights": 1}, tmp_path / "plain.pt")
    with pytest.raises(InputError, match="plain.pt is not a Lightning checkpoint"):
        read_checkpoint(tmp_path / "plain.pt")
    save_checkpoint(HorizonFinderSystem(**SMALL), tmp_path / "finder.ckpt")
    with pytest.raises(InputError, match="is not a HorizonSegmenterSystem checkpoint"):
        load_system(HorizonSegmenterSystem, tmp_path / "finder.ckpt")


def test_newest_checkpoint(tmp_path) -> None:
    import os

    assert newest_checkpoint(tmp_path) is None
    for name, mtime in (("a", 1000), ("b", 3000), ("c", 2000)):
        path = tmp_path / name / "last.ckpt"
        path.parent.mkdir()
        path.write_bytes(b"")
        os.utime(path, (mtime, mtime))
    assert newest_checkpoint(tmp_path) == tmp_path / "b" / "last.ckpt"

"""models.builders: every deployable model from a checkpoint or untrained; the sources checked."""

import pytest
import torch

from core.errors import InputError
from models.builders import (
    demo_horizon_checkpoint,
    frtm_system,
    frtm_tracker,
    horizon_finder,
    horizon_network,
    horizon_segmenter,
    level_panorama,
)
from models.horizon.segmenter import PanoramaSegmenter
from models.vos.tracker import FRTMTracker
from tests.models.test_checkpoint import SMALL, save_checkpoint

TINY_FRTM = {"mdim": 8, "tracker": {"channels": 8, "num_aug": 2, "memory_size": 4, "init_schedule": [2],
                                    "update_schedule": [2]}}


def test_horizon_networks_from_checkpoints_and_untrained(tmp_path) -> None:
    from models.horizon.lit import HorizonFinderSystem

    torch.manual_seed(0)
    system = HorizonFinderSystem(**SMALL)
    save_checkpoint(system, tmp_path / "finder.ckpt")
    finder = horizon_finder(ckpt=tmp_path / "finder.ckpt")
    image = torch.rand(1, 3, 32, 256)
    torch.testing.assert_close(finder(image), system.net.eval()(image))
    assert isinstance(horizon_segmenter(**SMALL), PanoramaSegmenter)
    assert isinstance(horizon_network("level"), type(level_panorama()))
    with pytest.raises(InputError, match="must be one of"):
        horizon_network("matcher")


def test_frtm_system_and_tracker(tmp_path) -> None:
    system = frtm_system(**TINY_FRTM)
    save_checkpoint(system, tmp_path / "frtm.ckpt")
    tracker = frtm_tracker(ckpt=tmp_path / "frtm.ckpt", memory_size=3, use_decoder=False)
    assert isinstance(tracker, FRTMTracker) and not tracker.use_decoder
    assert tracker.settings.memory_size == 3 and tracker.settings.channels == 8
    config = tmp_path / "tiny.yaml"
    config.write_text("model:\n  class_path: models.vos.lit.FRTMSegmentation\n  init_args:\n    mdim: 8\n")
    assert frtm_system(config=config).hparams.mdim == 8
    with pytest.raises(InputError, match="not both"):
        frtm_system(tmp_path / "frtm.ckpt", config=config)
    with pytest.raises(InputError, match="unknown tracker settings"):
        frtm_tracker(ckpt=tmp_path / "frtm.ckpt", chanels=4)
    (tmp_path / "other.yaml").write_text("model:\n  class_path: models.horizon.lit.HorizonFinderSystem\n")
    with pytest.raises(InputError, match="does not configure a FRTMSegmentation"):
        frtm_system(config=tmp_path / "other.yaml")


def test_demo_checkpoint_is_none_without_a_training(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert demo_horizon_checkpoint("finder") is None
    path = tmp_path / "outputs" / "horizon" / "finder_demo" / "version_0" / "checkpoints" / "last.ckpt"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"")
    assert demo_horizon_checkpoint("finder") == path.relative_to(tmp_path)

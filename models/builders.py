"""One builder per deployable model, torchvision style: each returns a ready PyTorch model from a Lightning
checkpoint (``ckpt=``), or an untrained model from keyword arguments. Commands, benchmarks and exports build their
models here; the exported graphs run in the torch-free deployment runtime (``runtime/``), which ``infer.py``'s
``--onnx`` options call.

    finder = horizon_finder(ckpt="finder.ckpt")            # nn.Module: (B, 3, H, W) -> (B, 4)
    tracker = frtm_tracker(ckpt="frtm.ckpt", channels=64)  # FRTMTracker with changed settings
    tracker = davos_tracker(ckpt="davos.ckpt", winner_takes_all=False)  # DAVOSTracker, an ablation switch
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from core.cylinder import LevelPanorama
from core.errors import InputError
from models.checkpoint import load_system, newest_checkpoint, read_checkpoint
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem
from models.horizon.segmenter import PanoramaSegmenter
from models.vos.davos_lit import DAVOSSegmentation
from models.vos.davos_tracker import DAVOSTracker
from models.vos.lit import FRTMSegmentation
from models.vos.tracker import FRTMTracker

#: A file or folder given as a string or a path.
Source = str | Path


def horizon_finder(ckpt: Source | None = None, **network_args) -> nn.Module:
    """HorizonFinder (thesis ch. 4.3): tilted panoramas (B, 3, H, W) in [0, 1] -> (B, 4) (sin, cos) of pitch
    and roll. Without a checkpoint, an untrained ``HorizonFinderSystem(**network_args)`` network."""
    system = load_system(HorizonFinderSystem, ckpt) if ckpt is not None else HorizonFinderSystem(**network_args)
    return system.net.eval()


def horizon_segmenter(ckpt: Source | None = None, **network_args) -> nn.Module:
    """HorizonSegmenter on whole levelled panoramas (``PanoramaSegmenter``): (B, 3, H, W) -> (B, 2, W) tan
    elevation of the horizon and the water line. Without a checkpoint, an untrained network."""
    system = load_system(HorizonSegmenterSystem, ckpt) if ckpt is not None else HorizonSegmenterSystem(**network_args)
    return PanoramaSegmenter(system.net).eval()


#: Where ``train.py`` writes the demo trainings of the horizon networks (``configs/demo/horizon_*.yaml``).
HORIZON_DEMO_RUNS = Path("outputs/horizon")
HORIZON_NETWORKS = ("finder", "segmenter", "level")


def horizon_network(which: str, ckpt: Source | None = None, **network_args) -> nn.Module:
    """``horizon_finder``, ``horizon_segmenter`` or ``level_panorama`` by name (``which``)."""
    if which not in HORIZON_NETWORKS:
        raise InputError(f"the horizon network must be one of {', '.join(HORIZON_NETWORKS)}, got {which!r}")
    if which == "level":
        return level_panorama()
    builder = horizon_finder if which == "finder" else horizon_segmenter
    return builder(ckpt, **network_args)


def demo_horizon_checkpoint(which: str) -> Path | None:
    """Newest ``last.ckpt`` of the demo training of horizon network ``which`` (finder, segmenter), if any."""
    return newest_checkpoint(HORIZON_DEMO_RUNS, f"{which}_demo/**/last.ckpt")


def level_panorama() -> nn.Module:
    """The levelling warp (thesis eq. 4.2): image (B, 3, H, W), pitch (B,), roll (B,) rad -> (B, 3, H, W)."""
    return LevelPanorama().eval()


def frtm_system(ckpt: Source | None = None, config: Source | None = None, **hparams) -> FRTMSegmentation:
    """The FRTM training system (backbone, decoder, tracker settings) in eval mode: from a checkpoint, from the
    ``model`` section of a train.py YAML config (untrained; same architecture and settings), or untrained from
    ``hparams``. Untrained systems are built with torch's seed 0."""
    if ckpt is not None and config is not None:
        raise InputError("FRTM system: give a checkpoint or a config, not both")
    if ckpt is not None:
        return load_system(FRTMSegmentation, ckpt)
    if config is not None:
        hparams = {**_config_model_args(Path(config), FRTMSegmentation), **hparams}
    torch.manual_seed(0)
    return FRTMSegmentation(**hparams).eval()


def frtm_tracker(ckpt: Source, use_decoder: bool = True, **settings) -> FRTMTracker:
    """An FRTM video object segmenter (thesis ch. 5): ``FRTMTracker`` on a checkpoint's networks with its tracker
    settings changed by ``settings`` (``FRTMSettings`` fields)."""
    return frtm_system(ckpt).make_tracker(use_decoder=use_decoder, **settings)


def davos_system(ckpt: Source | None = None, config: Source | None = None, **hparams) -> DAVOSSegmentation:
    """The DAVOS/LWL training system (thesis ch. 6) in eval mode: from a checkpoint, from the ``model`` section of
    a train.py YAML config (untrained), or untrained from ``hparams``; untrained systems use torch's seed 0."""
    if ckpt is not None and config is not None:
        raise InputError("DAVOS system: give a checkpoint or a config, not both")
    if ckpt is not None:
        return load_system(DAVOSSegmentation, ckpt)
    if config is not None:
        hparams = {**_config_model_args(Path(config), DAVOSSegmentation), **hparams}
    torch.manual_seed(0)
    return DAVOSSegmentation(**hparams).eval()


def davos_tracker(ckpt: Source, **settings) -> DAVOSTracker:
    """A DAVOS (or LWL) video object segmenter (thesis ch. 6) on a checkpoint's networks, its tracker settings
    changed by ``settings`` (``DAVOSSettings`` fields, e.g. the ablation ``winner_takes_all=False``)."""
    return davos_system(ckpt).make_tracker(**settings)


def vos_tracker(ckpt: Source) -> FRTMTracker | DAVOSTracker:
    """The tracker of a VOS checkpoint, FRTM or DAVOS/LWL, by the system class the checkpoint was trained as."""
    stored = read_checkpoint(ckpt, "VOS checkpoint").get("hyper_parameters", {}).get("_class_path", "")
    if stored.endswith(DAVOSSegmentation.__name__):
        return davos_tracker(ckpt)
    return frtm_tracker(ckpt)


def _config_model_args(path: Path, system: type[nn.Module]) -> dict:
    """``init_args`` of the ``model`` section of a LightningCLI YAML config, checked to configure ``system``."""
    import yaml

    if not path.is_file():
        raise InputError(f"config {path} does not exist")
    try:
        model = (yaml.safe_load(path.read_text()) or {}).get("model", {})
    except yaml.YAMLError as err:
        raise InputError(f"config {path} is not valid YAML: {err}") from err
    if not str(model.get("class_path", "")).endswith(system.__name__):
        raise InputError(f"config {path} does not configure a {system.__name__} model")
    return dict(model.get("init_args", {}))

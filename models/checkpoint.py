"""Reading Lightning checkpoints with errors that name the file: the one place that opens a checkpoint
(``torch.load``, ``load_from_checkpoint``); ``models.builders`` builds every deployable model on it."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import lightning as L
import torch
from torch import nn

from core.errors import InputError

System = TypeVar("System", bound=L.LightningModule)


def read_checkpoint(path: str | Path, what: str = "checkpoint") -> dict:
    """The raw content of a Lightning checkpoint file (on the CPU); ``what`` names it in errors."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what} {path} does not exist")
    try:
        content = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as err:  # pickle, zip and torch errors alike: the file is not a checkpoint
        raise InputError(f"{what} {path} is not a readable Lightning checkpoint: {err}") from err
    if not isinstance(content, dict) or "state_dict" not in content:
        raise InputError(f"{what} {path} is not a Lightning checkpoint (no state_dict)")
    return content


def load_system(system: type[System], path: str | Path) -> System:
    """The ``system`` (a LightningModule class) stored in checkpoint ``path``, on the CPU in eval mode."""
    content = read_checkpoint(path, f"{system.__name__} checkpoint")
    stored = content.get("hyper_parameters", {})
    try:
        model = system.load_from_checkpoint(str(path), map_location="cpu", weights_only=False)
    except (RuntimeError, KeyError, TypeError, ValueError) as err:
        raise InputError(f"checkpoint {path} is not a {system.__name__} checkpoint ({err}; its hyper-parameters: "
                         f"{sorted(stored)})") from err
    return model.eval()


def check_checkpoint_fits(model: nn.Module, path: str | Path) -> None:
    """``InputError`` unless checkpoint ``path`` holds weights of exactly ``model``'s names and shapes (e.g. a
    ``--ckpt_path`` of another model class or architecture)."""
    state = read_checkpoint(path)["state_dict"]
    own = model.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    reshaped = sorted(k for k in set(own) & set(state) if tuple(own[k].shape) != tuple(state[k].shape))
    if missing or unexpected or reshaped:
        example = (missing or unexpected or reshaped)[0]
        raise InputError(f"checkpoint {path} does not fit the configured {type(model).__name__}: {len(missing)} "
                         f"weights missing, {len(unexpected)} unexpected, {len(reshaped)} of another shape "
                         f"(e.g. {example})")


def datamodule_settings(path: str | Path) -> dict:
    """The data-module hyper-parameters a checkpoint was trained with (empty when it stores none)."""
    return dict(read_checkpoint(path).get("datamodule_hyper_parameters", {}))


def newest_checkpoint(root: str | Path, pattern: str = "**/last.ckpt") -> Path | None:
    """The most recently written checkpoint matching ``pattern`` under ``root``, or None when there is none."""
    found = sorted(Path(root).glob(pattern), key=lambda p: p.stat().st_mtime)
    return found[-1] if found else None

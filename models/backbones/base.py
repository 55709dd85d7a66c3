"""Common behaviour of the feature extractors: frozen mode and the input check."""

from __future__ import annotations

import torch
from torch import nn

from core.errors import InputError

STAGES = ("layer1", "layer2", "layer3", "layer4")
STRIDES = {"layer1": 4, "layer2": 8, "layer3": 16, "layer4": 32}


def check_stages(stages: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The requested stages in network order; raises ``InputError`` for an empty or unknown selection."""
    stages = tuple(stages)
    unknown = [s for s in stages if s not in STAGES]
    if unknown or not stages:
        raise InputError(f"backbone stages {stages!r} must be a non-empty subset of {STAGES}")
    return tuple(s for s in STAGES if s in stages)


class Backbone(nn.Module):
    """Base of the backbones: four stages ``layer1`` .. ``layer4`` at strides 4, 8, 16, 32, RGB input in [0, 1].

    Subclasses set ``channels`` (``{stage: channels}``), ``strides`` and ``stages`` and call ``freeze`` at the
    end of ``__init__``. A frozen backbone takes no gradients and keeps batch norm in eval mode in ``train()``.
    """

    frozen: bool
    channels: dict[str, int]
    strides: dict[str, int]
    stages: tuple[str, ...]

    def freeze(self, frozen: bool) -> None:
        self.frozen = frozen
        if frozen:
            self.requires_grad_(False)
            self.eval()

    def train(self, mode: bool = True) -> Backbone:
        """Switch mode; a frozen backbone always stays in eval mode (batch-norm statistics fixed)."""
        return super().train(mode and not self.frozen)

    @staticmethod
    def check_image(image: torch.Tensor) -> None:
        if image.ndim != 4 or image.shape[1] != 3:
            raise InputError(f"backbone input must be (B, 3, H, W) RGB, got shape {tuple(image.shape)}")

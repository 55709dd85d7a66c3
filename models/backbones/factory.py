"""Backbones by name, so configs choose ``resnet*`` or ``efficientnet_lite*`` with one string."""

from __future__ import annotations

from core.errors import InputError
from models.backbones.base import STAGES, Backbone
from models.backbones.efficientnet_lite import VARIANTS, EfficientNetLiteBackbone
from models.backbones.resnet import RESNETS, ResNetBackbone

BACKBONES = (*RESNETS, *VARIANTS)


def build_backbone(
    name: str,
    weights: str | None = None,
    frozen: bool = True,
    stages: tuple[str, ...] | list[str] = STAGES,
) -> Backbone:
    """The backbone ``name`` (``resnet18`` .. ``resnet152``, ``efficientnet_lite0`` .. ``2``).

    Args:
        weights: ``"imagenet"`` for either family; a torchvision weights name (``"IMAGENET1K_V2"``) for ResNets;
            ``None`` for random initialisation.
        frozen, stages: as in ``ResNetBackbone``.
    """
    if name in RESNETS:
        return ResNetBackbone(name, weights, frozen, stages)
    if name in VARIANTS:
        return EfficientNetLiteBackbone(name, weights, frozen, stages)
    raise InputError(f"backbone name {name!r} is not one of {', '.join(BACKBONES)}")

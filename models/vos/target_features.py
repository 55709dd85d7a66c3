"""The features a target model reads (thesis ch. 5.3 and 6.1): one backbone stage, or several at the first one's
resolution (DAVOS reads layer2 and layer3 concatenated at stride 8), each scaled so that the target model's
regularisation constants mean the same for every backbone."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError

FEATURE_NORMS = ("none", "fixed", "instance_l2")


def check_feature_norm(norm: str, scale: float) -> None:
    """``InputError`` unless ``norm`` is one of ``FEATURE_NORMS`` and ``scale`` is positive."""
    if norm not in FEATURE_NORMS:
        raise InputError(f"feature_norm must be one of {FEATURE_NORMS}, got {norm!r}")
    if not scale > 0:
        raise InputError(f"feature_scale must be positive, got {scale}")


def normalize_features(x: torch.Tensor, norm: str = "none", scale: float = 1.0) -> torch.Tensor:
    """Scale features (ImageNet EfficientNet-Lite stages have an RMS of about 6-9, ResNets about 1): ``"none"``
    keeps them, ``"fixed"`` divides by ``scale`` (e.g. the stage's RMS over natural images), ``"instance_l2"``
    scales each sample to unit root mean square over its channels and pixels (LWL's InstanceL2Norm).

    Shapes: x (..., D, h, w) -> same.
    """
    check_feature_norm(norm, scale)
    if norm == "none":
        return x
    if norm == "fixed":
        return x / scale
    return x * torch.rsqrt(x.pow(2).mean(dim=(-3, -2, -1), keepdim=True).clamp_min(1e-12))


class TargetFeatures(nn.Module):
    """Target-model input from a backbone's stage dict.

    Args:
        layers: a stage (``"layer3"``) or stages joined by ``+`` (``"layer2+layer3"``); the first sets the
            resolution, the others are resampled bilinearly (align_corners=False) to it.
        channels, strides: the backbone's ``{stage: channels}`` and ``{stage: stride}``.
        norm, scale: ``normalize_features`` applied to each stage before concatenation.

    Attributes:
        channels: D, the summed channels; stride: the first stage's stride.

    Shapes:
        ``{stage: (B, C_s, h_s, w_s)}`` -> (B, D, h, w).
    """

    def __init__(self, layers: str, channels: dict[str, int], strides: dict[str, int], norm: str = "none",
                 scale: float = 1.0) -> None:
        super().__init__()
        self.layers = layers.split("+")
        missing = [s for s in self.layers if s not in channels]
        if missing:
            raise InputError(f"backbone does not return the target-model stage(s) {missing} of {layers!r}")
        check_feature_norm(norm, scale)
        self.norm, self.scale = norm, scale
        self.channels = sum(channels[s] for s in self.layers)
        self.stride = strides[self.layers[0]]

    def forward(self, feats: dict[str, torch.Tensor]) -> torch.Tensor:
        first = normalize_features(feats[self.layers[0]], self.norm, self.scale)
        size = first.shape[-2:]
        rest = [normalize_features(F.interpolate(feats[s], size=size, mode="bilinear", align_corners=False),
                                   self.norm, self.scale) for s in self.layers[1:]]
        return torch.cat([first, *rest], -3) if rest else first

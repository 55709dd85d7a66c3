"""HorizonFinder (ch. 4.3, fig. 4.5): camera pitch and roll from a tilted 360-degree panorama.

ResNet backbone (``models.backbones``) -> column pooling (``ColumnPool``) -> two convolutional layers over the
columns (1x1 projection to few channels, then a circular 3-tap layer) -> a fully connected output of the
(sin, cos) pairs of pitch and roll. The fully connected layer sees the columns through their first Fourier
coefficients (mean, and means weighted by cos psi and sin psi of each column's azimuth): the S-curve of a
tilted horizon is exactly such a sinusoid, and the input width stays free (the thesis's footnote).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from models.backbones import build_backbone
from models.horizon.column_pool import ColumnPool


def fourier_pool(features: torch.Tensor) -> torch.Tensor:
    """(B, C, w) column features of a 360-degree panorama -> (B, 3C): means weighted by 1, cos psi, sin psi."""
    columns = features.shape[-1]
    psi = 2 * math.pi * (torch.arange(columns, dtype=features.dtype, device=features.device) + 0.5) / columns
    basis = torch.stack([torch.ones_like(psi), 2 * torch.cos(psi), 2 * torch.sin(psi)])  # (3, w)
    return torch.einsum("bcw,kw->bkc", features, basis).flatten(1) / columns


def sincos_to_angles(output: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, 4) (sin p, cos p, sin q, cos q) -> pitch (B,), roll (B,) in rad."""
    return torch.atan2(output[:, 0], output[:, 1]), torch.atan2(output[:, 2], output[:, 3])


class HorizonFinder(nn.Module):
    """Pitch and roll regression network.

    Args:
        backbone: backbone name (``models.backbones``: ``resnet50`` in the paper, ``efficientnet_lite0``).
        weights: ``"imagenet"`` (either family), a torchvision weights name, or None (random init).
        stage: backbone stage feeding the head (``layer4`` = stride 32).
        frozen: freeze the backbone.
        heads, head_channels: column pooling size.
        channels: channels of the two convolutional layers.

    Shapes:
        image (B, 3, H, W) RGB in [0, 1] -> (B, 4) unit (sin, cos) pairs of pitch and roll.
    """

    def __init__(
        self,
        backbone: str = "resnet50",
        weights: str | None = None,
        stage: str = "layer4",
        frozen: bool = False,
        heads: int = 4,
        head_channels: int = 32,
        channels: int = 64,
    ) -> None:
        super().__init__()
        self.stage = stage
        self.backbone = build_backbone(backbone, weights, frozen, (stage,))
        self.pool = ColumnPool(self.backbone.channels[stage], heads, head_channels)
        self.project = nn.Conv1d(self.pool.out_channels, channels, 1)
        self.context = nn.Conv1d(channels, channels, 3, padding=1, padding_mode="circular")
        self.output = nn.Linear(3 * channels, 4)
        with torch.no_grad():  # start level: an L1 loss on (sin, cos) holds a pair started near -1 at 180 degrees
            self.output.weight.mul_(0.1)
            self.output.bias.copy_(torch.tensor([0.0, 1.0, 0.0, 1.0]))

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        pooled, position = self.pool(self.backbone(image)[self.stage])
        x = F.relu(self.project(torch.cat([pooled, position], 1)))
        x = F.relu(self.context(x))
        out = self.output(fourier_pool(x)).reshape(-1, 2, 2)
        return (out / out.norm(dim=-1, keepdim=True).clamp(min=1e-6)).reshape(-1, 4)

"""HorizonSegmenter (ch. 4.3, fig. 4.6): horizon and water rows per column of a levelled panorama.

ResNet backbone -> column pooling -> 1x1 projection -> two layers that double the horizontal resolution
(transposed 1-D convolutions) -> a convolutional output head with two values per column: the height of the
horizon (sky above) and of the water line (sea below) above the image centre, in half-image-heights
(row = (H - 1) / 2 - y H / 2). The output is resampled linearly to the input columns. Nothing depends on the
input width (the head is convolutional, as the thesis's footnote recommends), so the network runs on crops of a
panorama as well as on whole ones; ``heights_to_tangent`` converts to tan elevation with the panorama's focal
length, and ``PanoramaSegmenter`` does so for whole 360-degree panoramas (the deployed form).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from models.backbones import build_backbone
from models.horizon.column_pool import ColumnPool


class HorizonSegmenter(nn.Module):
    """Per-column horizon and water line regression network.

    Args:
        backbone, weights, stage, frozen, heads, head_channels: as in ``HorizonFinder``.
        channels: channels of the projection and upsampling layers.

    Shapes:
        image (B, 3, H, W) levelled panorama (or part of one) in [0, 1] -> (B, 2, W) heights y of the horizon
        (channel 0) and water line (channel 1) per input column in half-image-heights above the centre.
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
        self.pool = ColumnPool(self.backbone.channels[stage], heads, head_channels, full_panorama=False)
        self.project = nn.Conv1d(self.pool.out_channels, channels, 1)
        self.up1 = nn.ConvTranspose1d(channels, channels, 4, stride=2, padding=1)
        self.up2 = nn.ConvTranspose1d(channels, channels, 4, stride=2, padding=1)
        self.head = nn.Conv1d(channels, 2, 3, padding=1)
        self.skip = nn.Conv1d(heads, 2, 1)  # the pooled positions are already heights

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        pooled, position = self.pool(self.backbone(image)[self.stage])
        x = F.relu(self.project(torch.cat([pooled, position], 1)))
        x = F.relu(self.up1(x))
        x = F.relu(self.up2(x))
        base = F.interpolate(self.skip(position), size=x.shape[-1], mode="linear", align_corners=False)
        out = self.head(x) * 0.1 + base
        return F.interpolate(out, size=image.shape[-1], mode="linear", align_corners=False)


def heights_to_tangent(heights: torch.Tensor, image_height: int, focal: float) -> torch.Tensor:
    """Heights above the centre in half-image-heights -> tan elevation, for a panorama of focal ``focal`` px/rad."""
    return heights * (image_height / 2.0) / focal


class PanoramaSegmenter(nn.Module):
    """A ``HorizonSegmenter`` on whole 360-degree panoramas, returning tan elevation (the deployed form).

    Shapes:
        image (B, 3, H, W) levelled panorama -> (B, 2, W) tan elevation of the horizon and the water line, with
        the focal length W / (2 pi) of the whole panorama.
    """

    def __init__(self, net: HorizonSegmenter) -> None:
        super().__init__()
        self.net = net
        self.backbone, self.stage = net.backbone, net.stage

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return heights_to_tangent(self.net(image), image.shape[-2], image.shape[-1] / (2 * math.pi))

"""Column pooling for panorama networks (ch. 4.3): reduce each feature column to a vector, keep where it looked.

Both horizon networks know that "there is a horizon profile stretching horizontally across the frame" and only
care about one or two places per column, so they pool the backbone features of each column. Here the pooling is
attention over the rows: K heads score every cell, a softmax over the rows of each column gives weights, and
each head returns the weighted features (projected to ``head_channels``) and the weighted mean of the rows'
vertical position (a soft arg-max, so the vertical position survives the pooling).

Row positions are tan elevations when the input is a whole 360-degree panorama (its width fixes the focal
length, ``full_panorama=True``), or heights above the centre in half-image-heights otherwise (crops of a
panorama, camera images), which depend on neither the input width nor the input height.
"""

from __future__ import annotations

import math

import torch
from torch import nn


def row_height_grid(rows: int, dtype: torch.dtype, device) -> torch.Tensor:
    """Height above the image centre of each of ``rows`` feature rows in half-image-heights, (rows,).

    Feature row i of stride s is centred on input row v_i = (i + 0.5) s - 0.5 of an image of height H = h s,
    so ((H - 1) / 2 - v_i) / (H / 2) = (h - 2 i - 1) / h.
    """
    i = torch.arange(rows, dtype=dtype, device=device)
    return (rows - 2 * i - 1) / rows


def row_tangent_grid(rows: int, columns: int, dtype: torch.dtype, device) -> torch.Tensor:
    """tan elevation at the centre of each of ``rows`` feature rows of a 360-degree panorama, (rows,).

    A feature map (h, w) of a panorama (H, W) with stride s has row i centred on input row (i + 0.5) s - 0.5,
    so with f = W / (2 pi) = w s / (2 pi): t_i = ((H - 1) / 2 - v_i) / f = pi (h - 2 i - 1) / w.
    """
    i = torch.arange(rows, dtype=dtype, device=device)
    return math.pi * (rows - 2 * i - 1) / columns


class ColumnPool(nn.Module):
    """Attention pooling of feature columns.

    Args:
        in_channels: backbone channels C.
        heads: number of attention heads K.
        head_channels: feature channels per head d.
        full_panorama: inputs are whole 360-degree panoramas (positions in tan elevation) or not (positions in
            half-image-heights above the centre).

    Shapes:
        (B, C, h, w) -> features (B, K * d, w) and positions (B, K, w).
    """

    def __init__(self, in_channels: int, heads: int = 4, head_channels: int = 32, full_panorama: bool = True) -> None:
        super().__init__()
        self.heads, self.head_channels, self.full_panorama = heads, head_channels, full_panorama
        self.score = nn.Conv2d(in_channels, heads, 1)
        self.value = nn.Conv2d(in_channels, heads * head_channels, 1)

    @property
    def out_channels(self) -> int:
        return self.heads * (self.head_channels + 1)

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        batch, _, rows, columns = features.shape
        weights = torch.softmax(self.score(features), dim=2)  # (B, K, h, w)
        values = self.value(features).reshape(batch, self.heads, self.head_channels, rows, columns)
        pooled = (weights[:, :, None] * values).sum(3).reshape(batch, self.heads * self.head_channels, columns)
        if self.full_panorama:
            grid = row_tangent_grid(rows, columns, features.dtype, features.device)
        else:
            grid = row_height_grid(rows, features.dtype, features.device)
        position = (weights * grid[None, None, :, None]).sum(2)
        return pooled, position

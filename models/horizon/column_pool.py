"""Column pooling for panorama networks (ch. 4.3): reduce each feature column to a vector, keep where it looked.

Both horizon networks know that "there is a horizon profile stretching horizontally across the frame" and only
care about one or two places per column, so they pool the backbone features of each column. Here the pooling is
attention over the rows: K heads score every cell, a softmax over the rows of each column gives weights, and
each head returns the weighted features (projected to ``head_channels``) and the weighted mean of the rows'
tan elevation (a soft arg-max, so the vertical position survives the pooling). Nothing depends on the input
height or width.
"""

from __future__ import annotations

import math

import torch
from torch import nn


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

    Shapes:
        (B, C, h, w) -> features (B, K * d, w) and positions (B, K, w) in tan elevation.
    """

    def __init__(self, in_channels: int, heads: int = 4, head_channels: int = 32) -> None:
        super().__init__()
        self.heads, self.head_channels = heads, head_channels
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
        tangent = row_tangent_grid(rows, columns, features.dtype, features.device)
        position = (weights * tangent[None, None, :, None]).sum(2)
        return pooled, position

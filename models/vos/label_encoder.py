"""The label encoder of LWL and DAVOS (thesis ch. 6.1, fig. 6.1; paper E): a small residual network that turns
a (soft) label, [target] for LWL or [target, distractor] for DAVOS, into the K-channel mask encoding E(y) the
target model learns to predict and the spatial weights W(y) of its residual, at the features' stride.

Layout (LWL ``ResidualDS16SW``, without batch norm): 3x3 convolution with stride 2 and ReLU, 3x3 max pool with
stride 2, residual blocks down to the stride, then E(y) = ReLU(3x3 conv) and W(y) = 3x3 conv whose weights
start at 0 and bias at 1 (every residual weighs 1 before training).

With ``pass_labels`` the first L of the K encoding channels are the labels themselves, area-averaged to the
features' size, and only the other K - L are learnt. A learnt encoding starts as noise that the decoder cannot
read yet, and LWL learns its way out of that over tens of thousands of steps; with the labels passed through,
the target model predicts the (coarse) target and distractor masks from the first step, as FRTM's does, and
the learnt channels add what the decoder finds useful.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError


def _area_weights(size_in: int, size_out: int, like: torch.Tensor) -> torch.Tensor:
    """(size_out, size_in) row-stochastic matrix of adaptive average pooling's bins: output i averages inputs
    floor(i size_in / size_out) .. ceil((i + 1) size_in / size_out) - 1."""
    i = torch.arange(size_out, device=like.device)
    start = (i * size_in) // size_out
    end = ((i + 1) * size_in + size_out - 1) // size_out
    j = torch.arange(size_in, device=like.device)
    inside = ((j >= start[:, None]) & (j < end[:, None])).to(like.dtype)
    return inside / inside.sum(1, keepdim=True)


def area_resize(x: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """``F.interpolate(x, size, mode="area")`` (adaptive average pooling) as two matrix products, so that an ONNX
    graph keeps its bins right at every input size: (N, C, H, W) -> (N, C, h, w)."""
    rows = _area_weights(x.shape[-2], size[0], x)
    cols = _area_weights(x.shape[-1], size[1], x)
    return rows @ x @ cols.transpose(0, 1)


class ResidualBlock(nn.Module):
    """x -> ReLU(conv3(ReLU(conv3(x))) + shortcut(x)); the shortcut is a strided 1x1 convolution when the
    stride or the width changes."""

    def __init__(self, in_channels: int, channels: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, channels, 3, stride, 1)
        self.conv2 = nn.Conv2d(channels, channels, 3, 1, 1)
        same = stride == 1 and in_channels == channels
        self.shortcut = nn.Identity() if same else nn.Conv2d(in_channels, channels, 1, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.conv2(F.relu(self.conv1(x))) + self.shortcut(x))


class LabelEncoder(nn.Module):
    """Mask encoding E(y) and spatial weights W(y) of labels.

    Args:
        in_channels: label channels L (1: target; 2: target and distractor).
        out_channels: K (LWL 16 at stride 16; DAVOS 32 at stride 8).
        stride: 8 or 16, the target-model features' stride.
        dims: widths of the stem and the residual stages.
        pass_labels: the first L encoding channels are the area-averaged labels (K > L needed).

    Shapes:
        labels (N, L, H, W) in [0, 1], size (h, w) of the features -> E (N, K, h, w), W (N, K, h, w); without a
        size the output keeps the encoder's own size, ceil(H / stride) x ceil(W / stride), which is the stage size
        of the ResNet and EfficientNet-Lite backbones.
    """

    def __init__(self, in_channels: int = 2, out_channels: int = 16, stride: int = 8,
                 dims: tuple[int, int, int] | list[int] = (16, 32, 64), pass_labels: bool = False) -> None:
        super().__init__()
        if stride not in (8, 16):
            raise InputError(f"label encoder stride must be 8 or 16, got {stride}")
        if in_channels < 1 or out_channels < 1 or (pass_labels and out_channels <= in_channels):
            raise InputError(f"label encoder channels must be >= 1 (more outputs than labels when passing them "
                             f"through), got {in_channels} -> {out_channels}")
        d0, d1, d2 = dims
        self.in_channels = in_channels
        self.pass_labels = pass_labels
        self.stem = nn.Sequential(nn.Conv2d(in_channels, d0, 3, 2, 1), nn.ReLU(inplace=True), nn.MaxPool2d(3, 2, 1))
        self.blocks = nn.Sequential(ResidualBlock(d0, d1, 2), ResidualBlock(d1, d2, 2 if stride == 16 else 1))
        self.encoding = nn.Conv2d(d2, out_channels - (in_channels if pass_labels else 0), 3, padding=1)
        self.weighting = nn.Conv2d(d2, out_channels, 3, padding=1)
        nn.init.zeros_(self.weighting.weight)
        nn.init.ones_(self.weighting.bias)

    def forward(self, labels: torch.Tensor, size: tuple[int, int] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        if labels.ndim != 4 or labels.shape[1] != self.in_channels:
            raise InputError(f"labels must be (N, {self.in_channels}, H, W), got {tuple(labels.shape)}")
        h = self.blocks(self.stem(labels))
        if size is not None and h.shape[-2:] != tuple(size):  # backbones that round odd sizes differently
            h = F.interpolate(h, size=size, mode="bilinear", align_corners=False)
        encoding = F.relu(self.encoding(h))
        if self.pass_labels:
            encoding = torch.cat([area_resize(labels, h.shape[-2:]), encoding], 1)
        return encoding, self.weighting(h)

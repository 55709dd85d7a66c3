"""FRTM segmentation decoder (thesis ch. 5.3, fig. 5.3-5.4; paper D): DFN-style stages from the
deepest backbone stage to the shallowest, each with a target segmentation encoder (TSE) that injects the
resized target-model score, refinement residual blocks (RRB) and a channel attention block (CAB), followed by
the upsampler from stride 4 to image resolution.

FRTM's score has one channel and the decoder one output logit; LWL and DAVOS (thesis ch. 6) feed it the
K-channel mask encoding their target model predicts, and DAVOS reads two logits (target, distractor).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError


def _conv(cin: int, cout: int, k: int) -> nn.Conv2d:
    return nn.Conv2d(cin, cout, k, padding=k // 2)


class TSE(nn.Module):
    """Target segmentation encoder: reduce backbone features, concatenate the score, transform.

    1x1 (C_l -> m), ReLU, 1x1 (m -> m); concat the S score channels (m + S); 3x3 (m+S -> m+S), ReLU,
    3x3 (m+S -> m+S), ReLU, 3x3 (m+S -> m), ReLU. Also returns the global average pool of the reduced features
    (used by the deepest CAB).
    """

    def __init__(self, in_channels: int, mdim: int = 64, score_channels: int = 1) -> None:
        super().__init__()
        wide = mdim + score_channels
        self.reduce = nn.Sequential(_conv(in_channels, mdim, 1), nn.ReLU(inplace=True), _conv(mdim, mdim, 1))
        self.transform = nn.Sequential(
            _conv(wide, wide, 3), nn.ReLU(inplace=True),
            _conv(wide, wide, 3), nn.ReLU(inplace=True),
            _conv(wide, mdim, 3), nn.ReLU(inplace=True),
        )

    def forward(self, features: torch.Tensor, score: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, C_l, h, w), (N, S, h, w) -> (N, m, h, w), pooled (N, m, 1, 1)."""
        x = self.reduce(features)
        pooled = F.adaptive_avg_pool2d(x, 1)
        return self.transform(torch.cat([x, score], 1)), pooled


class RRB(nn.Module):
    """Refinement residual block: 1x1 conv, then x + conv3-BN-ReLU-conv3(x), ReLU."""

    def __init__(self, in_channels: int, channels: int) -> None:
        super().__init__()
        self.conv1x1 = _conv(in_channels, channels, 1)
        self.residual = nn.Sequential(
            _conv(channels, channels, 3), nn.BatchNorm2d(channels), nn.ReLU(inplace=True), _conv(channels, channels, 3)
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.conv1x1(x)
        return F.relu(x + self.residual(x))


class CAB(nn.Module):
    """Channel attention block: a sigmoid gate from pooled shallow + pooled deeper features scales the shallow
    features; the (upsampled) deeper features are added. For the deepest stage "deeper" is the TSE pool."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.gate = nn.Sequential(_conv(2 * channels, channels, 1), nn.ReLU(inplace=True), _conv(channels, channels, 1))

    def forward(self, deeper: torch.Tensor, shallow: torch.Tensor) -> torch.Tensor:
        pooled = torch.cat([F.adaptive_avg_pool2d(shallow, 1), F.adaptive_avg_pool2d(deeper, 1)], 1)
        up = F.interpolate(deeper, size=shallow.shape[-2:], mode="bilinear", align_corners=False)
        return shallow * torch.sigmoid(self.gate(pooled)) + up


def _cubic(d: torch.Tensor, a: float = -0.75) -> torch.Tensor:
    """Keys' cubic convolution kernel at distances d (PyTorch's bicubic, a = -0.75)."""
    d = d.abs()
    near = ((a + 2) * d - (a + 3)) * d * d + 1
    far = ((a * d - 5 * a) * d + 8 * a) * d - 4 * a
    return torch.where(d <= 1, near, torch.where(d < 2, far, torch.zeros_like(d)))


def bicubic_upsample_matrix(n: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """(2n, n) matrix of 2x bicubic upsampling along one axis (align_corners=False, edge samples repeated).

    Built from element-wise ops on ``arange`` only, so it follows a symbolic ``n`` through ONNX export.
    """
    src = (torch.arange(2 * n, device=device, dtype=dtype) + 0.5) / 2 - 0.5
    base = src.floor()
    cols = torch.arange(n, device=device, dtype=dtype)
    m = torch.zeros_like(src[:, None] * cols)
    for offset in (-1, 0, 1, 2):
        tap = base + offset
        hit = (tap.clamp(0, n - 1)[:, None] == cols).to(dtype)
        m = m + _cubic(src - tap)[:, None] * hit
    return m


def bicubic_upsample2x(x: torch.Tensor) -> torch.Tensor:
    """``F.interpolate(x, scale_factor=2, mode="bicubic", align_corners=False)`` as two matrix products.

    Same values; the products' backward pass is many times faster on CPU than the interpolation kernel's.

    Args:
        x: (N, C, H, W).

    Returns:
        (N, C, 2H, 2W).
    """
    if x.dim() != 4:
        raise InputError(f"bicubic_upsample2x expects (N, C, H, W), got shape {tuple(x.shape)}")
    rows = bicubic_upsample_matrix(x.shape[-2], x.dtype, x.device)
    cols = bicubic_upsample_matrix(x.shape[-1], x.dtype, x.device)
    return rows @ x @ cols.transpose(0, 1)


class Upsampler(nn.Module):
    """Stride 4 to image size: bicubic 2x, 3x3 (m -> m/2), ReLU, bicubic 2x, bilinear to size, 3x3 (m/2 -> O)."""

    def __init__(self, mdim: int = 64, out_channels: int = 1) -> None:
        super().__init__()
        self.conv1 = _conv(mdim, mdim // 2, 3)
        self.conv2 = _conv(mdim // 2, out_channels, 3)

    def forward(self, x: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
        x = F.relu(self.conv1(bicubic_upsample2x(x)))
        x = bicubic_upsample2x(x)
        x = F.interpolate(x, size=size, mode="bilinear", align_corners=False)
        return self.conv2(x)


class SegmentationDecoder(nn.Module):
    """Decoder from a target-model score and backbone features to full-resolution logits.

    Args:
        in_channels: ``{stage: channels}`` of the backbone stages used, e.g. ``ResNetBackbone.channels``.
        mdim: width of the decoder (FRTM 64).
        stages: stages in decoding order, deepest first.
        score_channels: S, channels of the score (FRTM 1; LWL/DAVOS the K channels of the mask encoding).
        out_channels: O, output logits (FRTM and LWL 1; DAVOS 2: target and distractor).
    """

    def __init__(
        self,
        in_channels: dict[str, int],
        mdim: int = 64,
        stages: tuple[str, ...] | list[str] = ("layer4", "layer3", "layer2", "layer1"),
        score_channels: int = 1,
        out_channels: int = 1,
    ) -> None:
        super().__init__()
        missing = [s for s in stages if s not in in_channels]
        if missing:
            raise InputError(f"decoder stages {missing} have no channel count in {in_channels}")
        self.stages = tuple(stages)
        if score_channels < 1 or out_channels < 1:
            raise InputError(f"decoder score and output channels must be >= 1, got {score_channels}, {out_channels}")
        self.tse = nn.ModuleDict({s: TSE(in_channels[s], mdim, score_channels) for s in self.stages})
        self.rrb1 = nn.ModuleDict({s: RRB(mdim, mdim) for s in self.stages})
        self.cab = nn.ModuleDict({s: CAB(mdim) for s in self.stages})
        self.rrb2 = nn.ModuleDict({s: RRB(mdim, mdim) for s in self.stages})
        self.upsampler = Upsampler(mdim, out_channels)
        self._init_weights()

    def _init_weights(self) -> None:
        """He (fan-in, ReLU) initialisation of every convolution but the final logit one, zero biases.

        PyTorch's default (uniform, a = sqrt(5)) shrinks the signal at each of the ~30 convolutions, so an
        untrained decoder's logits hardly depend on the score or the features (std ~0.04 against ~1 here).
        """
        for module in self.modules():
            if isinstance(module, nn.Conv2d) and module is not self.upsampler.conv2:
                nn.init.kaiming_normal_(module.weight, mode="fan_in", nonlinearity="relu")
                nn.init.zeros_(module.bias)

    def forward(self, score: torch.Tensor, features: dict[str, torch.Tensor], size: tuple[int, int]) -> torch.Tensor:
        """Logits (N, O, H, W) from scores (N, S, h, w) and features ``{stage: (N or 1, C_l, h_l, w_l)}``.

        Features with batch 1 are shared by all N scores (several objects in one frame).
        """
        x = None
        n = score.shape[0]
        for stage in self.stages:
            feat = features[stage]
            if feat.shape[0] != n:
                feat = feat.expand(n, -1, -1, -1)
            s = F.interpolate(score, size=feat.shape[-2:], mode="bilinear", align_corners=False)
            h, pooled = self.tse[stage](feat, s)
            h = self.rrb1[stage](h)
            h = self.cab[stage](pooled if x is None else x, h)
            x = self.rrb2[stage](h)
        return self.upsampler(x, size)


def flip_averaged_logits(
    decoder: SegmentationDecoder,
    score: torch.Tensor,
    features: dict[str, torch.Tensor],
    mirrored: dict[str, torch.Tensor],
    size: tuple[int, int],
) -> torch.Tensor:
    """Test-time flip augmentation of the decoder: the mean of its logits for the frame and the logits for the
    left-right mirrored frame, mirrored back.

    The mirrored frame is decoded from the mirrored score and ``mirrored``, its backbone features; the result is
    exactly symmetric: mirrored inputs (score, features and ``mirrored`` swapped) give the mirrored logits.

    Args:
        decoder: the segmentation decoder.
        score: (N, S, h, w) target-model scores.
        features, mirrored: ``{stage: (N or 1, C_l, h_l, w_l)}`` backbone features of the frame and of the
            mirrored frame.
        size: (H, W) of the output.

    Returns:
        (N, O, H, W) logits.
    """
    direct = decoder(score, features, size)
    return 0.5 * (direct + decoder(score.flip(-1), mirrored, size).flip(-1))

"""The LWL/DAVOS target model (thesis ch. 6.1-6.2; paper E): a K-channel convolution filter tau applied to
projected, normalised backbone features, predicting the label encoding E(y) of a mask.

    scores = tau * x                        (K channels, zero padding, same size)
    r(tau) = [ sqrt(gamma_s) W_s (tau * x_s - E_s)  for every memory sample s,   lambda tau ]

E_s and W_s are the label encoding and spatial weights of sample s (``LabelEncoder``), gamma_s its memory
weight and lambda the learnt regularisation. ``apply_filter`` is a grouped convolution (one group per problem)
and ``filter_gradient`` its adjoint in the filter (a convolution of the features by the residual; in an export one
matrix product of the features with the residual's shifted windows), so the
steepest-descent trainer needs no autograd: it runs under ``torch.inference_mode``, exports to ONNX (with one
problem per graph call) and stays differentiable for meta-learning.

Shapes: features x (B, S, P, h, w); filter tau (B, K, P, k, k); scores, encodings E and weights W
(B, S, K, h, w); memory weights gamma (B, S). B problems (objects or training samples), S samples each.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError
from models.export_mode import exporting
from models.vos.target_features import normalize_features
from models.vos.target_model import tap_windows


def apply_filter(x: torch.Tensor, tau: torch.Tensor) -> torch.Tensor:
    """tau * x per problem: (B, S, P, h, w), (B, K, P, k, k) -> (B, S, K, h, w)."""
    b, s, p, h, w = x.shape
    k, size = tau.shape[1], tau.shape[-1]
    out = F.conv2d(x.transpose(0, 1).reshape(s, b * p, h, w), tau.reshape(b * k, p, size, size),
                   padding=size // 2, groups=b)
    return out.view(s, b, k, h, w).transpose(0, 1)


def filter_gradient(x: torch.Tensor, q: torch.Tensor, size: int) -> torch.Tensor:
    """Adjoint of ``apply_filter`` in the filter, d<q, tau * x>/d tau: (B, S, P, h, w), (B, S, K, h, w) ->
    (B, K, P, k, k), i.e. g[b, k, p, dy, dx] = sum over s, y, x of q[b, s, k, y, x] x[b, s, p, y + dy - k//2,
    x + dx - k//2] (zero outside)."""
    b, s, p, h, w = x.shape
    k = q.shape[2]
    if exporting():  # onnxruntime runs the convolution by the (h, w) residual about 3x slower than this product
        windows = tap_windows(q.reshape(b * s, k, h, w), size).reshape(b * s, k * size * size, h * w)
        g = torch.matmul(windows, x.reshape(b * s, p, h * w).transpose(1, 2))  # (B*S, K*k*k, P)
        return g.view(b, s, k, size, size, p).sum(1).permute(0, 1, 4, 2, 3)
    inputs = x.permute(2, 0, 1, 3, 4).reshape(p, b * s, h, w)
    kernels = q.transpose(1, 2).reshape(b * k, s, h, w)
    out = F.conv2d(inputs, kernels, padding=size // 2, groups=b)  # (P, B*K, k, k)
    return out.view(p, b, k, size, size).permute(1, 2, 0, 3, 4)


def check_problem(x: torch.Tensor, tau: torch.Tensor, encodings: torch.Tensor, weights: torch.Tensor,
                  sample_weights: torch.Tensor) -> None:
    """``InputError`` unless the shapes fit together (see the module docstring)."""
    if x.ndim != 5 or tau.ndim != 5:
        raise InputError(f"target-model features must be (B, S, P, h, w) and the filter (B, K, P, k, k), got "
                         f"{tuple(x.shape)} and {tuple(tau.shape)}")
    b, s, p, h, w = x.shape
    if tau.shape[0] != b or tau.shape[2] != p or tau.shape[-1] != tau.shape[-2] or tau.shape[-1] % 2 == 0:
        raise InputError(f"filter {tuple(tau.shape)} does not fit features {tuple(x.shape)} (B, K, P, k, k odd)")
    expected = (b, s, tau.shape[1], h, w)
    if encodings.shape != expected or weights.shape != expected:
        raise InputError(f"label encodings and weights must be (B, S, K, h, w) = {expected}, got "
                         f"{tuple(encodings.shape)} and {tuple(weights.shape)}")
    if sample_weights.shape != (b, s):
        raise InputError(f"sample weights must be (B, S) = {(b, s)}, got {tuple(sample_weights.shape)}")


class FeatureProjection(nn.Module):
    """The target model's input (LWL): a 3x3 convolution (D -> P channels) then InstanceL2Norm, which scales
    every sample to a root mean square of ``sqrt(1 / (P k^2))`` per element, so that a filter of unit norm gives
    scores of order one whatever the backbone.

    Args:
        in_channels: D; channels: P; filter_size: k of the target-model filter (sets the norm scale).

    Shapes:
        (N, D, h, w) -> (N, P, h, w).
    """

    def __init__(self, in_channels: int, channels: int = 64, filter_size: int = 3) -> None:
        super().__init__()
        self.conv = nn.Conv2d(in_channels, channels, 3, padding=1)
        nn.init.kaiming_normal_(self.conv.weight, mode="fan_in", nonlinearity="linear")
        nn.init.zeros_(self.conv.bias)
        self.scale = math.sqrt(1.0 / (channels * filter_size * filter_size))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.scale * normalize_features(self.conv(x), "instance_l2")


class LWLResidual:
    """The residual r(tau) above and its explicit Jacobian products for one set of memory samples.

    Args:
        x: (B, S, P, h, w) features; encodings, weights: (B, S, K, h, w) E and W; sample_weights: (B, S) gamma
        (0 leaves a sample out); reg: lambda, a number or a 0-d tensor (learnt).
    """

    def __init__(self, x: torch.Tensor, encodings: torch.Tensor, weights: torch.Tensor, sample_weights: torch.Tensor,
                 reg: torch.Tensor | float) -> None:
        self.x = x
        self.encodings = encodings
        self.weight = sample_weights.clamp_min(0).sqrt()[..., None, None, None] * weights  # sqrt(gamma) W
        self.reg = reg

    def data(self, tau: torch.Tensor) -> torch.Tensor:
        """Data residual sqrt(gamma) W (tau * x - E): (B, S, K, h, w)."""
        return self.weight * (apply_filter(self.x, tau) - self.encodings)

    def gradient(self, tau: torch.Tensor, data: torch.Tensor) -> torch.Tensor:
        """g = J^T r at tau, from its data residual: (B, K, P, k, k)."""
        return filter_gradient(self.x, self.weight * data, tau.shape[-1]) + self.reg**2 * tau

    def jvp_data(self, d: torch.Tensor) -> torch.Tensor:
        """Data part of J d (the regulariser part is lambda d): (B, S, K, h, w)."""
        return self.weight * apply_filter(self.x, d)

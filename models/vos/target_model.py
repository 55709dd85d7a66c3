"""FRTM target model (thesis eq. 5.1) and its loss (eq. 5.2), with explicit Jacobian products.

The target model is ``H_W(x) = W_f * (W_p * x)``: a 1x1 projection ``W_p`` (D -> C channels) then a k x k
filter ``W_f`` (C -> 1), no bias, no nonlinearity, on stride-16 backbone features. Its loss over K memory
samples is

    L(W) = sum_k gamma_k || v_k (U(H_W(x_k)) - y_k) ||^2 + lambda_p^2 ||W_p||^2 + lambda_f^2 ||W_f||^2

with sample weights gamma, residual (pixel) weights v and U the bilinear upsampling (align_corners=False) to
the label resolution. Every operator below is a convolution, a transposed convolution, an einsum or a matrix
product, so Jacobian (J d) and transposed-Jacobian (J^T r) products need no autograd: the optimizer runs under
``torch.inference_mode`` and exports to ONNX. Everything is batched over B independent problems (objects or
videos); the per-problem filters are applied as grouped convolutions in float32 and, in float64, as k^2
shifted einsums (same values; ONNX Runtime's CPU provider has no float64 convolution, and the tracker runs its
optimizer in float64, see ``FRTMTracker``).

Shapes: features x (B, K, D, h, w); projected features z (B, K, C, h, w); scores s (B, K, h, w); labels,
residual weights (B, K, H, W); sample weights gamma (B, K); W_p (B, C, D); W_f (B, C, k, k).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError


def project(x: torch.Tensor, wp: torch.Tensor) -> torch.Tensor:
    """W_p * x: (B, K, D, h, w), (B, C, D) -> (B, K, C, h, w)."""
    return torch.einsum("bcd,bkdhw->bkchw", wp, x)


def project_grad(gz: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Gradient of <gz, W_p * x> w.r.t. W_p: (B, K, C, h, w), (B, K, D, h, w) -> (B, C, D)."""
    return torch.einsum("bkchw,bkdhw->bcd", gz, x)


def tap_windows(q: torch.Tensor, size: int) -> torch.Tensor:
    """Q[..., (dy, dx), y, x] = q[..., y + p - dy, x + p - dx] (zero outside), p = size // 2, for every tap of a
    size x size filter: (..., h, w) -> (..., size^2, h, w)."""
    h, w = q.shape[-2:]
    p = size // 2
    qp = F.pad(q, (p, p, p, p))
    return torch.stack([qp[..., 2 * p - dy : 2 * p - dy + h, 2 * p - dx : 2 * p - dx + w]
                        for dy in range(size) for dx in range(size)], -3)


def apply_filter(z: torch.Tensor, wf: torch.Tensor) -> torch.Tensor:
    """W_f * z as a grouped convolution (zero padding, same size): (B, K, C, h, w), (B, C, k, k) -> (B, K, h, w)."""
    b, k, c, h, w = z.shape
    pad = wf.shape[-1] // 2
    if z.dtype == torch.float64:  # per tap t = <W_f[:, dy, dx], z> (one GEMM), then s = sum of shifted taps
        n = wf.shape[-1]
        taps = F.pad(torch.einsum("bkchw,bcq->bkqhw", z, wf.flatten(2)), (pad, pad, pad, pad))
        return sum(taps[:, :, dy * n + dx, dy : dy + h, dx : dx + w] for dy in range(n) for dx in range(n))
    out = F.conv2d(z.transpose(0, 1).reshape(k, b * c, h, w), wf, padding=pad, groups=b)
    return out.transpose(0, 1)


def apply_filter_transpose(q: torch.Tensor, wf: torch.Tensor) -> torch.Tensor:
    """Adjoint of ``apply_filter`` in z (a transposed convolution): (B, K, h, w), (B, C, k, k) -> (B, K, C, h, w)."""
    b, k, h, w = q.shape
    c = wf.shape[1]
    pad = wf.shape[-1] // 2
    if q.dtype == torch.float64:  # g[c, y, x] = sum_(dy, dx) q[y + pad - dy, x + pad - dx] W_f[c, dy, dx]
        return torch.einsum("bkqhw,bcq->bkchw", tap_windows(q, wf.shape[-1]), wf.flatten(2))
    out = F.conv_transpose2d(q.transpose(0, 1), wf, padding=pad, groups=b)
    return out.reshape(k, b, c, h, w).transpose(0, 1)


def filter_grad(z: torch.Tensor, q: torch.Tensor, size: int) -> torch.Tensor:
    """Adjoint of ``apply_filter`` in W_f (a convolution of z by q): (B, K, C, h, w), (B, K, h, w) -> (B, C, k, k)."""
    b, k, c, h, w = z.shape
    pad = size // 2
    if z.dtype == torch.float64:  # g[c, dy, dx] = sum_(k, y, x) z[c, y, x] q[y + pad - dy, x + pad - dx]
        return torch.einsum("bkchw,bkqhw->bcq", z, tap_windows(q, size)).view(b, c, size, size)
    out = F.conv2d(z.permute(2, 0, 1, 3, 4).reshape(c, b * k, h, w), q, padding=pad, groups=b)
    return out.transpose(0, 1)


def interpolation_matrix(n_in: int, n_out: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """(n_out, n_in) matrix of 1-D linear resampling with align_corners=False (as ``F.interpolate``)."""
    src = ((torch.arange(n_out, dtype=torch.float64) + 0.5) * (n_in / n_out) - 0.5).clamp_min(0)
    i0 = src.floor().long().clamp_max(n_in - 1)
    i1 = (i0 + 1).clamp_max(n_in - 1)
    lam = src - i0
    m = torch.zeros(n_out, n_in, dtype=torch.float64)
    rows = torch.arange(n_out)
    m[rows, i0] += 1 - lam
    m[rows, i1] += lam
    return m.to(dtype=dtype, device=device)


def upsample(s: torch.Tensor, ay: torch.Tensor, ax: torch.Tensor) -> torch.Tensor:
    """Separable bilinear upsampling U(s) = A_y s A_x^T: (..., h, w) -> (..., H, W)."""
    return ay @ s @ ax.transpose(0, 1)


def upsample_transpose(r: torch.Tensor, ay: torch.Tensor, ax: torch.Tensor) -> torch.Tensor:
    """Adjoint U^T(r) = A_y^T r A_x: (..., H, W) -> (..., h, w)."""
    return ay.transpose(0, 1) @ r @ ax


def hinge_pixel_weights(labels: torch.Tensor, fg_target: float = 0.1, min_pixels: int = 10) -> torch.Tensor:
    """Residual weights v = sqrt(w) of FRTM's "hinge" rule for small objects.

    With a_f the foreground fraction (labels > 0.5; a_f := t_f below ``min_pixels`` foreground pixels) and
    t_f = max(fg_target, a_f): w = t_f / a_f on foreground, (1 - t_f) / (1 - a_f) on background, so a small
    object carries ``fg_target`` of the total weight and larger ones are left unweighted.

    Args:
        labels: (B, K, H, W) soft labels in [0, 1].

    Returns:
        (B, K, H, W) residual weights v.
    """
    fg = labels > 0.5
    n_fg = fg.flatten(2).sum(-1).to(labels.dtype)
    a_f = n_fg / fg[0, 0].numel()
    a_f = torch.where(n_fg < min_pixels, torch.full_like(a_f, fg_target), a_f)
    t_f = a_f.clamp_min(fg_target)
    w_fg = t_f / a_f.clamp_min(1e-12)
    w_bg = torch.where(a_f < 1, (1 - t_f) / (1 - a_f).clamp_min(1e-12), torch.ones_like(a_f))
    w = torch.where(fg, w_fg[..., None, None], w_bg[..., None, None])
    return w.sqrt()


class TargetModelLoss:
    """The residual r(W) of eq. 5.2 and its explicit Jacobian products, for one set of memory samples.

    Args:
        x: (B, K, D, h, w) features; already projected (D = C) when W_p is fixed (``wp`` absent in calls).
        labels: (B, K, H, W) in [0, 1].
        pixel_weights: (B, K, H, W) residual weights v, or None for ones.
        sample_weights: (B, K) gamma (zero skips a sample).
        reg: (lambda_p, lambda_f).
    """

    def __init__(
        self,
        x: torch.Tensor,
        labels: torch.Tensor,
        pixel_weights: torch.Tensor | None,
        sample_weights: torch.Tensor,
        reg: tuple[float, float],
    ) -> None:
        if x.ndim != 5 or labels.ndim != 4 or labels.shape[:2] != x.shape[:2]:
            raise InputError(
                f"target-model features must be (B, K, D, h, w) and labels (B, K, H, W) with the same B, K; "
                f"got {tuple(x.shape)} and {tuple(labels.shape)}"
            )
        if sample_weights.shape != x.shape[:2]:
            raise InputError(f"sample weights must be (B, K) = {tuple(x.shape[:2])}, got {tuple(sample_weights.shape)}")
        self.x = x
        self.labels = labels
        h, w = x.shape[-2:]
        big_h, big_w = labels.shape[-2:]
        self.ay = interpolation_matrix(h, big_h, x.dtype, x.device)
        self.ax = interpolation_matrix(w, big_w, x.dtype, x.device)
        sw = sample_weights.clamp_min(0).sqrt()[..., None, None]
        self.weight = sw if pixel_weights is None else sw * pixel_weights  # sqrt(gamma) v
        self.reg = reg

    def scores(self, wp: torch.Tensor | None, wf: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Projected features z and low-resolution scores s = W_f * z."""
        z = self.x if wp is None else project(self.x, wp)
        return z, apply_filter(z, wf)

    def residual(self, wp: torch.Tensor | None, wf: torch.Tensor) -> list[torch.Tensor]:
        """[data residual (B, K, H, W), (lambda_p W_p,) lambda_f W_f]."""
        _, s = self.scores(wp, wf)
        data = self.weight * (upsample(s, self.ay, self.ax) - self.labels)
        return [data] + ([self.reg[0] * wp] if wp is not None else []) + [self.reg[1] * wf]

    def jvp(
        self, z: torch.Tensor, wp: torch.Tensor | None, wf: torch.Tensor, d: list[torch.Tensor]
    ) -> list[torch.Tensor]:
        """J d at (wp, wf) for parameter directions d = [(dW_p,) dW_f]; z = projected features at wp."""
        if wp is None:
            ds = apply_filter(z, d[0])
        else:
            ds = apply_filter(z, d[1]) + apply_filter(project(self.x, d[0]), wf)
        data = self.weight * upsample(ds, self.ay, self.ax)
        if wp is None:
            return [data, self.reg[1] * d[0]]
        return [data, self.reg[0] * d[0], self.reg[1] * d[1]]

    def vjp(
        self, z: torch.Tensor, wp: torch.Tensor | None, wf: torch.Tensor, r: list[torch.Tensor]
    ) -> list[torch.Tensor]:
        """J^T r at (wp, wf) for residual-shaped r; returns [(g_p,) g_f]."""
        q = upsample_transpose(self.weight * r[0], self.ay, self.ax)
        g_f = filter_grad(z, q, wf.shape[-1]) + self.reg[1] * r[-1]
        if wp is None:
            return [g_f]
        g_p = project_grad(apply_filter_transpose(q, wf), self.x) + self.reg[0] * r[1]
        return [g_p, g_f]


def target_model_init(
    batch: int,
    in_channels: int,
    channels: int,
    kernel_size: int = 3,
    seed: int = 0,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str = "cpu",
) -> tuple[torch.Tensor, torch.Tensor]:
    """Seeded random starting filters: W_p ~ N(0, 1/D) of shape (B, C, D), W_f ~ N(0, 1/(k^2 C)) (B, C, k, k)."""
    if kernel_size % 2 != 1:
        raise InputError(f"target-model kernel size must be odd, got {kernel_size}")
    gen = torch.Generator().manual_seed(seed)
    wp = torch.randn(channels, in_channels, generator=gen, dtype=torch.float64) / math.sqrt(in_channels)
    wf = torch.randn(channels, kernel_size, kernel_size, generator=gen, dtype=torch.float64)
    wf = wf / (kernel_size * math.sqrt(channels))
    wp = wp.to(dtype=dtype, device=device).expand(batch, -1, -1).clone()
    wf = wf.to(dtype=dtype, device=device).expand(batch, -1, -1, -1).clone()
    return wp, wf


class TargetModel(nn.Module):
    """Applies per-problem target models: ``forward(x, wp, wf)`` -> scores.

    Args of forward:
        x: (B, K, D, h, w) features, or already projected (B, K, C, h, w) when ``wp`` is None.
        wp: (B, C, D) projection or None.
        wf: (B, C, k, k) filter.

    Returns:
        (B, K, h, w) scores at feature resolution.
    """

    def forward(self, x: torch.Tensor, wp: torch.Tensor | None, wf: torch.Tensor) -> torch.Tensor:
        z = x if wp is None else project(x, wp)
        return apply_filter(z, wf)

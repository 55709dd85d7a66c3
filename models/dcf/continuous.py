"""Continuous single-channel correlation filter in the style of C-COT (Danelljan et al. 2016; eqs. 3.6-3.8).

A sample ``x[n]`` on an odd ``N``-point grid (per axis, period ``T = N`` bins, sample ``n`` at ``t = n``)
becomes the continuous periodic function ``J{x}(t) = sum_n x[n] b(t - n)`` (eq. 3.6) with the Keys cubic
kernel ``b`` (a = -0.75), whose Fourier-series coefficients are ``X^[k] = X[k] B(k / N) / N`` (``X`` = DFT).
The filter is trained in closed form per frequency (eq. 3.8, one channel, constant regulariser ``beta^2``):
``F = sum_j alpha_j conj(X^_j) Y^ / (sum_j alpha_j |X^_j|^2 + beta^2)``, with per-sample importance weights
``alpha_j`` that decay exponentially as new samples arrive (rate ``eta``; kept as running sums, which equals
an unbounded sample memory with those weights). The score ``s^ = F . Z^`` is a Fourier series; its maximum is
found on the grid and then refined by Newton iterations on the series (sub-bin accuracy). Spectra use the
``rfft`` half layout.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.dcf._signal import check_signal, full_frequencies, half_frequencies, signal_dims, wrap_index
from models.dcf.peak import _unravel
from models.dcf.preprocess import dcf_preprocess
from models.dcf.psr import peak_to_sidelobe_ratio
from models.export_mode import spread


def cubic_spline_fourier(f: Tensor, a: float = -0.75) -> Tensor:
    """Fourier transform ``B(f) = int b(s) exp(-i 2 pi f s) ds`` of the Keys cubic kernel (real, ``B(0) =
    1``).

    Evaluated in float64 (the closed form cancels badly near 0) and returned in ``f``'s dtype.
    """
    g = f.to(torch.float64)
    small = g.abs() < 1e-3
    g_safe = torch.where(small, torch.ones_like(g), g)
    p = torch.pi * g_safe
    num = (
        6 * (1 - torch.cos(2 * p))
        + 3 * a * (1 - torch.cos(4 * p))
        - (6 + 8 * a) * p * torch.sin(2 * p)
        - 2 * a * p * torch.sin(4 * p)
    )
    value = num / (4 * torch.pi**4 * g_safe**4)
    return torch.where(small, torch.ones_like(g), value).to(f.dtype)


def _axis_shape(ndim: int, axis: int, n: int) -> list[int]:
    shape = [1] * ndim
    shape[axis] = n
    return shape


def _frequency_grid(size: tuple[int, ...], device, dtype) -> list[Tensor]:
    """Per-axis integer frequencies in the rfft layout, each shaped to broadcast over ``(*K)``."""
    ndim = len(size)
    grids = []
    for axis, n in enumerate(size):
        k = half_frequencies(n, device, dtype) if axis == ndim - 1 else full_frequencies(n, device, dtype)
        grids.append(k.reshape(_axis_shape(ndim, axis, k.numel())))
    return grids


def _check_odd(size: tuple[int, ...]) -> None:
    if any(n % 2 == 0 for n in size):
        raise InputError(f"the continuous filter needs odd signal sizes, got {size}")


def ccot_sample(x: Tensor, ndim: int = 2) -> Tensor:
    """Fourier-series coefficients ``X^ = X . B(k / N) / N`` of the interpolated sample ``J{x}`` (eq. 3.6).

    Args:
        x: ``(..., *S)`` preprocessed real samples, odd sizes, target at index 0.
    Returns:
        ``(..., *K)`` complex half spectrum.
    """
    check_signal(x, ndim, "x")
    size = tuple(x.shape[-ndim:])
    _check_odd(size)
    X = torch.fft.rfftn(x, dim=signal_dims(ndim))
    scale = torch.ones((), device=x.device, dtype=x.dtype)
    for k, n in zip(_frequency_grid(size, x.device, x.dtype), size, strict=True):
        scale = scale * cubic_spline_fourier(k / n) / n
    return X * scale


def continuous_label(size: tuple[int, ...], sigma: float, *, device=None, dtype=torch.float32) -> Tensor:
    """Fourier-series coefficients of a periodic Gaussian of std ``sigma`` bins centred at 0, period
    ``N`` per axis.

    ``y^[k] = prod_axes sqrt(2 pi) sigma / N exp(-2 (pi sigma k / N)^2)``, rfft layout ``(*K)``, real.
    """
    if sigma <= 0:
        raise InputError(f"sigma must be positive, got {sigma}")
    label = torch.ones((), device=device, dtype=dtype)
    for k, n in zip(_frequency_grid(size, device, dtype), size, strict=True):
        label = label * (math.sqrt(2 * math.pi) * sigma / n) * torch.exp(-2 * (math.pi * sigma * k / n) ** 2)
    return label


def exponential_forgetting_weights(n: int, eta: float, *, device=None, dtype=torch.float64) -> Tensor:
    """Importance weights of ``n`` samples after exponential forgetting at rate ``eta``, oldest first.

    The first sample starts with weight 1; each new sample gets ``eta`` while older weights are scaled by
    ``1 - eta``, so the weights sum to 1: ``[(1-eta)^(n-1), eta (1-eta)^(n-2), ..., eta]``.
    """
    if n < 1 or not 0 < eta <= 1:
        raise InputError(f"need n >= 1 and 0 < eta <= 1, got n={n}, eta={eta}")
    age = torch.arange(n - 1, -1, -1, device=device, dtype=dtype)
    weights = eta * (1 - eta) ** age
    weights[0] = (1 - eta) ** (n - 1)
    return weights


def ccot_train(xhat: Tensor, yhat: Tensor, weights: Tensor, ndim: int = 2) -> tuple[Tensor, Tensor]:
    """Weighted closed-form numerator and denominator of eq. 3.8 from a sample memory.

    Args:
        xhat: ``(..., M, *K)`` sample coefficients (:func:`ccot_sample`); yhat: label
        (:func:`continuous_label`).
        weights: ``(..., M)`` importance weights ``alpha_j``.
    Returns:
        A ``(..., *K)`` complex ``sum_j alpha_j conj(X^_j) y^``; B ``(..., *K)`` real ``sum_j alpha_j
        |X^_j|^2``.
    """
    if weights.shape[-1] != xhat.shape[-(ndim + 1)]:
        raise InputError(
            f"weights {tuple(weights.shape)} do not match the sample axis of {tuple(xhat.shape)}"
        )
    alpha = weights.to(xhat.real.dtype).reshape(*weights.shape, *([1] * ndim))
    sample = -(ndim + 1)
    A = (alpha * xhat.conj() * yhat).sum(dim=sample)
    B = (alpha * (xhat.real.square() + xhat.imag.square())).sum(dim=sample)
    return A, B


def ccot_update(
    A: Tensor, B: Tensor, xhat: Tensor, yhat: Tensor, eta: float | Tensor
) -> tuple[Tensor, Tensor]:
    """Add one sample ``xhat`` ``(..., *K)`` with weight ``eta``, decaying the memory by ``1 - eta``."""
    A_new = xhat.conj() * yhat
    B_new = xhat.real.square() + xhat.imag.square()
    return eta * A_new + (1 - eta) * A, eta * B_new + (1 - eta) * B


def ccot_filter(A: Tensor, B: Tensor, ndim: int = 2, beta2: float = 0.0, beta2_rel: float = 0.0) -> Tensor:
    """Filter ``F = A / (B + beta^2)`` with ``beta^2 = beta2 + beta2_rel * mean(B)`` per filter (eq. 3.8)."""
    if beta2 < 0 or beta2_rel < 0 or (beta2 == 0 and beta2_rel == 0 and bool((B <= 0).any())):
        raise InputError("regularisation must be non-negative and positive where B has zeros")
    return A / (B + beta2 + beta2_rel * B.mean(dim=signal_dims(ndim), keepdim=True))


def shift_fourier(xhat: Tensor, shift: Tensor, size: tuple[int, ...]) -> Tensor:
    """Spectrum of the circularly shifted signal ``x'(t) = x(t + shift)``.

    Args:
        xhat: ``(..., *K)`` half spectrum of signals of size ``size``; shift: ``(..., ndim)`` bins, last
        axis first.
    """
    ndim = len(size)
    phase = torch.zeros((), device=shift.device, dtype=shift.dtype)
    view = (*shift.shape[:-1], *([1] * ndim))
    for axis, (k, n) in enumerate(zip(_frequency_grid(size, shift.device, shift.dtype), size, strict=True)):
        phase = phase + (2 * math.pi / n) * k * shift[..., ndim - 1 - axis].reshape(view)
    return xhat * torch.polar(torch.ones_like(phase), phase)


def _series(
    sr: Tensor, si: Tensor, theta: Tensor, ks: list[Tensor], w: Tensor, order: int, srsi: Tensor | None = None
):
    """Value, gradient and Hessian (if ``order`` 2) of ``sum_k w Re(s^[k] exp(i k . theta))``.

    ``theta`` is ``(..., ndim)`` ordered like the signal axes (first axis first); ``w`` weighs the halved last
    axis (1 at frequency 0, 2 elsewhere); ``srsi`` is ``cat([sr, si], -1)`` when already at hand (2D). 2D
    series are evaluated separably: one batched real matrix product sums the last axis for the three powers
    of ``kx``, then short dot products sum the first axis.
    """
    if len(ks) == 1:
        angle = ks[0] * theta
        c, s = torch.cos(angle), torch.sin(angle)
        pr, pi = (sr * c - si * s) * w, (sr * s + si * c) * w
        k = ks[0]
        value = pr.sum(-1)
        if order == 0:
            return value, None, None
        return value, -(k * pi).sum(-1, keepdim=True), [[-(k * k * pr).sum(-1)]]
    ky, kx, w = ks[0].squeeze(-1), ks[1].squeeze(0), w.reshape(-1)
    ax = kx * theta[..., 1:2]
    cx, sx = torch.cos(ax), torch.sin(ax)
    powers = torch.stack([w, w * kx, w * kx * kx], -1) if order else w.unsqueeze(-1)
    m = powers.shape[-1]
    er, ei = spread(cx.unsqueeze(-1), m) * powers, spread(sx.unsqueeze(-1), m) * powers
    basis = torch.cat([torch.cat([er, ei], -1), torch.cat([-ei, er], -1)], -2)
    u = (torch.cat([sr, si], -1) if srsi is None else srsi) @ basis
    ur, ui = u[..., :m], u[..., m:]
    ay = ky * theta[..., 0:1]
    cy, sy = spread(torch.cos(ay).unsqueeze(-1), m), spread(torch.sin(ay).unsqueeze(-1), m)
    re = cy * ur - sy * ui  # Re(exp(i ky theta_y) u)
    im = cy * ui + sy * ur
    value = re[..., 0].sum(-1)
    if order == 0:
        return value, None, None
    kyc = ky.unsqueeze(-1)
    grad = torch.stack([-(kyc * im[..., :1]).sum((-2, -1)), -im[..., 1].sum(-1)], -1)
    hyy = -(kyc * kyc * re[..., :1]).sum((-2, -1))
    hyx = -(kyc * re[..., 1:2]).sum((-2, -1))
    hxx = -re[..., 2].sum(-1)
    return value, grad, [[hyy, hyx], [hyx, hxx]]


def fourier_series_peak(
    shat: Tensor, size: tuple[int, ...], iterations: int = 5, grid: Tensor | None = None
) -> tuple[Tensor, Tensor]:
    """Sub-bin maximum of the periodic score ``s(t) = sum_k s^[k] exp(i 2 pi k . t / N)``: see
    :func:`fourier_series_peak_parts`, here with a complex half spectrum ``shat`` ``(..., *K)``."""
    if grid is None:
        grid = torch.fft.irfftn(shat, s=size, dim=signal_dims(len(size)))
    return fourier_series_peak_parts(shat.real, shat.imag, size, iterations, grid)


def fourier_series_peak_parts(
    sr: Tensor, si: Tensor, size: tuple[int, ...], iterations: int, grid: Tensor, srsi: Tensor | None = None
) -> tuple[Tensor, Tensor]:
    """Sub-bin maximum of the periodic score ``s(t) = sum_k s^[k] exp(i 2 pi k . t / N)``.

    The grid maximum (inverse DFT) starts :func:`fourier_series_refine`.

    Args:
        sr, si: ``(..., *K)`` real and imaginary parts of the score's half spectrum; size: odd signal size
        ``S``. The spectrum may be band-limited (odd ``2M + 1`` rows ``0 .. M, -M .. -1`` and ``M + 1``
        columns, as :class:`~models.dcf.dft.RealDft2` with ``band=M``). grid: the sampled score ``(..., *S)``.
        srsi: ``cat([sr, si], -1)`` if already at hand (2D).
    Returns:
        shift ``(..., ndim)`` in bins (last axis first, in ``[-N/2, N/2)``); score ``(...)`` at the peak.
    """
    ndim = len(size)
    v_grid, arg = grid.flatten(-ndim).max(dim=-1)  # the series sampled on the grid
    index = torch.stack(_unravel(arg, size), dim=-1)
    return fourier_series_refine(sr, si, size, iterations, index, v_grid, srsi)


def fourier_series_refine(
    sr: Tensor,
    si: Tensor,
    size: tuple[int, ...],
    iterations: int,
    index: Tensor,
    value: Tensor,
    srsi: Tensor | None = None,
) -> tuple[Tensor, Tensor]:
    """Newton refinement of a grid maximum of the periodic score ``s(t) = sum_k s^[k] exp(i 2 pi k . t / N)``.

    ``iterations`` Newton steps on the Fourier series (2x2 closed-form solve, steps only where the Hessian is
    negative definite, at most one bin each) start at the grid maximum; the grid peak is kept where the refined
    score is lower or the refinement moved more than one bin.

    Args:
        sr, si, size, srsi: as :func:`fourier_series_peak_parts`. index: ``(..., ndim)`` integer grid position
        of the maximum (first axis first, in ``[0, N)``); value: ``(...)`` the score there.
    Returns:
        shift ``(..., ndim)`` in bins (last axis first, in ``[-N/2, N/2)``); score ``(...)`` at the peak.
    """
    ndim = len(size)
    _check_odd(size)
    real_dtype = sr.dtype
    t0 = torch.stack([wrap_index(index[..., a], n).to(real_dtype) for a, n in enumerate(size)], dim=-1)
    ks = _frequency_grid((*sr.shape[len(sr.shape) - ndim : -1], 2 * sr.shape[-1] - 1), sr.device, real_dtype)
    w = torch.where(ks[-1] == 0, torch.ones_like(ks[-1]), 2 * torch.ones_like(ks[-1]))
    if ndim == 2 and srsi is None:
        srsi = torch.cat([sr, si], -1)
    two_pi_over_n = torch.tensor([2 * math.pi / n for n in size], device=sr.device, dtype=real_dtype)
    theta0 = t0 * two_pi_over_n
    theta = theta0
    for _ in range(iterations):
        _, g, h = _series(sr, si, theta, ks, w, order=2, srsi=srsi)
        if ndim == 1:
            ok = h[0][0] < 0
            step = -g / torch.where(ok, h[0][0], -torch.ones_like(h[0][0])).unsqueeze(-1)
        else:
            hyy, hyx, hxx = h[0][0], h[0][1], h[1][1]
            det = hyy * hxx - hyx * hyx
            ok = (hyy < 0) & (det > 0)
            det = torch.where(ok, det, torch.ones_like(det))
            step_y = -(hxx * g[..., 0] - hyx * g[..., 1]) / det
            step_x = -(-hyx * g[..., 0] + hyy * g[..., 1]) / det
            step = torch.stack([step_y, step_x], dim=-1)
        step = torch.where(ok.unsqueeze(-1), step, torch.zeros_like(step))
        theta = theta + torch.maximum(torch.minimum(step, two_pi_over_n), -two_pi_over_n)
    v_ref, _, _ = _series(sr, si, theta, ks, w, order=0, srsi=srsi)
    t = theta / two_pi_over_n
    keep = (v_ref >= value) & ((t - t0).abs() <= 1).all(dim=-1)
    t = torch.where(keep.unsqueeze(-1), t, t0)
    return t.flip(-1), torch.where(keep, v_ref, value)


class CcotFilter(nn.Module):
    """A batch of continuous single-channel C-COT filters with exponentially forgotten samples.

    Args:
        ndim: 1 or 2. sigma: label std in bins. eta: weight of each new sample (1 = retrain from scratch).
        beta2, beta2_rel: absolute and relative (to the mean of ``B``) regularisation ``beta^2``.
        log, normalize, window: preprocessing flags. newton_iterations: sub-bin refinement steps.
        psr_exclude: side of the window around the peak left out of the PSR sidelobe.
    """

    def __init__(
        self,
        ndim: int = 2,
        sigma: float = 1.0,
        eta: float = 0.125,
        beta2: float = 0.0,
        beta2_rel: float = 1e-2,
        log: bool = False,
        normalize: bool = True,
        window: bool = True,
        newton_iterations: int = 5,
        psr_exclude: int = 11,
    ) -> None:
        super().__init__()
        self.ndim, self.sigma, self.eta, self.beta2, self.beta2_rel = ndim, sigma, eta, beta2, beta2_rel
        self.log, self.normalize, self.window = log, normalize, window
        self.newton_iterations, self.psr_exclude = newton_iterations, psr_exclude

    def sample(self, x: Tensor) -> Tensor:
        """Preprocess raw signals ``(..., *S)`` and return their coefficients ``X^``."""
        x = dcf_preprocess(x, self.ndim, log=self.log, normalize=self.normalize, window=self.window)
        return ccot_sample(x, self.ndim)

    def label(self, x: Tensor) -> Tensor:
        return continuous_label(tuple(x.shape[-self.ndim :]), self.sigma, device=x.device, dtype=x.dtype)

    def fit(self, x: Tensor, weights: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Train on raw samples ``(..., M, *S)`` with weights ``(..., M)`` (default: forgetting at
        ``eta``)."""
        if weights is None:
            m = x.shape[-(self.ndim + 1)]
            weights = exponential_forgetting_weights(m, self.eta, device=x.device, dtype=x.dtype)
        return ccot_train(self.sample(x), self.label(x), weights, self.ndim)

    def update(self, state: tuple[Tensor, Tensor], x: Tensor) -> tuple[Tensor, Tensor]:
        """Add one raw sample per filter ``(..., *S)`` with weight ``eta``."""
        return ccot_update(*state, self.sample(x), self.label(x), self.eta)

    def forward(self, state: tuple[Tensor, Tensor], z: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """Apply to raw signals ``z`` ``(..., *S)``.

        Returns:
            grid score ``(..., *S)``, sub-bin shift ``(..., ndim)`` (last axis first) and PSR ``(...)``.
        """
        size = tuple(z.shape[-self.ndim :])
        shat = ccot_filter(*state, self.ndim, self.beta2, self.beta2_rel) * self.sample(z)
        score = torch.fft.irfftn(shat, s=size, dim=signal_dims(self.ndim))
        shift, _ = fourier_series_peak(shat, size, self.newton_iterations, grid=score)
        return score, shift, peak_to_sidelobe_ratio(score, self.ndim, self.psr_exclude)

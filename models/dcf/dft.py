"""Small 2D DFTs as real matrix products, for batches of odd ``N x N`` patches.

For the patch sizes of point tracking (N <= ~35) two real matrix products per transform are faster than an FFT
on a CPU, keep every tensor real (``torch.compile`` and ONNX friendly) and absorb per-axis factors for free: the
separable cosine window of the samples, the separable Fourier-domain scale of the continuous filter (cubic
spline interpolation, :func:`~models.dcf.continuous.ccot_sample`) and the centring of the patch.

Patches come in natural order (pixel ``i`` at offset ``i - N // 2`` from the centre) and with the batch in the
middle, ``(N, B, N)`` (rows, patches, columns): both transforms are then one large matrix product per axis (the
last axis multiplied from the right, the first from the left) with no batched small products and no copies.
Spectra use the same layout, ``(N_f, B, K)``, with the ``rfft2`` half layout per patch: FFT-ordered rows
(``ky = 0, 1, .., -1``) and ``kx = 0 .. N // 2``, as real and imaginary parts; they equal ``rfft2`` of the
FFT-ordered (centre at index 0) windowed patch times the axis scales. The inverse returns the real signal in FFT
order (zero shift at index 0), ``(N, B, N)``.

A band limit ``M < N // 2`` keeps only the frequencies ``|ky|, |kx| <= M`` (rows ``0 .. M, -M .. -1``, columns
``0 .. M``): the spectrum of a ``2M + 1``-point signal in the same layout, while the inverse still samples the
band-limited signal on the full ``N x N`` grid. C-COT's filters are band-limited in the same way (fewer Fourier
coefficients than sample pixels); the cost of both transforms and of everything done per frequency drops with
``(2M + 1)^2 / N^2``.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.dcf._signal import full_frequencies, half_frequencies


def band_frequencies(n: int, band: int, half: bool, device=None, dtype=torch.float64) -> Tensor:
    """Integer frequencies of a DFT axis of length ``n`` limited to ``|k| <= band``, in FFT order (``half``: the
    non-negative ones only)."""
    return (half_frequencies if half else full_frequencies)(2 * band + 1, device, dtype)


def band_index(n: int, band: int) -> Tensor:
    """Positions of :func:`band_frequencies` in an FFT-ordered axis of length ``n`` (``0 .. M, n - M .. n - 1``)."""
    return torch.remainder(band_frequencies(n, band, False, dtype=torch.int64), n)


def _forward_factors(
    n: int, band: int, window: Tensor | None, scale: Tensor | None, half: bool, dtype
) -> tuple[Tensor, Tensor]:
    """``cos`` and ``-sin`` factors ``(n_freq, n)`` of ``sum_o w[o] x[o] exp(-i 2 pi k o / n) * scale[k]``."""
    k = band_frequencies(n, band, half)
    offset = torch.arange(n, dtype=torch.float64) - n // 2
    angle = 2 * math.pi * k[:, None] * offset[None, :] / n
    w = torch.ones(n, dtype=torch.float64) if window is None else window.to(torch.float64)
    s = torch.ones(k.numel(), dtype=torch.float64) if scale is None else scale.to(torch.float64)[band_index(n, band)]
    s = s[: k.numel()]
    factor = s[:, None] * w[None, :]
    return (factor * torch.cos(angle)).to(dtype), (-factor * torch.sin(angle)).to(dtype)


class RealDft2(nn.Module):
    """Half-spectrum 2D DFT of real odd ``N x N`` patches, and its inverse, as real matrix products.

    Args:
        n: odd patch side. window: ``(N,)`` per-axis sample window in natural order (None: none).
        scale: ``(N,)`` per-axis factor of the full FFT-ordered frequencies ``0, 1, .., -1`` applied to the
        spectrum (the half axis uses the non-negative ones; None: none). dtype: of the matrices.
        band: highest kept frequency ``M`` per axis (None: all, ``N // 2``). The spectra are then
        ``(2M + 1) x (M + 1)``; below, ``N_f = 2M + 1`` and ``K = M + 1``.
    """

    def __init__(
        self,
        n: int,
        window: Tensor | None = None,
        scale: Tensor | None = None,
        dtype=torch.float32,
        band: int | None = None,
    ) -> None:
        super().__init__()
        if n < 1 or n % 2 == 0:
            raise InputError(f"RealDft2 needs an odd size, got {n}")
        band = n // 2 if band is None else band
        if not 0 <= band <= n // 2:
            raise InputError(f"band must lie in [0, {n // 2}] for size {n}, got {band}")
        self.n, self.band, self.rows_f, self.k = n, band, 2 * band + 1, band + 1
        cy, sy = _forward_factors(n, band, window, scale, False, dtype)
        cx, sx = _forward_factors(n, band, window, scale, True, dtype)
        self.register_buffer("rows", torch.cat([cy, sy]), persistent=False)  # (2N_f, N): Re, Im rows of the y DFT
        self.register_buffer("cols", torch.cat([cx, sx]).T.contiguous(), persistent=False)  # (N, 2K)
        # Inverse: the complex y transform of [Sr | Si] first (cos and sin rows), then the real part of the
        # x transform (weights 1 at kx = 0 and 2 elsewhere, 1 / N^2), both onto FFT-ordered offsets.
        kx = band_frequencies(n, band, True)
        ky = band_frequencies(n, band, False)
        pos = full_frequencies(n, None, torch.float64)
        ay = 2 * math.pi * pos[:, None] * ky[None, :] / n
        self.register_buffer("inv_rows", torch.cat([torch.cos(ay), torch.sin(ay)]).to(dtype),
                             persistent=False)  # (2N, N_f): [Sr | Si] -> [cos Sr | cos Si] and [sin Sr | sin Si]
        weight = (2 - (kx == 0).to(torch.float64)) / n**2
        ax = 2 * math.pi * kx[:, None] * pos[None, :] / n
        c, s = weight[:, None] * torch.cos(ax), weight[:, None] * torch.sin(ax)
        # Re sum_kx (Vr + i Vi) e^{i kx x} with Vr = cos Sr - sin Si, Vi = sin Sr + cos Si
        self.register_buffer("inv_cols_cos", torch.cat([c, -s]).to(dtype), persistent=False)  # (2K, N)
        self.register_buffer("inv_cols_sin", torch.cat([-s, -c]).to(dtype), persistent=False)  # (2K, N)

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Spectrum of patches ``(N, B, N)``: real and imaginary parts, each ``(N_f, B, K)``."""
        if x.dim() != 3 or x.shape[0] != self.n or x.shape[2] != self.n:
            raise InputError(f"expected ({self.n}, B, {self.n}) patches, got shape {tuple(x.shape)}")
        n, b, r, k = self.n, x.shape[1], self.rows_f, self.k
        u = torch.mm(x.reshape(n * b, n), self.cols).view(n, b * 2 * k)  # x transformed: (N, B, 2K)
        v = torch.mm(self.rows, u).view(2 * r, b, 2 * k)  # then y: Re rows then Im rows
        return v[:r, :, :k] - v[r:, :, k:], v[:r, :, k:] + v[r:, :, :k]

    def inverse(self, spectrum: Tensor) -> Tensor:
        """Real signals ``(N, B, N)`` in FFT order from half spectra given as ``[re | im]`` ``(N_f, B, 2K)``."""
        if spectrum.dim() != 3 or spectrum.shape[0] != self.rows_f or spectrum.shape[2] != 2 * self.k:
            raise InputError(f"expected ({self.rows_f}, B, {2 * self.k}) spectra, got shape {tuple(spectrum.shape)}")
        n, b, k2 = self.n, spectrum.shape[1], 2 * self.k
        u = torch.mm(self.inv_rows, spectrum.reshape(self.rows_f, b * k2))  # (2N, B * 2K): y transformed
        out = torch.mm(u[:n].view(n * b, k2), self.inv_cols_cos)
        return out.addmm_(u[n:].view(n * b, k2), self.inv_cols_sin).view(n, b, n)

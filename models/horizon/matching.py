"""Matching an observed horizon profile against a chunk of the filter bank (thesis ch. 4.4).

Each location's score is the peak-to-sidelobe ratio (PSR) of its filter response ``r = IDFT(H* . Z)``, with the
peak searched only within +-``band_deg`` of the compass heading and the sidelobe = the whole 360-degree response
minus ``exclude`` bins around that peak. The heading estimate is the peak's lag (refined by a parabola).

Nothing here computes the full response. With ``w_k`` = 1 for k = 0 and N/2 and 2 otherwise:

- band and window lags ``l``: ``r[l] = sum_k w_k Re(H*_k Z_k e^{2 pi i k l / N}) / N``, one GEMM of the chunk
  ``(L, 2K)`` with a ``(2K, B T)`` matrix built from the query (T lags per query);
- sum of the response: ``sum_n r[n] = Re(H*_0 Z_0)``;
- sum of squares (Parseval): ``sum_n r[n]^2 = sum_k w_k |H*_k|^2 |Z_k|^2 / N``, a GEMM of the squared chunk.

So a chunk costs two matrix products, memory bound on the stored spectra, and exports to ONNX as such.
Lag/heading convention: a query ``z[u] = x[u + s]`` (the profile seen with heading ``s`` bins, column 0 forward)
makes the filter trained on ``x`` (label at 0) peak at lag ``-s``; heading = ``-lag`` (mod N).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.horizon.filter_bank import profile_normalize


def band_bins(band_deg: float, bins: int) -> int:
    """Half-width of the heading band in bins (at least 1)."""
    return max(1, int(math.ceil(band_deg * bins / 360.0)))


def check_query(profile: Tensor, heading_deg: Tensor, bins: int) -> None:
    """Raise ``InputError`` for profiles of another length than the bank's or headings outside [0, 360)."""
    if not isinstance(profile, Tensor) or profile.dim() != 2 or not profile.is_floating_point():
        raise InputError(f"profiles must be a floating (B, {bins}) tensor, got "
                         f"{tuple(profile.shape) if isinstance(profile, Tensor) else type(profile).__name__}")
    if profile.shape[-1] != bins:
        raise InputError(f"profile length {profile.shape[-1]} does not match the bank's {bins} azimuth bins")
    if not torch.isfinite(profile).all():
        raise InputError("profiles contain NaN or infinite values")
    if heading_deg.shape != profile.shape[:1]:
        raise InputError(f"need one compass heading per profile: {tuple(heading_deg.shape)} vs {profile.shape[0]}")
    bad = ~torch.isfinite(heading_deg) | (heading_deg < 0) | (heading_deg >= 360)
    if bad.any():
        raise InputError(f"compass heading {heading_deg[bad][0].item():g} deg is outside [0, 360)")


def query_matrices(
    profile: Tensor,
    heading_deg: Tensor,
    half_spectrum: int,
    band: int,
    exclude: int,
    threshold_deg: float,
    drop_harmonics: int = 0,
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """The query side of the matching products.

    Args:
        profile: ``(B, N)`` observed profiles (tan elevation), column u at azimuth heading + 2 pi u / N.
        heading_deg: ``(B,)`` compass headings, degrees.
        half_spectrum: stored frequencies K of the bank.
        band: half-width of the heading band, bins; exclude: odd PSR window, bins.
        drop_harmonics: zero the query's harmonics 1 .. this (1 = the sinusoid a residual camera tilt adds).
    Returns:
        lag_matrix ``(2K, B T)``, energy_matrix ``(2K, B)``, dc ``(2, B)`` (Re, -Im of Z_0) and lags ``(B, T)``
        (T = 2 (band + exclude // 2) + 1, centred on the lag of the compass heading).
    """
    bins = profile.shape[-1]
    dtype = profile.dtype
    spectrum = torch.view_as_real(torch.fft.rfft(profile_normalize(profile, threshold_deg), dim=-1))
    spectrum = spectrum[:, :half_spectrum]  # (B, K, 2)
    k = torch.arange(half_spectrum, dtype=dtype, device=profile.device)
    if drop_harmonics > 0:
        keep = ((k < 1) | (k > drop_harmonics)).to(dtype)
        spectrum = spectrum * keep[None, :, None]
    weight = torch.where((k == 0) | (2 * k == bins), torch.ones_like(k), 2 * torch.ones_like(k)) / bins  # (K,)
    reach = band + exclude // 2
    centre = torch.round(-heading_deg.to(dtype) * bins / 360.0)
    lags = centre[:, None] + torch.arange(-reach, reach + 1, dtype=dtype, device=profile.device)  # (B, T)
    angle = (2 * math.pi / bins) * torch.remainder(k[None, :, None] * lags[:, None, :], bins)  # (B, K, T)
    cos, sin = torch.cos(angle), torch.sin(angle)
    zr, zi = spectrum[..., 0:1], spectrum[..., 1:2]  # (B, K, 1)
    re = (zr * cos - zi * sin) * weight[None, :, None]  # Re(Z e^{i a}) w
    im = (zr * sin + zi * cos) * weight[None, :, None]  # Im(Z e^{i a}) w
    # Re(H Z e) = Hr Re(Ze) - Hi Im(Ze); the chunk's columns alternate (re, im) per frequency.
    lag_matrix = torch.stack([re, -im], 2).permute(1, 2, 0, 3).reshape(2 * half_spectrum, -1)
    power = (spectrum.square().sum(-1) * weight).T  # (K, B)
    energy_matrix = torch.stack([power, power], 1).reshape(2 * half_spectrum, -1)
    dc = torch.stack([spectrum[:, 0, 0], -spectrum[:, 0, 1]])
    return lag_matrix, energy_matrix, dc, lags


def band_psr(
    filters: Tensor,
    profile: Tensor,
    heading_deg: Tensor,
    band_deg: float = 4.0,
    exclude: int = 11,
    threshold_deg: float = 1.0,
    drop_harmonics: int = 0,
) -> tuple[Tensor, Tensor]:
    """Score bank locations against observed profiles.

    Args:
        filters: ``(L, 2K)`` filter spectra ``H*`` of L locations, (re, im) per frequency (a bank chunk).
        profile: ``(B, N)`` observed profiles, tan elevation, column 0 at the camera heading.
        heading_deg: ``(B,)`` compass headings in [0, 360) degrees.
        band_deg: search band around the compass heading, degrees.
        exclude: odd number of bins around the peak left out of the sidelobe.
        threshold_deg: profile normalisation threshold (must match the bank).
        drop_harmonics: ignore the query's harmonics 1 .. this: a pitch/roll error of the levelling adds a
            sinusoid (harmonic 1) to a profile measured in an image, which then carries no position information.
    Returns:
        psr ``(B, L)`` and heading ``(B, L)`` in degrees [0, 360) of the band peak (sub-bin).
    """
    bins = profile.shape[-1]
    if filters.dim() != 2 or filters.shape[-1] % 2:
        raise InputError(f"filters must be (L, 2K), got shape {tuple(filters.shape)}")
    half = filters.shape[-1] // 2
    band = band_bins(band_deg, bins)
    if exclude < 1 or exclude % 2 == 0 or 2 * (band + exclude // 2) + 1 > bins - exclude - 2:
        raise InputError(f"band {band_deg} deg and exclude {exclude} bins do not fit in {bins} bins")
    lag_matrix, energy_matrix, dc, lags = query_matrices(profile, heading_deg, half, band, exclude, threshold_deg,
                                                         drop_harmonics)
    filters = filters.to(profile.dtype)
    batch, taps = lags.shape
    response = (filters @ lag_matrix).reshape(-1, batch, taps).transpose(0, 1)  # (B, L, T)
    total = (filters[:, :2] @ dc).T  # (B, L)
    energy = (filters.square() @ energy_matrix).T  # (B, L)
    reach = exclude // 2
    in_band = response[..., reach : taps - reach]
    peak, arg = in_band.max(-1)  # arg in [0, 2 band]
    window_index = arg[..., None] + torch.arange(exclude, device=arg.device)  # around peak, in response indices
    window = response.gather(-1, window_index)
    count = bins - exclude
    mean = (total - window.sum(-1)) / count
    var = ((energy - window.square().sum(-1)) / count - mean.square()).clamp_min(0)
    psr = (peak - mean) / (var.sqrt() + 1e-12)
    left = response.gather(-1, (arg + reach - 1)[..., None])[..., 0]
    right = response.gather(-1, (arg + reach + 1)[..., None])[..., 0]
    curvature = left - 2 * peak + right
    concave = curvature < 0
    delta = torch.where(concave, 0.5 * (left - right) / torch.where(concave, curvature, -torch.ones_like(curvature)),
                        torch.zeros_like(curvature)).clamp(-0.5, 0.5)
    lag = lags[:, None, reach] + arg.to(profile.dtype) + delta
    heading = torch.remainder(-lag * (360.0 / bins), 360.0)
    return psr, heading


class BandPsr(nn.Module):
    """Module form of :func:`band_psr` (the exported matching step: profile in, scores over a chunk out).

    Shapes:
        filters ``(L, 2K)``, profile ``(B, N)``, heading_deg ``(B,)`` -> psr ``(B, L)``, heading ``(B, L)`` deg.
    """

    def __init__(self, band_deg: float = 4.0, exclude: int = 11, threshold_deg: float = 1.0,
                 drop_harmonics: int = 0) -> None:
        super().__init__()
        self.band_deg, self.exclude, self.threshold_deg = band_deg, exclude, threshold_deg
        self.drop_harmonics = drop_harmonics

    def forward(self, filters: Tensor, profile: Tensor, heading_deg: Tensor) -> tuple[Tensor, Tensor]:
        return band_psr(filters, profile, heading_deg, self.band_deg, self.exclude, self.threshold_deg,
                        self.drop_harmonics)

"""Band PSR matching against a brute-force full-response loop, with harmonic 1 dropped, in float32."""

import math

import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths
from models.horizon.filter_bank import profile_normalize
from models.horizon.matching import band_psr


def _brute_psr(filters, profile, heading_deg, band_deg, exclude, threshold, drop=0):
    """Full irfft response per location (numpy fp64 loop), peak in the band, sidelobe by an explicit mask."""
    bins = profile.shape[-1]
    z = np.fft.rfft(profile_normalize(torch.from_numpy(profile), threshold).numpy())
    z[:, 1 : drop + 1] = 0
    band = max(1, math.ceil(band_deg * bins / 360))
    psr = np.zeros((len(profile), len(filters)))
    heading = np.zeros_like(psr)
    for b in range(len(profile)):
        centre = round(-heading_deg[b] * bins / 360)
        for i, f in enumerate(filters):
            h = np.zeros(bins // 2 + 1, complex)
            h[: len(f) // 2] = f[0::2] + 1j * f[1::2]
            r = np.fft.irfft(h * z[b], n=bins)
            lags = np.arange(centre - band, centre + band + 1)
            p = lags[np.argmax(r[lags % bins])]
            mask = np.ones(bins, bool)
            mask[np.arange(p - exclude // 2, p + exclude // 2 + 1) % bins] = False
            side = r[mask]
            psr[b, i] = (r[p % bins] - side.mean()) / side.std()
            lo, mid, hi = r[(p - 1) % bins], r[p % bins], r[(p + 1) % bins]
            delta = 0.5 * (lo - hi) / (lo - 2 * mid + hi) if lo - 2 * mid + hi < 0 else 0.0
            heading[b, i] = (-(p + np.clip(delta, -0.5, 0.5)) * 360 / bins) % 360
    return psr, heading


@pytest.mark.parametrize(("bins", "frequencies", "band_deg", "drop"), [(128, 65, 4.0, 0), (200, 40, 10.0, 1)])
def test_band_psr_matches_full_response_loop(bins, frequencies, band_deg, drop):
    gen = torch.Generator().manual_seed(bins)
    filters = torch.randn(37, 2 * frequencies, generator=gen, dtype=torch.float64)
    filters[:, 1] = 0  # DC and Nyquist of a real signal's spectrum are real
    if frequencies == bins // 2 + 1:
        filters[:, -1] = 0
    profile = torch.cumsum(torch.randn(3, bins, generator=gen, dtype=torch.float64), -1) * 0.01
    heading = torch.tensor([0.0, 123.4, 359.9], dtype=torch.float64)
    psr, est = band_psr(filters, profile, heading, band_deg, 11, 1.0, drop)
    ref_psr, ref_heading = _brute_psr(filters.numpy(), profile.numpy(), heading.numpy(), band_deg, 11, 1.0, drop)
    np.testing.assert_allclose(psr.numpy(), ref_psr, rtol=1e-9, atol=1e-9)
    diff = (est.numpy() - ref_heading + 180) % 360 - 180
    np.testing.assert_allclose(diff, 0, atol=1e-9)


def test_dropping_harmonic_one_ignores_a_tilt_sinusoid():
    gen = torch.Generator().manual_seed(3)
    filters = torch.randn(20, 2 * 129, generator=gen, dtype=torch.float64)
    filters[:, 1] = filters[:, -1] = 0
    psi = column_azimuths(256, torch.float64)
    base = 3.0 * torch.rand(1, 256, generator=gen, dtype=torch.float64)  # degrees, above the threshold
    tilted = base + 0.4 * torch.cos(psi - 0.7)  # a levelling error adds harmonic 1 (in elevation)
    to_tan = lambda deg: torch.tan(torch.deg2rad(deg))  # noqa: E731
    heading = torch.tensor([77.0], dtype=torch.float64)
    p0, h0 = band_psr(filters, to_tan(base), heading, drop_harmonics=1)
    p1, h1 = band_psr(filters, to_tan(tilted), heading, drop_harmonics=1)
    np.testing.assert_allclose(p1.numpy(), p0.numpy(), rtol=1e-9)  # PSR is scale invariant: max division is moot
    np.testing.assert_allclose(h1.numpy(), h0.numpy(), atol=1e-9)
    assert not np.allclose(band_psr(filters, to_tan(tilted), heading)[0].numpy(), p0.numpy(), rtol=1e-3)


def test_band_psr_float32_close_to_float64():
    gen = torch.Generator().manual_seed(0)
    filters = torch.randn(50, 2 * 129, generator=gen, dtype=torch.float64)
    profile = torch.cumsum(torch.randn(2, 256, generator=gen, dtype=torch.float64), -1) * 0.01
    heading = torch.tensor([10.0, 300.0], dtype=torch.float64)
    p64, _ = band_psr(filters, profile, heading)
    p32, _ = band_psr(filters.float(), profile.float(), heading.float())
    np.testing.assert_allclose(p32.double().numpy(), p64.numpy(), atol=1e-4 * p64.abs().max().item())

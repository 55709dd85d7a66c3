"""RealDft2 against torch.fft: windowed, scaled half spectra of natural-order patches and the inverse, in its
batch-in-the-middle layout."""

import pytest
import torch

from models.dcf import cosine_window
from models.dcf.dft import RealDft2


def _spectrum(dft: RealDft2, x: torch.Tensor) -> torch.Tensor:
    """Complex spectra ``(B, N_f, K)`` of patches ``(B, N, N)`` (batch first, as torch.fft)."""
    re, im = dft(x.permute(1, 0, 2))
    return torch.complex(re, im).permute(1, 0, 2)


def _inverse(dft: RealDft2, spectrum: torch.Tensor) -> torch.Tensor:
    """Signals ``(B, N, N)`` from complex spectra ``(B, N_f, K)``."""
    both = torch.cat([spectrum.real, spectrum.imag], -1).permute(1, 0, 2)
    return dft.inverse(both).permute(1, 0, 2)


@pytest.mark.parametrize("n", [1, 7, 15])
def test_forward_equals_rfft2_of_the_centred_windowed_patch(n):
    gen = torch.Generator().manual_seed(n)
    x = torch.randn(4, n, n, generator=gen, dtype=torch.float64)
    window = torch.rand(n, generator=gen, dtype=torch.float64) + 0.5
    scale = torch.rand(n, generator=gen, dtype=torch.float64) + 0.5
    spectrum = _spectrum(RealDft2(n, window, scale, dtype=torch.float64), x)
    centred = torch.roll(x * window[:, None] * window[None, :], (-(n // 2), -(n // 2)), (-2, -1))
    k = n // 2 + 1
    expected = torch.fft.rfft2(centred) * scale[:, None] * scale[None, :k]
    torch.testing.assert_close(spectrum, expected, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("n", [5, 21])
def test_inverse_equals_irfft2(n):
    gen = torch.Generator().manual_seed(n)
    spectrum = torch.fft.rfft2(torch.randn(3, n, n, generator=gen, dtype=torch.float64))
    out = _inverse(RealDft2(n, dtype=torch.float64), spectrum)
    torch.testing.assert_close(out, torch.fft.irfft2(spectrum, s=(n, n)), rtol=1e-10, atol=1e-10)


def test_round_trip_and_window_from_the_filter_core():
    n = 9
    x = torch.randn(2, n, n, dtype=torch.float64)
    window = cosine_window((n,), dtype=torch.float64).roll(n // 2)
    dft = RealDft2(n, window, dtype=torch.float64)
    back = _inverse(dft, _spectrum(dft, x))
    centred = torch.roll(x * window[:, None] * window, (-(n // 2), -(n // 2)), (-2, -1))
    torch.testing.assert_close(back, centred)
    with pytest.raises(ValueError, match="odd"):
        RealDft2(8)
    with pytest.raises(ValueError, match="patches"):
        dft(torch.zeros(n, 2, n + 2, dtype=torch.float64))
    with pytest.raises(ValueError, match="spectra"):
        dft.inverse(torch.zeros(n, 2, n, dtype=torch.float64))
    with pytest.raises(ValueError, match="band"):
        RealDft2(n, band=n // 2 + 1)


@pytest.mark.parametrize(("n", "band"), [(21, 7), (15, 0), (9, 4)])
def test_band_limit_keeps_the_low_frequencies_of_the_full_spectrum(n, band):
    gen = torch.Generator().manual_seed(band)
    x = torch.randn(3, n, n, generator=gen, dtype=torch.float64)
    window = torch.rand(n, generator=gen, dtype=torch.float64) + 0.5
    scale = torch.rand(n, generator=gen, dtype=torch.float64) + 0.5
    full = _spectrum(RealDft2(n, window, scale, dtype=torch.float64), x)
    limited = RealDft2(n, window, scale, dtype=torch.float64, band=band)
    rows = torch.cat([torch.arange(band + 1), torch.arange(n - band, n)])
    expected = full[:, rows, : band + 1]
    torch.testing.assert_close(_spectrum(limited, x), expected, rtol=1e-10, atol=1e-10)
    # the inverse samples the band-limited signal on the full grid: irfft2 of the zero-padded spectrum
    padded = torch.zeros_like(full)
    padded[:, rows, : band + 1] = expected
    out = _inverse(limited, expected)
    torch.testing.assert_close(out, torch.fft.irfft2(padded, s=(n, n)), rtol=1e-10, atol=1e-10)


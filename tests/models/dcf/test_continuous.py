"""Continuous C-COT filter: spline transform, samples, weights, Newton peak and sub-pixel shifts."""

import math

import numpy as np
import pytest
import torch

from models.dcf import (
    CcotFilter,
    ccot_filter,
    ccot_sample,
    ccot_train,
    ccot_update,
    continuous_label,
    cubic_spline_fourier,
    exponential_forgetting_weights,
    fourier_series_peak,
    shift_fourier,
)
from models.dcf.continuous import fourier_series_peak_parts


def _keys(s: np.ndarray, a: float = -0.75) -> np.ndarray:
    s = np.abs(s)
    inner = (a + 2) * s**3 - (a + 3) * s**2 + 1
    outer = a * s**3 - 5 * a * s**2 + 8 * a * s - 4 * a
    return np.where(s <= 1, inner, np.where(s < 2, outer, 0.0))


def test_spline_fourier_equals_numerical_transform():
    s = np.linspace(-2, 2, 200001)
    f = np.array([0.0, 1e-4, 0.05, 0.2, 0.37, 0.5, 0.9])
    ref = np.trapezoid(_keys(s)[None] * np.cos(2 * np.pi * f[:, None] * s[None]), s, axis=1)
    got = cubic_spline_fourier(torch.tensor(f)).numpy()
    np.testing.assert_allclose(got, ref, atol=1e-8)
    assert cubic_spline_fourier(torch.tensor([1e-4], dtype=torch.float32)).item() == pytest.approx(
        1.0, abs=1e-6
    )


def test_sample_coefficients_equal_interpolated_function():
    n, fine = 7, 7 * 400
    x = torch.randn(n, dtype=torch.float64, generator=torch.Generator().manual_seed(4))
    t = np.arange(fine) * n / fine
    # J{x}(t) = sum_n x[n] b(t - n), periodic with period n
    J = sum(x[m].item() * _keys(((t - m + n / 2) % n) - n / 2) for m in range(n))
    coef = np.fft.fft(J) / fine  # Fourier-series coefficients c_k, k = 0, 1, ...
    got = ccot_sample(x, 1).numpy()
    np.testing.assert_allclose(got, coef[: n // 2 + 1], atol=1e-9)


def test_label_equals_periodic_gaussian_coefficients():
    n, sigma, fine = 11, 1.3, 11 * 200
    t = np.arange(fine) * n / fine
    d = ((t + n / 2) % n) - n / 2
    y = sum(np.exp(-0.5 * ((d + j * n) / sigma) ** 2) for j in (-1, 0, 1))
    coef = np.fft.fft(y) / fine
    got = continuous_label((n,), sigma, dtype=torch.float64).numpy()
    np.testing.assert_allclose(got, coef[: n // 2 + 1].real, atol=1e-9)
    got2 = continuous_label((n, n), sigma, dtype=torch.float64).numpy()
    full = coef[np.fft.fftfreq(n, 1 / n).astype(int) % fine].real
    np.testing.assert_allclose(got2, np.outer(full, coef[: n // 2 + 1].real), atol=1e-9)


def test_recursive_update_equals_weighted_memory():
    gen = torch.Generator().manual_seed(5)
    size, eta = (9, 7), 0.2
    xhat = ccot_sample(torch.randn(4, 3, *size, generator=gen, dtype=torch.float64))  # 4 filters, 3 samples
    yhat = continuous_label(size, 1.0, dtype=torch.float64)
    A, B = ccot_train(xhat[:, :1], yhat, torch.ones(4, 1, dtype=torch.float64))
    for j in (1, 2):
        A, B = ccot_update(A, B, xhat[:, j], yhat, eta)
    weights = exponential_forgetting_weights(3, eta)
    assert weights.sum().item() == pytest.approx(1.0)
    A_ref, B_ref = ccot_train(xhat, yhat, weights.expand(4, 3))
    torch.testing.assert_close(A, A_ref)
    torch.testing.assert_close(B, B_ref)


def _dense_series_max(shat: np.ndarray, size: tuple[int, int], step: float) -> tuple[float, float]:
    """Brute-force maximum of the 2D series on a fine grid of step ``step`` bins."""
    ky = np.fft.fftfreq(size[0], 1 / size[0])
    kx = np.arange(size[1] // 2 + 1)
    w = np.where(kx == 0, 1.0, 2.0)
    ty = np.arange(-size[0] / 2, size[0] / 2, step)
    tx = np.arange(-size[1] / 2, size[1] / 2, step)
    Ey = np.exp(2j * np.pi * np.outer(ty, ky) / size[0])
    Ex = np.exp(2j * np.pi * np.outer(kx, tx) / size[1]) * w[:, None]
    s = (Ey @ shat @ Ex).real
    i, j = np.unravel_index(np.argmax(s), s.shape)
    return tx[j], ty[i]


def test_newton_peak_equals_dense_search():
    gen = torch.Generator().manual_seed(6)
    size = (15, 13)
    for _ in range(3):
        x = torch.randn(*size, generator=gen, dtype=torch.float64)
        smooth = torch.fft.irfftn(
            torch.fft.rfftn(x) * continuous_label(size, 1.2, dtype=torch.float64), s=size
        )
        shat = ccot_sample(smooth, 2)
        shift, _ = fourier_series_peak(shat, size, iterations=8)
        ref = _dense_series_max(shat.numpy(), size, 0.004)
        np.testing.assert_allclose(shift.numpy(), ref, atol=4e-3)


def test_newton_peak_of_a_band_limited_spectrum_equals_the_zero_padded_one():
    gen = torch.Generator().manual_seed(7)
    size, band = (21, 21), 6
    shat = ccot_sample(torch.randn(5, *size, generator=gen, dtype=torch.float64), 2)
    rows = torch.cat([torch.arange(band + 1), torch.arange(size[0] - band, size[0])])
    padded = torch.zeros_like(shat)
    padded[:, rows, : band + 1] = shat[:, rows, : band + 1]
    limited = padded[:, rows, : band + 1]
    grid = torch.fft.irfftn(padded, s=size)
    expected = fourier_series_peak(padded, size, iterations=6, grid=grid)
    shift, value = fourier_series_peak_parts(limited.real, limited.imag, size, 6, grid)
    torch.testing.assert_close(shift, expected[0], rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(value, expected[1], rtol=1e-12, atol=1e-12)


def _bandlimited(
    n_batch: int, size: tuple[int, ...], shift: torch.Tensor, gen
) -> tuple[torch.Tensor, torch.Tensor]:
    """Random real periodic signals with |k| <= N/3 sampled at t = n and at t = n - shift (last axis
    first)."""
    ndim = len(size)
    ks = [torch.fft.fftfreq(n, 1 / n, dtype=torch.float64) for n in size]
    grids = torch.meshgrid(*ks, indexing="ij")
    band = torch.ones(size, dtype=torch.bool)
    for g, n in zip(grids, size, strict=True):
        band &= g.abs() <= n / 3
    spec = torch.complex(
        torch.randn(n_batch, *size, generator=gen), torch.randn(n_batch, *size, generator=gen)
    )
    spec = spec.to(torch.complex128) * band
    x = torch.fft.ifftn(spec, dim=tuple(range(-ndim, 0))).real
    phase = sum(grids[a] * shift[:, ndim - 1 - a].reshape(-1, *([1] * ndim)) / size[a] for a in range(ndim))
    X = torch.fft.fftn(x, dim=tuple(range(-ndim, 0)))
    z = torch.fft.ifftn(X * torch.exp(-2j * math.pi * phase), dim=tuple(range(-ndim, 0))).real
    return x, z


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("size", [(63,), (21, 21), (15, 19)])
def test_subpixel_shift_of_bandlimited_signals(size, dtype):
    gen = torch.Generator().manual_seed(7)
    ndim = len(size)
    shift = (torch.rand(32, ndim, generator=gen, dtype=torch.float64) - 0.5) * 6
    x, z = _bandlimited(32, size, shift, gen)
    ccot = CcotFilter(ndim, sigma=1.0, beta2_rel=1e-3, log=False, normalize=False, window=False)
    state = ccot.fit(x.to(dtype).unsqueeze(-ndim - 1))
    _, est, _ = ccot(state, z.to(dtype))
    err = (est.double() - shift).abs().max().item()
    assert err < 0.05, err


def test_shift_fourier_moves_sample():
    gen = torch.Generator().manual_seed(8)
    size = (11, 13)
    shift = torch.tensor([[1.25, -0.5]], dtype=torch.float64)
    x, z = _bandlimited(1, size, shift, gen)
    # z(t) = x(t - shift), so z shifted by +shift is x again
    torch.testing.assert_close(shift_fourier(ccot_sample(z), shift, size), ccot_sample(x))


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="odd"):
        ccot_sample(torch.rand(3, 8, 8))
    with pytest.raises(ValueError, match="weights"):
        ccot_train(ccot_sample(torch.rand(2, 3, 5, 5)), continuous_label((5, 5), 1.0), torch.ones(2, 4))
    with pytest.raises(ValueError, match="eta"):
        exponential_forgetting_weights(3, 0.0)
    with pytest.raises(ValueError, match="regularisation"):
        ccot_filter(torch.ones(5, 3, dtype=torch.complex64), torch.zeros(5, 3))

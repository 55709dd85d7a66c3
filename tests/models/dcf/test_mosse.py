"""MOSSE against a brute-force spatial least-squares solve, and exact recovery of integer shifts."""

import itertools

import numpy as np
import pytest
import torch

from models.dcf import (
    Mosse,
    cosine_window,
    dcf_preprocess,
    gaussian_label,
    mosse_filter,
    mosse_response,
    mosse_train,
    mosse_update,
    response_peak,
)


def _correlation_matrix(x: np.ndarray) -> np.ndarray:
    """Matrix C with (C h)[n] = sum_m h[m] x[(n + m) mod size], over flattened 1D/2D indices."""
    size = x.shape
    idx = list(itertools.product(*[range(s) for s in size]))
    C = np.zeros((len(idx), len(idx)))
    for i, n in enumerate(idx):
        for j, m in enumerate(idx):
            C[i, j] = x[tuple((a + b) % s for a, b, s in zip(n, m, size, strict=True))]
    return C


def _brute_force_filter(xs: np.ndarray, y: np.ndarray, weights: np.ndarray, eps: float) -> np.ndarray:
    """argmin_h sum_i w_i ||h (*) x_i - y||^2 + eps ||h||^2 by normal equations."""
    n = y.size
    lhs = eps * np.eye(n)
    rhs = np.zeros(n)
    for w, x in zip(weights, xs, strict=True):
        C = _correlation_matrix(x)
        lhs += w * C.T @ C
        rhs += w * C.T @ y.ravel()
    return np.linalg.solve(lhs, rhs).reshape(y.shape)


@pytest.mark.parametrize("size", [(9,), (12,), (5, 6), (4, 4)])
def test_closed_form_equals_spatial_least_squares(size):
    gen = torch.Generator().manual_seed(0)
    ndim = len(size)
    x = torch.randn(3, *size, generator=gen, dtype=torch.float64)
    y = gaussian_label(size, 1.5, dtype=torch.float64)
    eps = 0.7
    A, B = mosse_train(x, y, ndim)
    H = mosse_filter(A, B, ndim, eps=eps)
    # (C h)[n] = sum_m h[m] x[n + m] has DFT conj(DFT(h)) X, so h = IDFT(conj(H*)).
    h = torch.fft.irfftn(H.conj(), s=size, dim=tuple(range(-ndim, 0)))
    ref = _brute_force_filter(x.numpy(), y.numpy(), np.ones(3), eps)
    np.testing.assert_allclose(h.numpy(), ref, atol=1e-10)
    z = torch.randn(*size, generator=gen, dtype=torch.float64)
    response = mosse_response(H, z, ndim)
    np.testing.assert_allclose(
        response.numpy().ravel(), _correlation_matrix(z.numpy()) @ ref.ravel(), atol=1e-10
    )


def test_running_update_equals_weighted_least_squares():
    gen = torch.Generator().manual_seed(1)
    size, eta, eps = (6, 5), 0.3, 0.2
    x = torch.randn(3, *size, generator=gen, dtype=torch.float64)
    y = gaussian_label(size, 1.0, dtype=torch.float64)
    A, B = mosse_train(x[:1], y)
    for t in (1, 2):
        A, B = mosse_update(A, B, x[t], y, eta)
    h = torch.fft.irfftn(mosse_filter(A, B, eps=eps).conj(), s=size)
    weights = np.array([(1 - eta) ** 2, eta * (1 - eta), eta])
    np.testing.assert_allclose(h.numpy(), _brute_force_filter(x.numpy(), y.numpy(), weights, eps), atol=1e-10)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("size", [(64,), (31,), (24, 20), (17, 17)])
def test_integer_shifts_recovered_exactly(size, dtype):
    gen = torch.Generator().manual_seed(2)
    ndim = len(size)
    batch = 16
    x = torch.rand(batch, *size, generator=gen).to(dtype)
    shifts = torch.stack([torch.randint(-(n // 2), n - n // 2, (batch,), generator=gen) for n in size], -1)
    z = torch.stack(
        [torch.roll(xi, tuple(s.tolist()), tuple(range(ndim))) for xi, s in zip(x, shifts, strict=True)]
    )
    mosse = Mosse(ndim, sigma=2.0, eps_rel=1e-3, log=False, normalize=False, window=False)
    state = mosse.fit(x.unsqueeze(-ndim - 1))
    response, shift, psr = mosse(state, z)
    integer, _ = response_peak(response, ndim, subpixel=False)
    expected = shifts.flip(-1).to(dtype)  # last axis first
    assert torch.equal(integer, expected)
    assert (shift - expected).abs().max() < 1e-3
    assert (psr > 20).all()


def test_preprocessing_flags():
    x = torch.rand(4, 9, 11, dtype=torch.float64) * 255
    n = dcf_preprocess(x, 2, log=False, normalize=True, window=False)
    assert n.mean((-2, -1)).abs().max() < 1e-12
    assert ((n.square().mean((-2, -1)) - 1).abs() < 1e-6).all()
    w = cosine_window((9, 11), dtype=torch.float64)
    assert w[0, 0] == w.max() and w.min() > 0
    assert torch.allclose(dcf_preprocess(x, 2, log=True, normalize=False, window=False), torch.log1p(x))
    assert torch.equal(dcf_preprocess(x, 2, log=False, normalize=False, window=False), x)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="ndim"):
        mosse_train(torch.rand(2, 3, 4, 4), torch.rand(4, 4), ndim=3)
    with pytest.raises(ValueError, match="floating"):
        mosse_response(torch.ones(3, 3, dtype=torch.complex64), torch.ones(3, 5, dtype=torch.int64))
    with pytest.raises(ValueError, match="sample axis"):
        mosse_train(torch.rand(8), torch.rand(8), ndim=1)
    with pytest.raises(ValueError, match="sigma"):
        gaussian_label((5,), 0.0)

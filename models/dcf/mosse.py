"""MOSSE correlation filter (Bolme et al. 2010; thesis eqs. 3.1-3.5) for batched 1D and 2D signals.

Closed form per frequency: ``H* = sum_i G_i . conj(F_i) / (sum_i F_i . conj(F_i) + eps)``; running update
``A_t = eta G . conj(F_t) + (1 - eta) A_{t-1}`` and likewise ``B_t``; response ``IDFT(H* . Z)``. In the
spatial domain ``H*`` is the minimiser of ``sum_i ||h (*) x_i - y_i||^2 + eps ||h||^2`` with ``(*)`` circular
correlation. Spectra are ``rfft`` half spectra, so signals are real. The state ``(A, B)`` is kept unnormalised
so that the regulariser can be absolute (``eps``) or relative to the mean sample energy (``eps_rel``).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.dcf._signal import check_signal, signal_dims
from models.dcf.peak import response_peak
from models.dcf.preprocess import dcf_preprocess
from models.dcf.psr import peak_to_sidelobe_ratio


def gaussian_label(size: tuple[int, ...], sigma: float, *, device=None, dtype=torch.float32) -> Tensor:
    """Sampled Gaussian label with peak 1 at index 0, wrapped around (circular distance), std ``sigma``
    bins."""
    if sigma <= 0:
        raise InputError(f"sigma must be positive, got {sigma}")
    label = torch.ones((), device=device, dtype=dtype)
    for axis, n in enumerate(size):
        i = torch.arange(n, device=device, dtype=dtype)
        d = torch.minimum(i, n - i)
        shape = [1] * len(size)
        shape[axis] = n
        label = label * torch.exp(-0.5 * (d / sigma) ** 2).reshape(shape)
    return label


def _spectra(x: Tensor, y: Tensor, ndim: int) -> tuple[Tensor, Tensor]:
    dims = signal_dims(ndim)
    return torch.fft.rfftn(x, dim=dims), torch.fft.rfftn(y, dim=dims)


def mosse_train(x: Tensor, y: Tensor, ndim: int = 2) -> tuple[Tensor, Tensor]:
    """Closed-form MOSSE numerator and denominator from M training samples (eq. 3.4).

    Args:
        x: ``(..., M, *S)`` preprocessed samples, ``ndim`` signal axes, sample axis just before them.
        y: labels broadcastable to ``x`` (e.g. :func:`gaussian_label`).
    Returns:
        A: ``(..., *K)`` complex ``sum_i Y_i conj(X_i)``; B: ``(..., *K)`` real ``sum_i |X_i|^2``
        (``K`` = half spectrum of ``S``).
    """
    check_signal(x, ndim, "x")
    if x.dim() < ndim + 1:
        raise InputError(f"x needs a sample axis before the {ndim} signal axes, got shape {tuple(x.shape)}")
    X, Y = _spectra(x, y.to(x.dtype), ndim)
    sample = -(ndim + 1)
    return (Y * X.conj()).sum(dim=sample), (X.real.square() + X.imag.square()).sum(dim=sample)


def mosse_update(A: Tensor, B: Tensor, x: Tensor, y: Tensor, eta: float | Tensor, ndim: int = 2):
    """Running MOSSE update with learning rate ``eta`` (eq. 3.4 as in Bolme et al.).

    Args:
        A, B: ``(..., *K)`` current numerator (complex) and denominator (real).
        x: ``(..., *S)`` one new preprocessed sample per filter; y: its label (broadcastable).
        eta: learning rate in ``[0, 1]``, a float or a tensor broadcastable to ``(...)`` + ``ndim`` ones.
    Returns:
        updated ``(A, B)``.
    """
    check_signal(x, ndim, "x")
    X, Y = _spectra(x, y.to(x.dtype), ndim)
    A_new = Y * X.conj()
    B_new = X.real.square() + X.imag.square()
    return eta * A_new + (1 - eta) * A, eta * B_new + (1 - eta) * B


def mosse_filter(A: Tensor, B: Tensor, ndim: int = 2, eps: float = 0.0, eps_rel: float = 0.0) -> Tensor:
    """Filter ``H* = A / (B + eps + eps_rel * mean(B))`` with the mean over each filter's frequencies.

    Returns:
        ``(..., *K)`` complex conjugate filter spectrum ``H*``.
    """
    if eps < 0 or eps_rel < 0 or (eps == 0 and eps_rel == 0 and bool((B <= 0).any())):
        raise InputError("regularisation must be non-negative and positive where B has zeros")
    reg = eps + eps_rel * B.mean(dim=signal_dims(ndim), keepdim=True)
    return A / (B + reg)


def mosse_response(H: Tensor, z: Tensor, ndim: int = 2) -> Tensor:
    """Response ``IDFT(H* . Z)`` (eq. 3.5) of filters ``H*`` ``(..., *K)`` to signals ``z`` ``(..., *S)``."""
    check_signal(z, ndim, "z")
    dims = signal_dims(ndim)
    return torch.fft.irfftn(H * torch.fft.rfftn(z, dim=dims), s=z.shape[-ndim:], dim=dims)


class Mosse(nn.Module):
    """A batch of MOSSE filters: fixed hyper-parameters, state ``(A, B)`` passed in and out.

    Args:
        ndim: 1 (profiles) or 2 (image patches).
        sigma: Gaussian label std in bins. eta: learning rate of :meth:`update`.
        eps, eps_rel: absolute and relative (to the mean of ``B``) regularisation.
        log, normalize, window: preprocessing flags (:func:`dcf_preprocess`).
        psr_exclude: side of the window around the peak left out of the PSR sidelobe.
    """

    def __init__(
        self,
        ndim: int = 2,
        sigma: float = 2.0,
        eta: float = 0.125,
        eps: float = 0.0,
        eps_rel: float = 1e-2,
        log: bool = True,
        normalize: bool = True,
        window: bool = True,
        psr_exclude: int = 11,
    ) -> None:
        super().__init__()
        self.ndim, self.sigma, self.eta, self.eps, self.eps_rel = ndim, sigma, eta, eps, eps_rel
        self.log, self.normalize, self.window, self.psr_exclude = log, normalize, window, psr_exclude

    def preprocess(self, x: Tensor) -> Tensor:
        return dcf_preprocess(x, self.ndim, log=self.log, normalize=self.normalize, window=self.window)

    def label(self, x: Tensor) -> Tensor:
        return gaussian_label(tuple(x.shape[-self.ndim :]), self.sigma, device=x.device, dtype=x.dtype)

    def fit(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Train on ``(..., M, *S)`` raw samples (target at index 0); returns the state ``(A, B)``."""
        return mosse_train(self.preprocess(x), self.label(x), self.ndim)

    def update(self, state: tuple[Tensor, Tensor], x: Tensor) -> tuple[Tensor, Tensor]:
        """Blend one raw sample per filter ``(..., *S)`` into the state with rate ``eta``."""
        return mosse_update(*state, self.preprocess(x), self.label(x), self.eta, self.ndim)

    def forward(self, state: tuple[Tensor, Tensor], z: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """Apply to raw signals ``z`` ``(..., *S)``.

        Returns:
            response ``(..., *S)``, shift ``(..., ndim)`` (sub-bin, last axis first) and PSR ``(...)``.
        """
        H = mosse_filter(*state, self.ndim, self.eps, self.eps_rel)
        response = mosse_response(H, self.preprocess(z), self.ndim)
        shift, _ = response_peak(response, self.ndim)
        return response, shift, peak_to_sidelobe_ratio(response, self.ndim, self.psr_exclude)

"""Optional DCF preprocessing (MOSSE, Bolme et al. 2010): log, normalisation and a cosine window, each a flag.

Periodic signals such as 360-degree horizon profiles want none of them; image patches want all or some.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.dcf._signal import check_signal, signal_dims


def cosine_window(size: tuple[int, ...], *, device=None, dtype=torch.float32) -> Tensor:
    """Separable Hann window ``hann(N + 2)[1:-1]`` per axis (never zero), centred on index 0 (FFT order).

    Args:
        size: signal shape, 1 or 2 axes.
    Returns:
        window of shape ``size`` with its maximum at index 0.
    """
    window = torch.ones((), device=device, dtype=dtype)
    for axis, n in enumerate(size):
        k = torch.arange(1, n + 1, device=device, dtype=dtype)
        w = 0.5 - 0.5 * torch.cos(2 * torch.pi * k / (n + 1))
        w = torch.roll(w, -(n // 2))
        shape = [1] * len(size)
        shape[axis] = n
        window = window * w.reshape(shape)
    return window


def tukey_window(size: tuple[int, ...], taper: float = 0.5, *, device=None, dtype=torch.float32) -> Tensor:
    """Separable Tukey (tapered cosine) window per axis, sampled like :func:`cosine_window` (never zero), centred
    on index 0 (FFT order): 1 over the middle ``1 - taper`` of each axis, a half Hann taper over ``taper / 2`` at
    either end; ``taper`` 1 is :func:`cosine_window`.

    A flat window weights more of a patch fully: where noise limits a correlation's precision, the scatter of the
    peak falls with the sum of the weights (the pixels that count), at the price of more of the patch's border,
    where a patch deforms or is occluded first, counting as much as its centre.

    Args:
        size: signal shape, 1 or 2 axes. taper: fraction of each axis in the tapers, in (0, 1].
    Returns:
        window of shape ``size`` with its flat top around index 0.
    """
    if not 0 < taper <= 1:
        raise InputError(f"tukey_window needs a taper in (0, 1], got {taper}")
    window = torch.ones((), device=device, dtype=dtype)
    for axis, n in enumerate(size):
        x = torch.arange(1, n + 1, device=device, dtype=dtype) / (n + 1)  # in (0, 1), as cosine_window's samples
        edge = torch.minimum(x, 1 - x) / (taper / 2)  # < 1 inside the tapers
        w = torch.where(edge < 1, 0.5 - 0.5 * torch.cos(torch.pi * edge.clamp_max(1)), torch.ones_like(x))
        w = torch.roll(w, -(n // 2))
        shape = [1] * len(size)
        shape[axis] = n
        window = window * w.reshape(shape)
    return window


def dcf_preprocess(
    x: Tensor,
    ndim: int = 2,
    *,
    log: bool = True,
    normalize: bool = True,
    window: bool = True,
    eps: float = 1e-5,
) -> Tensor:
    """Preprocess signals for a correlation filter.

    Args:
        x: ``(..., *S)`` real signals in FFT order (target at index 0), ``ndim`` signal axes.
        log: apply ``log(x + 1)`` (needs ``x >= 0``, e.g. pixel values).
        normalize: subtract the mean and divide by the standard deviation (plus ``eps``) per signal.
        window: multiply by :func:`cosine_window`, centred on index 0.
    Returns:
        ``(..., *S)`` preprocessed signals.
    """
    check_signal(x, ndim, "x")
    dims = signal_dims(ndim)
    if log:
        x = torch.log(x.clamp_min(0) + 1)
    if normalize:
        mean = x.mean(dim=dims, keepdim=True)
        std = (x - mean).square().mean(dim=dims, keepdim=True).sqrt()
        x = (x - mean) / (std + eps)
    if window:
        x = x * cosine_window(tuple(x.shape[-ndim:]), device=x.device, dtype=x.dtype)
    return x


class DcfPreprocess(nn.Module):
    """Module form of :func:`dcf_preprocess` with fixed flags."""

    def __init__(self, ndim: int = 2, log: bool = True, normalize: bool = True, window: bool = True) -> None:
        super().__init__()
        self.ndim, self.log, self.normalize, self.window = ndim, log, normalize, window

    def forward(self, x: Tensor) -> Tensor:
        return dcf_preprocess(x, self.ndim, log=self.log, normalize=self.normalize, window=self.window)

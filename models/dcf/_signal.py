"""Small helpers shared by the filter modules: argument checks and integer frequency grids."""

from __future__ import annotations

import torch
from torch import Tensor

from core.checks import check_tensor
from core.errors import InputError


def check_signal(x: Tensor, ndim: int, name: str) -> None:
    """Raise ``InputError`` unless ``x`` is a real floating tensor with at least ``ndim`` non-empty signal axes."""
    if ndim not in (1, 2):
        raise InputError(f"ndim must be 1 or 2, got {ndim}")
    check_tensor(x, name, min_ndim=ndim, floating=True)
    if any(n < 1 for n in x.shape[-ndim:]):
        raise InputError(f"{name} has an empty signal axis: shape {tuple(x.shape)}")


def signal_dims(ndim: int) -> tuple[int, ...]:
    """The signal axes as negative dims, e.g. ``(-2, -1)`` for 2D."""
    return tuple(range(-ndim, 0))


def full_frequencies(n: int, device: torch.device, dtype: torch.dtype) -> Tensor:
    """Integer frequencies of a full DFT axis of length ``n`` in FFT order: 0, 1, .., -1."""
    return torch.remainder(torch.arange(n, device=device, dtype=dtype) + n // 2, n) - n // 2


def half_frequencies(n: int, device: torch.device, dtype: torch.dtype) -> Tensor:
    """Integer frequencies 0 .. n // 2 of the last (halved) axis of an rfft of length ``n``."""
    return torch.arange(n // 2 + 1, device=device, dtype=dtype)


def wrap_index(i: Tensor, n: int) -> Tensor:
    """Map a circular index in ``[0, n)`` to the signed shift in ``[-n // 2, n - n // 2)``."""
    return torch.remainder(i + n // 2, n) - n // 2

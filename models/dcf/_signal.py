"""Small helpers shared by the filter modules: argument checks and integer frequency grids."""

from __future__ import annotations

import torch
from torch import Tensor


def check_signal(x: Tensor, ndim: int, name: str) -> None:
    """Raise ValueError unless ``x`` is a real floating tensor with at least ``ndim`` signal axes."""
    if ndim not in (1, 2):
        raise ValueError(f"ndim must be 1 or 2, got {ndim}")
    if not isinstance(x, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if x.dim() < ndim:
        raise ValueError(f"{name} needs at least {ndim} signal axes, got shape {tuple(x.shape)}")
    if not x.is_floating_point():
        raise ValueError(f"{name} must be a real floating tensor, got {x.dtype}")
    if any(n < 1 for n in x.shape[-ndim:]):
        raise ValueError(f"{name} has an empty signal axis: shape {tuple(x.shape)}")


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

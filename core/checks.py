"""Argument checks shared by every layer: each raises ``InputError`` with a message that names the argument."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

from core.errors import InputError


def check_tensor(
    x: object,
    name: str,
    shape: Sequence[int | None] | None = None,
    min_ndim: int | None = None,
    floating: bool = False,
) -> Tensor:
    """Return ``x`` when it is a tensor of the expected form, else raise ``InputError`` naming ``name``.

    Args:
        x: the value to check.
        name: the argument's name in the message, e.g. ``"cameras P"``.
        shape: expected shape, ``None`` for any size of an axis, e.g. ``(None, None, 3, 4)`` for (B, N, 3, 4).
        min_ndim: at least this many axes (when ``shape`` is not given).
        floating: require a real floating dtype (float16/32/64, bfloat16).
    """
    if not isinstance(x, Tensor):
        raise InputError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if shape is not None and (x.dim() != len(shape) or any(s is not None and s != n for s, n in zip(shape, x.shape,
                                                                                                     strict=False))):
        expected = ", ".join("*" if s is None else str(s) for s in shape)
        raise InputError(f"{name} must have shape ({expected}), got {tuple(x.shape)}")
    if min_ndim is not None and x.dim() < min_ndim:
        raise InputError(f"{name} needs at least {min_ndim} axes, got shape {tuple(x.shape)}")
    if floating and (not x.is_floating_point() or x.is_complex()):
        raise InputError(f"{name} must be a real floating tensor, got {x.dtype}")
    return x


def check_same_dtype(*named: tuple[str, Tensor]) -> torch.dtype:
    """The one dtype shared by the ``(name, tensor)`` pairs, else ``InputError`` naming them all."""
    dtypes = {t.dtype for _, t in named}
    if len(dtypes) != 1:
        listed = " and ".join(f"{n} {t.dtype}" for n, t in named)
        raise InputError(f"{', '.join(n for n, _ in named)} must share one dtype, got {listed}")
    return dtypes.pop()


def check_positive(value: float, name: str) -> float:
    """Return ``value`` when it is a finite number > 0, else raise ``InputError`` naming ``name``."""
    if not (value > 0 and value < float("inf")):
        raise InputError(f"{name} must be positive, got {value}")
    return value


def check_device(device: str, name: str = "device") -> torch.device:
    """``device`` as a ``torch.device`` when this machine has it, else ``InputError`` naming ``name``: an unknown
    device string, a device other than the CPU and CUDA (the project's ops run on these two), or a CUDA device where
    CUDA is not available or has fewer devices than its index."""
    try:
        parsed = torch.device(device)
    except RuntimeError as err:
        raise InputError(f"{name} {device!r} is not a torch device: {err}") from None
    if parsed.type not in ("cpu", "cuda"):
        raise InputError(f"{name} {device!r}: only cpu and cuda devices are supported")
    if parsed.type == "cuda":
        if not torch.cuda.is_available():
            raise InputError(f"{name} {device!r} requested but CUDA is not available")
        if parsed.index is not None and parsed.index >= torch.cuda.device_count():
            raise InputError(f"{name} {device!r} requested but only {torch.cuda.device_count()} CUDA devices exist")
    return parsed

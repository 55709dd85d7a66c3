"""The frame size a video tracker works at (``process_height``), shared by the PyTorch trackers and the
deployment runtime so that both resize frames alike. Torch-free."""

from __future__ import annotations

import numpy as np

from core.errors import InputError


def check_process_height(height: int) -> int:
    """``height`` when it is 0 (native size) or a positive number of rows, else an ``InputError`` naming it."""
    if height < 0:
        raise InputError(f"process_height must be 0 (native size) or a positive number of rows, got {height}")
    return height


def processing_size(size: tuple[int, int], height: int) -> tuple[int, int]:
    """``(h, w)`` px at which a ``size = (H, W)`` frame is processed: ``height`` rows with the aspect kept (the
    width rounded to the nearest pixel, at least 1), or ``size`` itself when ``height`` is 0."""
    check_process_height(height)
    h, w = int(size[0]), int(size[1])
    if height == 0 or height == h:
        return h, w
    return height, max(1, round(w * height / h))


def nearest_indices(n_in: int, n_out: int) -> np.ndarray:
    """Source index ``(n_out,)`` int64 of each output pixel when an axis of ``n_in`` pixels is resized to ``n_out``
    by nearest neighbour between pixel centres: ``floor((i + 0.5) n_in / n_out)``, in exact integer arithmetic
    (the rule of torch's ``nearest-exact``, without its floating-point ties)."""
    return (2 * np.arange(n_out, dtype=np.int64) + 1) * n_in // (2 * n_out)

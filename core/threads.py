"""CPU thread control for torch and OpenCV together (benchmarks and commands take ``--threads``)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import cv2
import torch

from core.errors import InputError


def set_cpu_threads(n: int) -> tuple[int, int]:
    """Use ``n`` CPU threads in torch's intra-op pool and OpenCV; returns the previous (torch, OpenCV) counts.

    Many small per-point tensors run fastest, and least disturbed by other jobs, on one thread; on a shared
    2-core machine torch's 2-thread pool collapses under contention.
    """
    if not isinstance(n, int) or n < 1:
        raise InputError(f"the number of threads must be a positive integer, got {n!r}")
    before = torch.get_num_threads(), cv2.getNumThreads()
    torch.set_num_threads(n)
    cv2.setNumThreads(n)
    return before


@contextmanager
def cpu_threads(n: int) -> Iterator[None]:
    """Run the block with ``n`` CPU threads in torch and OpenCV (``set_cpu_threads``), then restore the counts."""
    before = set_cpu_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before[0])
        cv2.setNumThreads(before[1])

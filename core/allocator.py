"""Heap settings for processes that allocate the same large temporaries over and over (point tracking).

glibc's ``malloc`` serves large blocks from fresh ``mmap`` pages and hands freed memory at the top of the heap back
to the kernel; the next block of the same size is then faulted in and zeroed page by page again. A tracking step
allocates and frees about a hundred tensors of megabytes each; how often glibc hands them back depends on the order
of the allocations. Repeating one step on a Sintel frame faulted about 5000 pages a step at 2000 points and 100000
at 10000 points; in whole runs keeping freed memory made the benchmark's 10000-point step about 1.4x faster and
``infer.py track`` 3-8 % faster at 2000 points (docs/results.md). The values computed do not change.
"""

from __future__ import annotations

import ctypes
import sys

# mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_MAX = -4
_NEVER_TRIM = 2**31 - 1  # bytes free at the heap top before glibc trims it (the largest the int parameter takes)


def retain_freed_memory() -> bool:
    """Make glibc's ``malloc`` keep freed memory for reuse in this process: every block from the heap, none from
    ``mmap`` (``M_MMAP_MAX`` 0), and the heap top handed back only when more than 2 GiB of it are free
    (``M_TRIM_THRESHOLD``).

    Process-wide and for the rest of the process (glibc stops adapting its thresholds once they are set); the
    process keeps the peak of its heap. Returns whether the settings took: False off Linux, without glibc's
    ``mallopt`` (e.g. musl) or where it refuses them.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the symbols already loaded in the process, libc's among them
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, _NEVER_TRIM))

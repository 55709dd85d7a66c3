"""A progress line on stderr for the long loops of the torch-free runtime, which installs no progress-bar
package: ``desc: done/total unit (rate/s)``, rewritten in place."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

T = TypeVar("T")


def progress(items: Iterable[T], desc: str, total: int | None = None, unit: str = "frame", enabled: bool = True,
             stream: TextIO | None = None, interval_s: float = 0.5) -> Iterator[T]:
    """Yield ``items`` and rewrite one line ``desc: i/total unit (rate/s)`` on ``stream`` (stderr) at most every
    ``interval_s`` seconds and after the last item (``total``: ``len(items)`` where it has one; without it the
    line shows the count alone). Nothing is written where ``enabled`` is False."""
    if not enabled:
        yield from items
        return
    stream = sys.stderr if stream is None else stream
    total = len(items) if total is None and hasattr(items, "__len__") else total  # type: ignore[arg-type]
    start = shown = time.perf_counter()
    done = 0

    def show(end: str) -> None:
        rate = done / max(time.perf_counter() - start, 1e-9)
        count = f"{done}/{total}" if total is not None else f"{done}"
        stream.write(f"\r{desc}: {count} {unit}s ({rate:.1f}/s)" + end)
        stream.flush()

    for item in items:
        yield item
        done += 1
        if time.perf_counter() - shown >= interval_s:
            show("")
            shown = time.perf_counter()
    if done:
        show("\n")

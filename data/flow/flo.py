"""Middlebury ``.flo`` optical flow files: float32 magic 202021.25 ("PIEH"), int32 width, int32 height, then
``H x W x 2`` float32 (u, v) little-endian, row-major. Values beyond 1e9 mean "unknown" and become NaN.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.errors import InputError

FLO_MAGIC = 202021.25
UNKNOWN_FLOW = 1e9


def read_flo(path: str | Path) -> np.ndarray:
    """Read a ``.flo`` file into a ``(H, W, 2)`` float32 array of (u, v) in pixels (NaN where unknown).

    Raises:
        InputError: the file is missing, too short, has a wrong magic number, bad dimensions or a wrong size.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"flow file not found: {path}")
    raw = path.read_bytes()
    if len(raw) < 12:
        raise InputError(f"{path}: not a .flo file (only {len(raw)} bytes)")
    magic = np.frombuffer(raw, "<f4", 1, 0)[0]
    if magic != np.float32(FLO_MAGIC):
        raise InputError(f"{path}: not a .flo file (magic {magic!r}, expected {FLO_MAGIC})")
    width, height = (int(v) for v in np.frombuffer(raw, "<i4", 2, 4))
    if not (0 < width < 100_000 and 0 < height < 100_000):
        raise InputError(f"{path}: implausible flow size {width}x{height}")
    expected = 12 + width * height * 8
    if len(raw) != expected:
        raise InputError(
            f"{path}: {len(raw)} bytes, expected {expected} for a {width}x{height} flow (truncated?)"
        )
    flow = np.frombuffer(raw, "<f4", width * height * 2, 12).reshape(height, width, 2).astype(np.float32)
    flow[np.abs(flow) > UNKNOWN_FLOW] = np.nan
    return flow


def write_flo(path: str | Path, flow: np.ndarray) -> None:
    """Write a ``(H, W, 2)`` flow as ``.flo`` (NaN is written as the unknown value 1e10)."""
    flow = np.asarray(flow, dtype=np.float32)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise InputError(f"flow must have shape (H, W, 2), got {flow.shape}")
    data = np.where(np.isnan(flow), np.float32(1e10), flow).astype("<f4")
    header = (
        np.array([FLO_MAGIC], "<f4").tobytes() + np.array([flow.shape[1], flow.shape[0]], "<i4").tobytes()
    )
    Path(path).write_bytes(header + data.tobytes())

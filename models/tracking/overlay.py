"""Overlay video of point tracks: tracked points green with a short trail, lost points red."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError
from core.files import atomic_path


def write_overlay_video(
    path: str | Path,
    frames: Sequence[np.ndarray],
    tracks: np.ndarray,
    lost: np.ndarray,
    fps: float = 10.0,
    trail: int = 5,
) -> None:
    """Write an MP4 (``mp4v``) of gray frames ``(H, W)`` in [0, 255] with tracks ``(T, P, 2)``, lost
    ``(T, P)`` (atomically: under a temporary name, renamed when complete)."""
    h, w = frames[0].shape
    with atomic_path(path) as tmp:
        _write_video(tmp, frames, tracks, lost, fps, trail, (w, h), path)


def _write_video(tmp: Path, frames: Sequence[np.ndarray], tracks: np.ndarray, lost: np.ndarray, fps: float,
                 trail: int, size: tuple[int, int], path: str | Path) -> None:
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
    if not writer.isOpened():
        raise InputError(f"cannot open {path} for writing a video")
    try:
        for t, frame in enumerate(frames):
            image = cv2.cvtColor(np.clip(frame, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
            for p in np.flatnonzero(~lost[t]):
                points = tracks[max(0, t - trail) : t + 1, p].round().astype(np.int32)
                cv2.polylines(image, [points.reshape(-1, 1, 2)], False, (0, 200, 0), 1)
                cv2.circle(image, tuple(int(v) for v in points[-1]), 2, (0, 255, 0), -1)
            for p in np.flatnonzero(lost[t]):
                x, y = tracks[t, p].round().astype(int)
                cv2.drawMarker(image, (int(x), int(y)), (0, 0, 255), cv2.MARKER_TILTED_CROSS, 5, 1)
            writer.write(image)
    finally:
        writer.release()

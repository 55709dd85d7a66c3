"""Track points through a frame sequence with any method (the ``track`` command's engine)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from core.errors import InputError
from models.tracking.good_features import good_features_to_track
from models.tracking.klt import klt_track
from models.tracking.point_tracker import METHODS, PointTracker

ALL_METHODS = (*METHODS, "klt")


def track_points(
    frames: Sequence[np.ndarray],
    points: np.ndarray | None = None,
    detect: int | None = None,
    method: str = "ccot",
    device: str = "cpu",
    progress: bool = False,
    compile: bool = False,
) -> dict[str, np.ndarray]:
    """Track given points, or ``detect`` good features in the first frame, through gray frames ``(H, W)``
    (``compile``: the DCF trackers' step through ``torch.compile``, see :meth:`PointTracker.track`).

    Returns:
        ``tracks`` ``(T, P, 2)``, ``lost`` ``(T, P)``, ``psr`` ``(T, P)`` (NaN for KLT) and the start
        ``points``.
    """
    if method not in ALL_METHODS:
        raise InputError(f"unknown tracking method {method!r}; choose one of {', '.join(ALL_METHODS)}")
    if not frames:
        raise InputError("no frames to track")
    if torch.device(device).type == "cuda" and not torch.cuda.is_available():
        raise InputError(f"device {device!r} requested but CUDA is not available")
    if (points is None) == (detect is None):
        raise InputError("give either start points or a number of points to detect")
    for t, frame in enumerate(frames):
        if frame.shape != frames[0].shape:
            raise InputError(f"frame {t} has size {frame.shape}, frame 0 has {frames[0].shape}")
    if points is None:
        if detect < 1:
            raise InputError(f"--detect needs a positive number of points, got {detect}")
        points = good_features_to_track(torch.from_numpy(np.asarray(frames[0], np.float32)), detect).numpy()
        if len(points) == 0:
            raise InputError("no good features to track in the first frame (is it blank?)")
    points = np.asarray(points, dtype=np.float64)
    if method == "klt":
        gray = [np.clip(np.asarray(f), 0, 255).round().astype(np.uint8) for f in frames]
        tracks, lost = klt_track(gray, points)
        return {"tracks": tracks, "lost": lost, "psr": np.full(lost.shape, np.nan), "points": points}
    tracker = PointTracker(method).to(device)
    tensors = [torch.as_tensor(np.asarray(f, np.float32), device=device) for f in frames]
    tracks, lost, psr = tracker.track(
        tensors, torch.as_tensor(points, dtype=torch.float32), progress=progress, compile=compile
    )
    return {
        "tracks": tracks.double().cpu().numpy(),
        "lost": lost.cpu().numpy(),
        "psr": psr.double().cpu().numpy(),
        "points": points,
    }

"""Track points through a frame sequence with any method (the ``track`` command's engine)."""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence

import numpy as np
import torch
from tqdm import tqdm

from core.checks import check_device
from core.errors import InputError
from core.good_features import good_features
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
    """Track given points, or ``detect`` good features in the first frame (:func:`core.good_features.good_features`,
    OpenCV's, as the runtime detects them), through gray frames ``(H, W)``
    (``compile``: the DCF trackers' step through ``torch.compile``, see :meth:`PointTracker.track`).

    Returns:
        ``tracks`` ``(T, P, 2)``, ``lost`` ``(T, P)``, ``psr`` ``(T, P)`` (NaN for KLT), the start ``points`` and
        ``frame_seconds`` ``(T,)``: wall seconds from the tracker's construction until each frame was tracked
        (frame 0: the filters trained; so ``frame_seconds[1]`` is the first-call latency; NaN for KLT).
    """
    if method not in ALL_METHODS:
        raise InputError(f"unknown tracking method {method!r}; choose one of {', '.join(ALL_METHODS)}")
    if not frames:
        raise InputError("no frames to track")
    check_device(device)
    if (points is None) == (detect is None):
        raise InputError("give either start points or a number of points to detect")
    for t, frame in enumerate(frames):
        if frame.shape != frames[0].shape:
            raise InputError(f"frame {t} has size {frame.shape}, frame 0 has {frames[0].shape}")
    # OpenCV's detector, as the runtime's: infer.py track starts from the same points with and without --onnx
    points = good_features(frames[0], detect) if points is None else np.asarray(points, dtype=np.float64)
    if method == "klt":
        gray = [np.clip(np.asarray(f), 0, 255).round().astype(np.uint8) for f in frames]
        tracks, lost = klt_track(gray, points)
        nan = np.full(lost.shape, np.nan)
        return {"tracks": tracks, "lost": lost, "psr": nan, "points": points, "frame_seconds": nan[:, 0]}
    start = time.perf_counter()
    tracker = PointTracker(method).to(device)
    if min(frames[0].shape) < tracker.min_frame_size:
        raise InputError(f"frame 0 is {frames[0].shape}: the {method} tracker needs frames of at least "
                         f"{tracker.min_frame_size} px a side")
    requested: list[float] = []  # when each frame was asked for, i.e. when the one before it was tracked

    def tensors() -> Iterator[torch.Tensor]:
        for frame in tqdm(frames, desc=f"track {method}", unit="frame", disable=not progress):
            requested.append(time.perf_counter())
            yield torch.as_tensor(np.asarray(frame, np.float32), device=device)

    tracks, lost, psr = tracker.track(tensors(), torch.as_tensor(points, dtype=torch.float32), compile=compile)
    done = np.array([*requested[1:], time.perf_counter()]) - start
    return {
        "tracks": tracks.double().cpu().numpy(),
        "lost": lost.cpu().numpy(),
        "psr": psr.double().cpu().numpy(),
        "points": points,
        "frame_seconds": done,
    }

"""Start points for tracking: OpenCV's Shi-Tomasi good features to track, shared by ``infer.py track`` and the
torch-free runtime so that both start from the same points."""

from __future__ import annotations

import cv2
import numpy as np

from core.errors import InputError


def good_features(frame: np.ndarray, count: int, quality: float = 0.01, min_distance: float = 5) -> np.ndarray:
    """Up to ``count`` Shi-Tomasi corners (``cv2.goodFeaturesToTrack``: minimum-eigenvalue response above ``quality``
    times the best, local maxima at least ``min_distance`` px apart) of a gray frame ``(H, W)`` (values in [0, 255],
    rounded to 8 bits), strongest first.

    Returns:
        ``(P, 2)`` (x, y) pixels, float64. ``InputError`` for a non-positive ``count``, a frame that is not 2-D, or
        a frame without corners.
    """
    if count < 1:
        raise InputError(f"--detect needs a positive number of points, got {count}")
    frame = np.asarray(frame)
    if frame.ndim != 2:
        raise InputError(f"good features need a gray (H, W) frame, got shape {frame.shape}")
    gray = np.clip(frame, 0, 255).round().astype(np.uint8)
    corners = cv2.goodFeaturesToTrack(gray, count, quality, min_distance)
    if corners is None:
        raise InputError("no good features to track in the first frame (is it blank?)")
    return corners.reshape(-1, 2).astype(np.float64)

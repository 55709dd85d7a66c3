"""OpenCV's pyramidal Lucas-Kanade tracker (KLT), the thesis's baseline: ``cv2.calcOpticalFlowPyrLK`` with a
21x21 window and 3 levels (``maxLevel=2``), frame to frame, lost points dropped."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from core.errors import InputError


def klt_track(
    frames: Sequence[np.ndarray], points: np.ndarray, window: int = 21, levels: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """Track ``(P, 2)`` (x, y) points through uint8 gray frames ``(H, W)``.

    Returns:
        tracks ``(T, P, 2)`` float64 (lost points keep their last position) and lost ``(T, P)`` (status 0 or
        outside the image).
    """
    points = np.asarray(points, dtype=np.float32)
    if points.ndim != 2 or points.shape[1] != 2:
        raise InputError(f"points must have shape (P, 2), got {points.shape}")
    if len(points) == 0:
        raise InputError("the point set is empty: nothing to track")
    h, w = frames[0].shape
    pos = points.copy()
    lost = ~((pos[:, 0] >= 0) & (pos[:, 0] <= w - 1) & (pos[:, 1] >= 0) & (pos[:, 1] <= h - 1))
    tracks, losts = [pos.astype(np.float64)], [lost.copy()]
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)
    for t in range(1, len(frames)):
        if frames[t].shape != (h, w):
            raise InputError(f"frame {t} has size {frames[t].shape}, frame 0 has {(h, w)}")
        idx = np.flatnonzero(~lost)
        if len(idx):
            new, status, _ = cv2.calcOpticalFlowPyrLK(
                frames[t - 1],
                frames[t],
                pos[idx, None],
                None,
                winSize=(window, window),
                maxLevel=levels - 1,
                criteria=criteria,
            )
            new = new.reshape(-1, 2)
            ok = (status.ravel() == 1) & (new[:, 0] >= 0) & (new[:, 0] <= w - 1)
            ok &= (new[:, 1] >= 0) & (new[:, 1] <= h - 1)
            pos[idx[ok]] = new[ok]
            lost[idx[~ok]] = True
        tracks.append(pos.astype(np.float64))
        losts.append(lost.copy())
    return np.stack(tracks), np.stack(losts)

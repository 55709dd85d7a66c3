"""Ground-truth point tracks from dense flow (thesis 3.4): move detected points by the bilinearly sampled
flow, chained over frames, and drop points that are occluded, invalid, leave the image or sit where the flow
diverges in their neighbourhood (motion boundaries).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from core.errors import InputError


def sample_bilinear(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear samples of a ``(H, W)`` or ``(H, W, C)`` array at ``(P, 2)`` (x, y) pixel positions (pixel
    centres at integers); positions outside the image are clamped to the border."""
    img = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float64))
    img = img[None, None] if img.dim() == 2 else img.permute(2, 0, 1)[None]
    h, w = image.shape[:2]
    pts = torch.from_numpy(np.asarray(points, dtype=np.float64))
    grid = torch.stack([(2 * pts[:, 0] + 1) / w - 1, (2 * pts[:, 1] + 1) / h - 1], -1)
    out = F.grid_sample(img, grid[None, None], mode="bilinear", padding_mode="border", align_corners=False)
    out = out[0, :, 0].T.numpy()
    return out[:, 0] if image.ndim == 2 else out


def divergent_flow_mask(flow: np.ndarray, radius: int = 3, threshold: float = 1.0) -> np.ndarray:
    """``(H, W)`` True where either flow component varies by more than ``threshold`` px (max - min) within the
    ``(2 radius + 1)^2`` neighbourhood, or where the neighbourhood has unknown flow."""
    f = torch.from_numpy(np.nan_to_num(flow, nan=1e6).transpose(2, 0, 1)[None].astype(np.float32))
    k = 2 * radius + 1
    hi = F.max_pool2d(f, k, 1, radius)
    lo = -F.max_pool2d(-f, k, 1, radius)
    return ((hi - lo) > threshold).any(1)[0].numpy()


def tracks_from_flow(
    points: np.ndarray,
    flows: list[np.ndarray],
    bad: list[np.ndarray] | None = None,
    radius: int = 3,
    threshold: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Chain flows ``t -> t + 1`` from start points.

    Args:
        points: ``(P, 2)`` (x, y) start positions in frame 0.
        flows: T flows ``(H, W, 2)`` (frame t to t + 1); bad: optional ``(H, W)`` masks per flow
        (occluded/invalid).
        radius, threshold: divergence test (:func:`divergent_flow_mask`).
    Returns:
        tracks ``(T + 1, P, 2)`` and valid ``(T + 1, P)``; a track stays invalid once it fails a test.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise InputError(f"points must have shape (P, 2), got {points.shape}")
    tracks = [points]
    valid = [np.ones(len(points), dtype=bool)]
    for t, flow in enumerate(flows):
        h, w = flow.shape[:2]
        p = tracks[-1]
        ok = valid[-1] & (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)
        mask = divergent_flow_mask(flow, radius, threshold)
        if bad is not None:
            mask = mask | np.asarray(bad[t], dtype=bool)
        ok &= sample_bilinear(mask.astype(np.float32), p) == 0
        move = sample_bilinear(np.nan_to_num(flow, nan=0.0), p)
        q = p + move
        ok &= (
            np.isfinite(q).all(1) & (q[:, 0] >= 0) & (q[:, 0] <= w - 1) & (q[:, 1] >= 0) & (q[:, 1] <= h - 1)
        )
        tracks.append(q)
        valid.append(ok)
    return np.stack(tracks), np.stack(valid)

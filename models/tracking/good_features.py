"""Good features to track (Shi and Tomasi 1994): minimum-eigenvalue corner response, non-maximum suppression
in a window of ``min_distance`` pixels, a quality threshold relative to the best corner, strongest first.

The benchmark's start points (``bench/point_tracking.py``; its recorded figures use them). The window suppression
keeps fewer corners than OpenCV's distance rule; ``infer.py track`` and the runtime detect with OpenCV
(:func:`core.good_features.good_features`).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from kornia.feature import gftt_response
from torch import Tensor, nn


def good_features_to_track(
    frame: Tensor, max_points: int, quality: float = 0.01, min_distance: int = 5, border: int = 4
) -> Tensor:
    """Detect corners in one gray frame.

    Args:
        frame: ``(H, W)`` gray image (any range).
        max_points: at most this many corners (strongest first).
        quality: keep responses above ``quality`` times the largest response.
        min_distance: suppression radius in pixels (no two corners closer than this in either axis).
        border: ignore this many pixels at the image border.
    Returns:
        ``(P, 2)`` corner positions (x, y) in pixels, ``P <= max_points``.
    """
    if frame.dim() != 2 or min(frame.shape) < 2 * border + 3:
        raise ValueError(f"frame must be a 2-D image larger than the border, got shape {tuple(frame.shape)}")
    if max_points < 1:
        raise ValueError(f"max_points must be positive, got {max_points}")
    image = frame.float()[None, None]
    image = image / image.abs().amax().clamp_min(1e-12)
    response = gftt_response(image)[0, 0]
    k = 2 * min_distance + 1
    local_max = F.max_pool2d(response[None, None], k, 1, min_distance)[0, 0]
    keep = (response >= local_max) & (response > quality * response.max()) & (response > 0)
    keep[:border] = False
    keep[-border:] = False
    keep[:, :border] = False
    keep[:, -border:] = False
    ys, xs = torch.nonzero(keep, as_tuple=True)
    order = response[ys, xs].argsort(descending=True)[:max_points]
    return torch.stack([xs[order], ys[order]], -1).to(
        frame.dtype if frame.is_floating_point() else torch.float32
    )


class GoodFeaturesToTrack(nn.Module):
    """Module form of :func:`good_features_to_track`."""

    def __init__(self, max_points: int = 1000, quality: float = 0.01, min_distance: int = 5) -> None:
        super().__init__()
        self.max_points, self.quality, self.min_distance = max_points, quality, min_distance

    def forward(self, frame: Tensor) -> Tensor:
        return good_features_to_track(frame, self.max_points, self.quality, self.min_distance)

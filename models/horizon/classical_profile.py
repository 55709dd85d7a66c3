"""A classical (not learned, DEM-free) horizon profile extractor for localisation.

The classical label maker of ``data.horizon.classical`` needs the GPS position (it fits the DEM's virtual
horizon to the image), so its profiles cannot be used to find the position. This extractor uses only the image:
Canny edges and Hough voting for pitch and roll (``hough_tilt``, ch. 4.2), the levelling warp, then in each
column of the levelled panorama the sky boundary = the strongest downward brightness drop (bright sky above,
darker land or sea below) above the sea horizon's row band, refined to sub-pixel by a parabola.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor

from core.cylinder import panorama_focal, row_to_tangent, warp_panorama
from core.errors import InputError
from core.raycast import effective_radius
from data.horizon.classical import edge_distance, hough_tilt


def classical_profile(
    image: Tensor, camera_height: Tensor | float = 2.0, max_tilt_deg: float = 10.0, below_px: float = 3.0
) -> tuple[Tensor, Tensor, Tensor]:
    """Horizon profiles of tilted panoramas without networks or DEM.

    Args:
        image: (B, 3, H, W) tilted 360-degree panoramas in [0, 1], column 0 forward.
        camera_height: metres above the sea, scalar or (B,) (for the sea-horizon dip).
        max_tilt_deg: largest pitch/roll searched.
        below_px: the boundary is searched above the sea horizon's row plus this many pixels.
    Returns:
        profile (B, W) tan elevation per levelled column (column u at heading + 2 pi u / W), pitch (B,), roll (B,).
    """
    if image.ndim != 4 or image.shape[1] != 3:
        raise InputError(f"panorama must be (B, 3, H, W), got shape {tuple(image.shape)}")
    batch, _, height, width = image.shape
    dtype = image.dtype
    h_c = torch.as_tensor(camera_height, dtype=torch.float64).expand(batch)
    dip = torch.sqrt(2 * h_c / effective_radius())
    edges, _ = edge_distance(image)
    pitch, roll, _ = hough_tilt(edges, dip, math.radians(max_tilt_deg))
    level = warp_panorama(image, pitch.to(dtype), roll.to(dtype))
    gray = F.avg_pool2d(level.mean(1, keepdim=True), (1, 3), stride=1, padding=(0, 1))[:, 0]  # (B, H, W)
    drop = gray[:, :-1] - gray[:, 1:]  # boundary between rows v and v + 1
    sea_row = (height - 1) / 2.0 + dip.to(dtype)[:, None] * panorama_focal(width)  # (B, 1)
    boundary = torch.arange(height - 1, dtype=dtype) + 0.5
    allowed = boundary[None, :, None] <= (sea_row + below_px)[:, :, None]
    drop = torch.where(allowed, drop, torch.full_like(drop, -math.inf))
    best = drop.argmax(1)  # (B, W)
    centre = drop.gather(1, best[:, None])[:, 0]
    up = drop.gather(1, (best - 1).clamp(min=0)[:, None])[:, 0]
    down = drop.gather(1, (best + 1).clamp(max=height - 2)[:, None])[:, 0]
    curvature = up - 2 * centre + down
    ok = torch.isfinite(curvature) & (curvature < 0)
    delta = torch.where(ok, 0.5 * (up - down) / torch.where(ok, curvature, -torch.ones_like(curvature)), 0.0)
    row = best.to(dtype) + 0.5 + delta.clamp(-0.5, 0.5)
    return row_to_tangent(row, height, width), pitch, roll

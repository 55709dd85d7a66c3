"""The classical horizon pipeline of ch. 4.2 (after Grelsson), used as the label maker for the networks.

1. ``edge_distance``: Canny edges of the panorama and their distance transform D (OpenCV, one image at a time;
   the panorama is padded around in azimuth so edges and distances wrap).
2. ``hough_tilt``: Hough voting for pitch and roll. A level circle seen by the tilted cylinder is the S-curve
   ``t = -A cos(psi) + B sin(psi) - delta`` (``A = tan p / cos q``, ``B = tan q``, delta = tan of the sea-horizon
   dip), so every edge pixel votes along a line in the (A, B) accumulator; the peak is refined by least squares
   on the edge pixels near its curve.
3. ``refine_pose``: eq. 4.1. The virtual horizon (and water line) ray-cast from the DEM at the GPS position is
   projected into the image, ``R(psi) pi(R(theta, phi) pi^-1(h_i))``, and ``sum_i min(D, tau)**2`` is minimised
   over pitch, roll and heading: a heading scan around the compass at the Hough tilt, then a batched pattern
   search (derivative-free, which suits the piecewise-linear distance transform) on all three angles.
4. Labels: pitch, roll, heading, and the horizon and water profiles of the levelled panorama (the virtual
   profiles at the fitted heading), with a fit quality (share of projected horizon points on an edge, above
   chance); fits below ``min_quality`` are flagged as failed so the dataset can reject them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from core.cylinder import (
    column_azimuths,
    interp_profile,
    level_to_tilted,
    panorama_focal,
    row_tangents,
    tangent_to_row,
)
from core.errors import InputError
from core.raycast import VirtualHorizon, effective_radius


@dataclass
class ClassicalLabels:
    """Output of the classical pipeline for B panoramas of width W.

    Attributes:
        pitch, roll, heading: (B,) fitted angles in rad.
        horizon, water: (B, W) tan elevation of the horizon and water profiles per levelled column
            (column u at azimuth heading + 2 pi u / W).
        horizon_rows, water_rows: (B, W) their rows in the levelled panorama.
        hough_pitch, hough_roll: (B,) the Hough estimates before the eq. 4.1 refinement, rad.
        inlier_ratio: (B,) share of projected virtual horizon points within ``inlier_px`` of an edge.
        quality: (B,) inlier ratio above chance, ``(inlier_ratio - c) / (1 - c)`` with c the inlier ratio of
            the same profile displaced 4-8 px up or down (high in edge clutter, e.g. noise).
        ok: (B,) bool, the fit is accepted (``quality >= min_quality``).
    """

    pitch: torch.Tensor
    roll: torch.Tensor
    heading: torch.Tensor
    horizon: torch.Tensor
    water: torch.Tensor
    horizon_rows: torch.Tensor
    water_rows: torch.Tensor
    hough_pitch: torch.Tensor
    hough_roll: torch.Tensor
    inlier_ratio: torch.Tensor
    quality: torch.Tensor
    ok: torch.Tensor


def edge_distance(
    image: torch.Tensor, low: float = 20.0, high: float = 50.0, sigma: float = 1.0
) -> tuple[torch.Tensor, torch.Tensor]:
    """Canny edges and the Euclidean distance transform to the nearest edge.

    Args:
        image: (B, 3, H, W) RGB or (B, 1, H, W) gray panorama in [0, 1].
        low, high: Canny hysteresis thresholds on the L2 Sobel magnitude of the 8-bit gray image.
        sigma: Gaussian pre-blur in px (0 = none).

    Returns:
        edges (B, H, W) bool and distance (B, H, W) float32 px, wrapping around in azimuth.
    """
    if image.ndim != 4 or image.shape[1] not in (1, 3):
        raise InputError(f"panorama must be (B, 3 or 1, H, W), got shape {tuple(image.shape)}")
    gray = image.mean(1) if image.shape[1] == 3 else image[:, 0]
    gray = (gray.detach().float().clamp(0, 1) * 255).round().to(torch.uint8).cpu().numpy()
    width = gray.shape[-1]
    pad = min(32, width)
    edges, distances = [], []
    for frame in gray:  # OpenCV: one image at a time
        padded = np.concatenate([frame[:, -pad:], frame, frame[:, :pad]], axis=1)
        if sigma > 0:
            padded = cv2.GaussianBlur(padded, (0, 0), sigma)
        edge = cv2.Canny(padded, low, high, L2gradient=True)[:, pad : pad + width]
        wrapped = np.concatenate([edge[:, -pad:], edge, edge[:, :pad]], axis=1)
        distance = cv2.distanceTransform((wrapped == 0).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        edges.append(edge > 0)
        distances.append(distance[:, pad : pad + width])
    device = image.device
    return torch.from_numpy(np.stack(edges)).to(device), torch.from_numpy(np.stack(distances)).to(device)


def hough_tilt(
    edges: torch.Tensor,
    dip: torch.Tensor,
    max_tilt: float = math.radians(10.0),
    bins: int = 101,
    refine_px: tuple[float, ...] = (2.0, 1.0, 0.7),
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Pitch and roll from edge pixels by Hough voting for the S-curve, refined by least squares.

    Args:
        edges: (B, H, W) bool edge map of the tilted panorama.
        dip: (B,) tan of the sea-horizon dip (the horizon lies this far below the level circle).
        max_tilt: largest |A|, |B| searched (tan units, about the tilt in rad).
        bins: accumulator bins per axis.
        refine_px: inlier tolerances (px) of the successive least-squares refinements.

    Returns:
        pitch (B,), roll (B,) in rad and the number of inlier edge pixels (B,).
    """
    batch, height, width = edges.shape
    f = panorama_focal(width)
    device = edges.device
    dtype = torch.float64
    b_idx, v, u = edges.nonzero(as_tuple=True)
    psi = column_azimuths(width, dtype, device)[u]
    t = row_tangents(height, width, dtype, device)[v] + dip.to(dtype)[b_idx]
    keep = t.abs() <= max_tilt * 1.1
    b_idx, psi, t = b_idx[keep], psi[keep], t[keep]
    cos, sin = torch.cos(psi), torch.sin(psi)
    grid = torch.linspace(-max_tilt, max_tilt, bins, dtype=dtype, device=device)
    scale = (bins - 1) / (2 * max_tilt)
    accumulator = torch.zeros(batch * bins * bins, dtype=dtype, device=device)

    def vote(image: torch.Tensor, free: torch.Tensor, a_is_fixed: bool) -> None:
        free_index = ((free + max_tilt) * scale).round()  # (P, bins) nearest bin of the solved parameter
        inside = (free_index >= 0) & (free_index <= bins - 1)
        fixed_index = torch.arange(bins, device=device).expand_as(free_index)
        free_index = free_index.long().clamp(0, bins - 1)
        a_index, b_index = (fixed_index, free_index) if a_is_fixed else (free_index, fixed_index)
        flat = (image[:, None] * bins + a_index) * bins + b_index
        accumulator.index_add_(0, flat[inside], torch.ones_like(free)[inside])

    steep = sin.abs() >= cos.abs()
    # B = (t + A cos psi) / sin psi for each A-bin, or A = (B sin psi - t) / cos psi for each B-bin.
    vote(b_idx[steep], (t[steep, None] + grid * cos[steep, None]) / sin[steep, None], True)
    level = ~steep
    vote(b_idx[level], (grid * sin[level, None] - t[level, None]) / cos[level, None], False)
    accumulator = accumulator.reshape(batch, 1, bins, bins)
    accumulator = F.avg_pool2d(accumulator, 3, stride=1, padding=1)
    peak = accumulator.reshape(batch, -1).argmax(-1)
    a = grid[peak // bins]
    b = grid[peak % bins]
    c = torch.zeros_like(a)
    count = torch.zeros(batch, dtype=torch.long, device=device)
    design = torch.stack([-cos, sin, torch.ones_like(cos)], -1)  # (P, 3)
    for tol in refine_px:
        residual = t - (design * torch.stack([a, b, c], -1)[b_idx]).sum(-1)
        inlier = (residual.abs() <= tol / f).to(dtype)
        # Per-image normal equations (3 x 3), solved in closed form for the batch.
        weighted = design * inlier[:, None]
        normal = torch.zeros(batch, 3, 3, dtype=dtype, device=device).index_add_(
            0, b_idx, weighted[:, :, None] * design[:, None, :]
        )
        rhs = torch.zeros(batch, 3, dtype=dtype, device=device).index_add_(0, b_idx, weighted * t[:, None])
        count = torch.zeros(batch, dtype=dtype, device=device).index_add_(0, b_idx, inlier).long()
        solvable = count >= 10
        normal = torch.where(solvable[:, None, None], normal, torch.eye(3, dtype=dtype, device=device))
        solution = torch.linalg.solve(normal, rhs)
        a = torch.where(solvable, solution[:, 0], a)
        b = torch.where(solvable, solution[:, 1], b)
        c = torch.where(solvable, solution[:, 2], c)
    roll = torch.atan(b)
    pitch = torch.atan(a * torch.cos(roll))
    return pitch, roll, count


def _sample_distance(distance: torch.Tensor, u: torch.Tensor, v: torch.Tensor, tau: float) -> torch.Tensor:
    """Bilinear distance-transform values (B, H, W) at (B, N) pixel positions; tau outside the rows."""
    batch, height, width = distance.shape
    padded = torch.cat([distance, distance[..., :1]], dim=-1)[:, None]  # wrap one column
    u = torch.remainder(u, width)
    grid = torch.stack([u / width * 2 - 1, v / (height - 1) * 2 - 1], -1)[:, None]
    values = F.grid_sample(padded.to(u.dtype), grid, mode="bilinear", padding_mode="border", align_corners=True)
    values = values[:, 0, 0]
    return torch.where((v < 0) | (v > height - 1), torch.full_like(values, tau), values)


def projection_cost(
    distance: torch.Tensor,
    points_psi: torch.Tensor,
    points_t: torch.Tensor,
    weights: torch.Tensor,
    angles: torch.Tensor,
    tau: float = 3.0,
) -> torch.Tensor:
    """Eq. 4.1 cost of candidate poses: mean over virtual points of min(D, tau)**2.

    Args:
        distance: (B, H, W) distance transform of the edges in px.
        points_psi, points_t: (B, N) world azimuth (rad, clockwise from north) and tan elevation of the
            virtual horizon / water points.
        weights: (B, N) point weights (0 = unused).
        angles: (B, K, 3) candidate (pitch, roll, heading) in rad.
        tau: truncation in px.

    Returns:
        (B, K) costs.
    """
    batch, height, width = distance.shape
    k = angles.shape[1]
    psi = (points_psi[:, None] - angles[..., 2:3]).reshape(batch * k, -1)
    t = points_t[:, None].expand(batch, k, -1).reshape(batch * k, -1)
    psi_cam, t_cam = level_to_tilted(psi, t, angles[..., 0].reshape(-1), angles[..., 1].reshape(-1))
    u = psi_cam * (width / (2 * math.pi))
    v = tangent_to_row(t_cam, height, width)
    d = _sample_distance(distance, u.reshape(batch, -1), v.reshape(batch, -1), tau).reshape(batch, k, -1)
    return (d.clamp(max=tau) ** 2 * weights[:, None]).sum(-1) / weights.sum(-1, keepdim=True).clamp(min=1)


def refine_pose(
    distance: torch.Tensor,
    points_psi: torch.Tensor,
    points_t: torch.Tensor,
    weights: torch.Tensor,
    pitch: torch.Tensor,
    roll: torch.Tensor,
    compass: torch.Tensor,
    heading_search: float = math.radians(8.0),
    heading_step: float = math.radians(0.25),
    start_step: float = math.radians(0.25),
    iterations: int = 40,
    tau: float = 3.0,
) -> torch.Tensor:
    """Minimise eq. 4.1 over (pitch, roll, heading) from the Hough tilt and the compass heading.

    A scan of headings within ``heading_search`` of the compass at the Hough tilt, then a batched compass
    (pattern) search: try +-s on each angle, move to the best improvement, halve s when none improves.

    Returns:
        (B, 3) fitted (pitch, roll, heading) in rad.
    """
    dtype = points_t.dtype
    scan = torch.arange(-heading_search, heading_search + 1e-12, heading_step, dtype=dtype, device=distance.device)
    candidates = torch.stack(
        [pitch[:, None].expand(-1, len(scan)), roll[:, None].expand(-1, len(scan)), compass[:, None] + scan], -1
    )
    cost = projection_cost(distance, points_psi, points_t, weights, candidates, tau)
    current = candidates[torch.arange(len(pitch)), cost.argmin(-1)]
    eye = torch.eye(3, dtype=dtype, device=distance.device)
    moves = torch.cat([torch.zeros(1, 3, dtype=dtype, device=distance.device), eye, -eye])  # centre first
    centre = 0
    step = torch.full((len(pitch), 1), start_step, dtype=dtype, device=distance.device)
    for _ in range(iterations):
        trial = current[:, None] + moves[None] * step[:, :, None]
        cost = projection_cost(distance, points_psi, points_t, weights, trial, tau)
        best = cost.argmin(-1)
        stay = cost[:, centre] <= cost.gather(1, best[:, None])[:, 0]
        current = torch.where(stay[:, None], current, trial[torch.arange(len(pitch)), best])
        step = torch.where(stay[:, None], step / 2, step)
    return current


class ClassicalHorizon(nn.Module):
    """Canny + Hough + eq. 4.1 label maker over a DEM (see the module docstring).

    Args:
        caster: ray caster over the DEM; its ``bins`` is the number of virtual horizon points.
        canny_low, canny_high, canny_sigma: edge detector settings (see ``edge_distance``).
        max_tilt_deg: largest pitch/roll searched by the Hough transform, degrees.
        heading_search_deg: compass error covered by the heading scan, degrees.
        tau_px: truncation of the distance cost, px.
        inlier_px: distance counting a projected horizon point as on an edge, px.
        min_quality: least fit quality (inlier ratio above chance) of an accepted fit.
    """

    def __init__(
        self,
        caster: VirtualHorizon,
        canny_low: float = 20.0,
        canny_high: float = 50.0,
        canny_sigma: float = 1.0,
        max_tilt_deg: float = 10.0,
        heading_search_deg: float = 8.0,
        tau_px: float = 3.0,
        inlier_px: float = 1.5,
        min_quality: float = 0.5,
    ) -> None:
        super().__init__()
        self.caster = caster
        self.canny = (canny_low, canny_high, canny_sigma)
        self.max_tilt = math.radians(max_tilt_deg)
        self.heading_search = math.radians(heading_search_deg)
        self.tau, self.inlier_px, self.min_quality = tau_px, inlier_px, min_quality

    def forward(
        self, image: torch.Tensor, positions: torch.Tensor, camera_height: torch.Tensor, compass: torch.Tensor
    ) -> ClassicalLabels:
        """Labels for tilted panoramas.

        Args:
            image: (B, 3, H, W) panoramas in [0, 1], column 0 along the camera's forward axis.
            positions: (B, 2) GPS positions in metres (DEM coordinates).
            camera_height: (B,) camera height above the sea in metres.
            compass: (B,) compass heading of the forward axis in rad (clockwise from north).
        """
        if image.ndim != 4 or image.shape[1] != 3:
            raise InputError(f"panorama must be (B, 3, H, W), got shape {tuple(image.shape)}")
        batch, _, height, width = image.shape
        if positions.shape != (batch, 2) or camera_height.shape != (batch,) or compass.shape != (batch,):
            raise InputError(
                f"positions (B, 2), camera_height (B,) and compass (B,) must match B = {batch}, got "
                f"{tuple(positions.shape)}, {tuple(camera_height.shape)}, {tuple(compass.shape)}"
            )
        dtype = torch.float64
        device = image.device
        camera_height = camera_height.to(dtype=dtype, device=device)
        edges, distance = edge_distance(image, *self.canny)
        dip = torch.sqrt(2 * camera_height / effective_radius(self.caster.k, self.caster.earth_radius))
        pitch0, roll0, _ = hough_tilt(edges, dip, self.max_tilt)

        profiles = self.caster(positions.to(self.caster.heights), camera_height.to(self.caster.heights))
        horizon, water = profiles.horizon.to(dtype), profiles.water.to(dtype)
        bins = horizon.shape[1]
        psi = column_azimuths(bins, dtype, device)[None].expand(batch, bins)
        f = panorama_focal(width)
        has_water_line = (horizon - water) > 1.0 / f  # land base visible apart from the horizon
        points_psi = torch.cat([psi, psi], 1)
        points_t = torch.cat([horizon, water], 1)
        weights = torch.cat([torch.ones_like(horizon), has_water_line.to(dtype)], 1)
        angles = refine_pose(distance.to(dtype), points_psi, points_t, weights, pitch0, roll0,
                             compass.to(dtype=dtype, device=device), self.heading_search, tau=self.tau)

        pitch, roll, heading = angles.unbind(-1)
        psi_cam, t_cam = level_to_tilted(psi - heading[:, None], horizon, pitch, roll)
        u, v = psi_cam * (width / (2 * math.pi)), tangent_to_row(t_cam, height, width)
        d = _sample_distance(distance.to(dtype), u, v, self.tau)
        inlier_ratio = (d <= self.inlier_px).to(dtype).mean(-1)
        # Chance level: the same profile displaced vertically also lands on edges in cluttered images.
        offsets = torch.tensor([-8.0, -6.0, -4.0, 4.0, 6.0, 8.0], dtype=dtype, device=device)
        shifted = _sample_distance(
            distance.to(dtype), u.repeat(1, len(offsets)), (v[:, None] + offsets[:, None]).reshape(batch, -1),
            self.tau,
        )
        chance = (shifted <= self.inlier_px).to(dtype).mean(-1)
        quality = (inlier_ratio - chance) / (1 - chance).clamp(min=1e-6)

        level_psi = column_azimuths(width, dtype, device)[None] + heading[:, None]
        level_h = interp_profile(horizon, level_psi)
        level_w = interp_profile(water, level_psi)
        return ClassicalLabels(
            pitch=pitch, roll=roll, heading=torch.remainder(heading, 2 * math.pi), horizon=level_h, water=level_w,
            horizon_rows=tangent_to_row(level_h, height, width), water_rows=tangent_to_row(level_w, height, width),
            hough_pitch=pitch0, hough_roll=roll0, inlier_ratio=inlier_ratio, quality=quality,
            ok=quality >= self.min_quality,
        )


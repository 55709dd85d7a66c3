"""Virtual horizons by batched ray casting through a DEM, with curvature and refraction (ch. 4.2, fig. 4.3).

From a camera at height ``h_c`` above the sea, a point at ground distance d and height z is seen at
``tan(theta) = (z - h_c - d**2 / (2 R_eff)) / d`` with ``R_eff = R / (1 - k)`` (R = 6371 km, refraction
k = 0.13). Along each azimuth psi (clockwise from north, bin j at psi = 2 pi j / bins) the horizon profile is
the highest such value, ``h(psi) = max_d tan(theta)``; open sea gives the sea horizon
``-tan(dip) = -sqrt(2 h_c / R_eff)``.
The water profile is where sea meets land: the first shore along the ray at distance d_s (where the bilinearly
interpolated land indicator, 1 on cells higher than ``shore_height``, crosses 1/2) is seen at
``(-h_c - d_s**2 / (2 R_eff)) / d_s`` when it lies before the sea horizon (d_s < sqrt(2 R_eff h_c)), otherwise
(and with no land in range) the sea horizon hides it and the water profile equals the sea horizon.

Heights between cell centres are bilinear; outside the DEM is sea. Samples lie at d = step, 2 step, ..
max_range; the shore crossing is interpolated linearly between the last sea and the first land sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import nn

from core.errors import InputError

EARTH_RADIUS_M = 6371e3
REFRACTION_K = 0.13


def effective_radius(k: float = REFRACTION_K, earth_radius: float = EARTH_RADIUS_M) -> float:
    """Earth radius bent by refraction coefficient k: R / (1 - k) metres (7323 km for k = 0.13)."""
    return earth_radius / (1.0 - k)


def curvature_drop(
    distance: torch.Tensor | float, k: float = REFRACTION_K, earth_radius: float = EARTH_RADIUS_M
) -> torch.Tensor | float:
    """Apparent drop d**2 / (2 R_eff) in metres of a point at ground distance ``distance`` metres."""
    return distance**2 / (2.0 * effective_radius(k, earth_radius))


@dataclass
class HorizonProfiles:
    """Output of ``virtual_horizon``; all (B, bins), bin j at azimuth 2 pi j / bins clockwise from north.

    Attributes:
        horizon: tan of the highest elevation angle (sky above).
        water: tan of the elevation angle where sea meets land (sea below); equals ``horizon`` over open sea.
        horizon_distance: ground distance in metres of the point forming the horizon.
        shore_distance: distance in metres of the first shore along the ray (inf when none within range).
    """

    horizon: torch.Tensor
    water: torch.Tensor
    horizon_distance: torch.Tensor
    shore_distance: torch.Tensor


def virtual_horizon(
    heights: torch.Tensor,
    x0: float,
    y0: float,
    cell: float,
    positions: torch.Tensor,
    camera_height: torch.Tensor | float,
    bins: int,
    max_range: float = 8000.0,
    step: float | None = None,
    k: float = REFRACTION_K,
    earth_radius: float = EARTH_RADIUS_M,
    shore_height: float = 0.0,
    chunk_samples: int = 2**24,
) -> HorizonProfiles:
    """Horizon and water profiles seen from ``positions`` by ray casting through a DEM.

    Args:
        heights: (H, W) DEM heights in metres (sea = 0), row 0 north; its dtype and device are used.
        x0, y0: north-west corner of the DEM in metres; cell (r, c) is centred at
            (x0 + (c + 0.5) cell, y0 - (r + 0.5) cell).
        cell: DEM cell size in metres.
        positions: (B, 2) camera positions (x east, y north) in metres.
        camera_height: camera height above the sea in metres, scalar or (B,); must be > 0.
        bins: number of azimuth bins over 360 degrees.
        max_range: longest ray in metres.
        step: distance between samples along a ray in metres (default: half a cell).
        k: refraction coefficient; R_eff = earth_radius / (1 - k).
        earth_radius: in metres.
        shore_height: ground above this height (m) counts as land for the water profile.
        chunk_samples: rays are processed in chunks of about this many samples (memory bound).

    Returns:
        ``HorizonProfiles`` with (B, bins) tensors.
    """
    if heights.ndim != 2:
        raise InputError(f"DEM heights must be (H, W), got shape {tuple(heights.shape)}")
    if positions.ndim != 2 or positions.shape[-1] != 2:
        raise InputError(f"positions must be (B, 2) metres, got shape {tuple(positions.shape)}")
    if bins < 1 or max_range <= 0:
        raise InputError(f"bins ({bins}) and max_range ({max_range}) must be positive")
    dtype, device = heights.dtype, heights.device
    batch = positions.shape[0]
    positions = positions.to(dtype=dtype, device=device)
    h_c = torch.as_tensor(camera_height, dtype=dtype, device=device).expand(batch).reshape(batch, 1)
    if (h_c <= 0).any():
        raise InputError("camera_height must be > 0 m above the sea")
    step = cell / 2.0 if step is None else step
    r_eff = effective_radius(k, earth_radius)
    samples = max(int(math.ceil(max_range / step)), 1)
    distance = step * torch.arange(1, samples + 1, dtype=dtype, device=device)  # (S,)
    drop = distance**2 / (2.0 * r_eff)
    psi = 2.0 * math.pi * torch.arange(bins, dtype=dtype, device=device) / bins
    east, north = torch.sin(psi), torch.cos(psi)
    rows, cols = heights.shape
    # Heights and the land indicator as two channels, sampled together (zeros outside = sea).
    fields = torch.stack([heights, (heights > shore_height).to(dtype)])[None]
    # Ray samples in grid_sample's normalised coordinates (align_corners: -1 and 1 at the outer cell centres).
    gx0 = ((positions[:, 0] - x0) / cell - 0.5) * (2.0 / (cols - 1)) - 1.0  # (B,)
    gy0 = ((y0 - positions[:, 1]) / cell - 0.5) * (2.0 / (rows - 1)) - 1.0
    gx_step = east * (2.0 / ((cols - 1) * cell))  # (bins,) per metre
    gy_step = -north * (2.0 / ((rows - 1) * cell))
    sea_tan = -torch.sqrt(2.0 * h_c / r_eff)  # (B, 1)
    sea_distance = torch.sqrt(2.0 * r_eff * h_c)

    rays_per_chunk = max(chunk_samples // samples, 1)
    rays = torch.stack(torch.meshgrid(torch.arange(batch, device=device), torch.arange(bins, device=device),
                                      indexing="ij"), -1).reshape(-1, 2)
    horizon, horizon_d, shore_d = [], [], []
    for start in range(0, rays.shape[0], rays_per_chunk):
        b, j = rays[start : start + rays_per_chunk].unbind(-1)
        grid = torch.stack([gx0[b, None] + distance[None] * gx_step[j, None],
                            gy0[b, None] + distance[None] * gy_step[j, None]], -1)
        sampled = nn.functional.grid_sample(fields, grid[None], mode="bilinear", padding_mode="zeros",
                                            align_corners=True)[0]
        z, land = sampled[0], sampled[1]  # (R, S)
        tangent = (z - h_c[b] - drop) / distance
        best, index = tangent.max(dim=-1)
        horizon.append(best)
        horizon_d.append(distance[index])
        above = land > 0.5
        has_land = above.any(dim=-1)
        first = above.to(torch.uint8).argmax(dim=-1)
        after = land.gather(-1, first[:, None])[:, 0]
        before = torch.where(first > 0, land.gather(-1, (first - 1).clamp(min=0)[:, None])[:, 0], after * 0)
        frac = ((0.5 - before) / (after - before).clamp(min=1e-12)).clamp(0.0, 1.0)
        d = step * first.to(dtype) + step * frac  # distance of sample `first` is step * (first + 1)
        shore_d.append(torch.where(has_land, d, torch.full_like(d, math.inf)))
    horizon_t = torch.cat(horizon).reshape(batch, bins)
    horizon_dist = torch.cat(horizon_d).reshape(batch, bins)
    shore = torch.cat(shore_d).reshape(batch, bins)
    sea_wins = horizon_t < sea_tan
    horizon_t = torch.where(sea_wins, sea_tan.expand_as(horizon_t), horizon_t)
    horizon_dist = torch.where(sea_wins, sea_distance.expand_as(horizon_dist), horizon_dist)
    visible_shore = shore < sea_distance
    water = torch.where(visible_shore, (-h_c - shore**2 / (2.0 * r_eff)) / shore.clamp(min=step), sea_tan)
    return HorizonProfiles(horizon_t, torch.minimum(water, horizon_t), horizon_dist, shore)


class HeightMap(Protocol):
    """A north-up height grid: ``z`` (rows, cols) metres, its north-west corner at (``x0``, ``y0``) map metres,
    rows running south, square cells of ``cell`` metres (``data.world.dem.Dem`` is one)."""

    z: np.ndarray
    x0: float
    y0: float
    cell: float

    def check_positions(self, xy: np.ndarray, name: str = "position") -> None:
        """Raise ``InputError`` when a position (..., 2) lies outside the grid."""


class VirtualHorizon(nn.Module):
    """``virtual_horizon`` over a fixed DEM held as a buffer (moves with ``.to(device)``).

    Args:
        dem: the height grid (a ``data.world.dem.Dem``).
        bins, max_range, step, k, earth_radius, shore_height: as in ``virtual_horizon``.
    """

    def __init__(
        self,
        dem: HeightMap,
        bins: int = 2048,
        max_range: float = 8000.0,
        step: float | None = None,
        k: float = REFRACTION_K,
        earth_radius: float = EARTH_RADIUS_M,
        shore_height: float = 0.0,
    ) -> None:
        super().__init__()
        self.dem = dem
        self.register_buffer("heights", torch.from_numpy(np.ascontiguousarray(dem.z, dtype=np.float32)))
        self.bins, self.max_range, self.step = bins, max_range, step
        self.k, self.earth_radius, self.shore_height = k, earth_radius, shore_height

    def forward(self, positions: torch.Tensor, camera_height: torch.Tensor | float) -> HorizonProfiles:
        """Profiles (B, bins) from positions (B, 2) metres; positions outside the DEM raise ``InputError``."""
        if positions.ndim != 2 or positions.shape[-1] != 2:
            raise InputError(f"positions must be (B, 2) metres, got shape {tuple(positions.shape)}")
        self.dem.check_positions(positions.detach().cpu().numpy())
        return virtual_horizon(
            self.heights, self.dem.x0, self.dem.y0, self.dem.cell, positions, camera_height, self.bins,
            self.max_range, self.step, self.k, self.earth_radius, self.shore_height,
        )

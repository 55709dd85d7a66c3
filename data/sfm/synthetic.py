"""The thesis's synthetic triangulation experiment: points in a cube seen by cameras on a circle (thesis 2.5)."""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import Tensor


class SyntheticScene(NamedTuple):
    """Cameras, noisy observations and ground truth of one synthetic scene.

    Attributes:
        cameras: (1, N, 3, 4) camera matrices ``K [R | -R C]`` shared by all points (``w > 0`` in front).
        observations: (B, N, 2) noisy image points in px (origin at the top-left pixel centre).
        points: (B, 3) true 3D points.
        clean: (B, N, 2) noise-free projections in px.
        intrinsics: (3, 3) the calibration matrix K shared by all cameras.
    """

    cameras: Tensor
    observations: Tensor
    points: Tensor
    clean: Tensor
    intrinsics: Tensor


def look_at_camera(center: Tensor, K: Tensor) -> Tensor:
    """Camera matrix ``K [R | -R C]`` (3, 4) at ``center`` (3,) looking at the origin, world y axis up."""
    z = -center / center.norm()
    up = torch.tensor([0.0, 1.0, 0.0], dtype=center.dtype)
    x = torch.linalg.cross(up, z)
    x = x / x.norm()
    y = torch.linalg.cross(z, x)
    R = torch.stack((x, y, z))
    return K @ torch.cat((R, (-R @ center).unsqueeze(-1)), dim=-1)


def synthetic_cube_scene(
    num_points: int,
    num_views: int = 3,
    noise_px: float = 1.0,
    seed: int = 0,
    radius: float = 5.0,
    angle_step: float = 0.3,
    focal: float = 1000.0,
    half_size: float = 1.0,
    dtype: torch.dtype = torch.float64,
) -> SyntheticScene:
    """Random points in the cube ``[-half_size, half_size]^3`` observed by ``num_views`` cameras.

    The cameras sit on a circle of ``radius`` in the x-z plane, ``angle_step`` rad apart and centred on the
    -z axis (three views: -0.3, 0, +0.3 rad), all looking at the origin, focal length ``focal`` px, 1000x1000
    images. Observations get i.i.d. N(0, noise_px^2) noise on both coordinates. Seeded and deterministic.
    """
    if num_points < 1 or num_views < 2:
        raise ValueError(f"need num_points >= 1 and num_views >= 2, got {num_points} and {num_views}")
    gen = torch.Generator().manual_seed(seed)
    angles = [angle_step * (i - (num_views - 1) / 2) for i in range(num_views)]
    centers = [torch.tensor([radius * math.sin(a), 0.0, -radius * math.cos(a)], dtype=torch.float64) for a in angles]
    K = torch.tensor([[focal, 0.0, 500.0], [0.0, focal, 500.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    P = torch.stack([look_at_camera(c, K) for c in centers]).unsqueeze(0)
    X = (torch.rand(num_points, 3, generator=gen, dtype=torch.float64) * 2 - 1) * half_size
    Xh = torch.cat((X, torch.ones(num_points, 1, dtype=torch.float64)), dim=-1)
    p = torch.einsum("nij,bj->bni", P[0], Xh)
    clean = p[..., :2] / p[..., 2:]
    noisy = clean + noise_px * torch.randn(clean.shape, generator=gen, dtype=torch.float64)
    return SyntheticScene(P.to(dtype), noisy.to(dtype), X.to(dtype), clean.to(dtype), K.to(dtype))

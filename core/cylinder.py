"""Geometry of 360-degree cylindrical panoramas: pixels, directions, camera tilt and levelling (ch. 4.2).

A panorama of width W and height H has focal length f = W / (2 pi) px/rad. Column u (pixel centres at integer
u, origin at the top-left pixel centre) looks at azimuth psi = 2 pi u / W, clockwise seen from above, from the
camera's forward axis; row v shows tan(elevation) t = (c - v) / f with c = (H - 1) / 2, so a horizon profile
h(psi) = tan(theta) is linear in rows.

Camera frame: x forward, y left, z up; a pixel's direction is (cos psi, -sin psi, t). The camera is tilted by
pitch p (nose up positive) and roll q (right side down positive): a camera direction d maps to the level frame
(x forward at the heading, z up) as ``R(p, q) d`` with ``R = R_y(-p) R_x(q)``. A level great circle (t_level = 0)
then appears as the S-curve ``t = -(tan p / cos q) cos psi + tan q sin psi`` (``s_curve``). The levelled panorama
has the same size; its column u is at level azimuth 2 pi u / W from the heading.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError


def panorama_focal(width: int) -> float:
    """Focal length W / (2 pi) in px/rad of a 360-degree cylindrical panorama of ``width`` pixels."""
    return width / (2.0 * math.pi)


def tilt_matrix(pitch: torch.Tensor, roll: torch.Tensor) -> torch.Tensor:
    """Camera-to-level rotation R_y(-pitch) R_x(roll). pitch, roll: (B,) rad; returns (B, 3, 3)."""
    cp, sp, cr, sr = torch.cos(pitch), torch.sin(pitch), torch.cos(roll), torch.sin(roll)
    one, zero = torch.ones_like(pitch), torch.zeros_like(pitch)
    r_y = torch.stack([cp, zero, -sp, zero, one, zero, sp, zero, cp], -1).reshape(-1, 3, 3)
    r_x = torch.stack([one, zero, zero, zero, cr, -sr, zero, sr, cr], -1).reshape(-1, 3, 3)
    return r_y @ r_x


def _rotate(psi: torch.Tensor, t: torch.Tensor, rotation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rotate cylinder points (psi, t) of shape (B, ...) by (B, 3, 3); returns (psi, t) in the new frame."""
    d = torch.stack([torch.cos(psi), -torch.sin(psi), t], -1)  # (B, ..., 3)
    shape = d.shape
    d = (d.reshape(shape[0], -1, 3) @ rotation.transpose(1, 2)).reshape(shape)
    horizontal = torch.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
    return torch.atan2(-d[..., 1], d[..., 0]), d[..., 2] / horizontal


def tilted_to_level(
    psi: torch.Tensor, t: torch.Tensor, pitch: torch.Tensor, roll: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Camera (psi, tan elevation) of shape (B, ...) to level (psi, tan elevation); pitch, roll (B,) rad."""
    return _rotate(psi, t, tilt_matrix(pitch, roll))


def level_to_tilted(
    psi: torch.Tensor, t: torch.Tensor, pitch: torch.Tensor, roll: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Level (psi, tan elevation) of shape (B, ...) to camera (psi, tan elevation); pitch, roll (B,) rad."""
    return _rotate(psi, t, tilt_matrix(pitch, roll).transpose(1, 2))


def s_curve(psi: torch.Tensor, pitch: torch.Tensor, roll: torch.Tensor) -> torch.Tensor:
    """tan elevation in the tilted camera of the level great circle at camera azimuths psi (B, N); (B, N)."""
    pitch, roll = pitch[:, None], roll[:, None]
    return -torch.tan(pitch) / torch.cos(roll) * torch.cos(psi) + torch.tan(roll) * torch.sin(psi)


def column_azimuths(width: int, dtype: torch.dtype = torch.float32, device=None) -> torch.Tensor:
    """Azimuth 2 pi u / W of each column u, (W,) rad."""
    return 2.0 * math.pi * torch.arange(width, dtype=dtype, device=device) / width


def row_tangents(height: int, width: int, dtype: torch.dtype = torch.float32, device=None) -> torch.Tensor:
    """tan elevation (c - v) / f of each row v, (H,)."""
    return ((height - 1) / 2.0 - torch.arange(height, dtype=dtype, device=device)) / panorama_focal(width)


def tangent_to_row(t: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """Row coordinate (origin at the top pixel centre) of tan elevation t in a panorama of size (H, W)."""
    return (height - 1) / 2.0 - t * panorama_focal(width)


def row_to_tangent(row: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """tan elevation of a row coordinate in a panorama of size (H, W) (inverse of ``tangent_to_row``)."""
    return ((height - 1) / 2.0 - row) / panorama_focal(width)


def interp_profile(profile: torch.Tensor, psi: torch.Tensor) -> torch.Tensor:
    """Circular linear interpolation of profiles (B, N), bin j at azimuth 2 pi j / N, at azimuths (B, ...) rad."""
    batch, bins = profile.shape
    x = torch.remainder(psi, 2.0 * math.pi).reshape(batch, -1) * (bins / (2.0 * math.pi))
    j0 = x.floor().long().clamp(0, bins - 1)
    frac = x - j0.to(x.dtype)
    out = profile.gather(1, j0) * (1 - frac) + profile.gather(1, (j0 + 1) % bins) * frac
    return out.reshape(psi.shape)


def warp_panorama(image: torch.Tensor, pitch: torch.Tensor, roll: torch.Tensor, to_level: bool = True) -> torch.Tensor:
    """Resample a panorama between the tilted camera and the level frame (bilinear, wrapping around in azimuth).

    Args:
        image: (B, C, H, W) panorama.
        pitch, roll: (B,) camera tilt in rad.
        to_level: True = tilted input to levelled output (removes the S-curve); False = the inverse.

    Returns:
        (B, C, H, W) warped panorama; pixels that fall outside the input rows are 0.
    """
    if image.ndim != 4:
        raise InputError(f"panorama must be (B, C, H, W), got shape {tuple(image.shape)}")
    batch, _, height, width = image.shape
    if pitch.shape != (batch,) or roll.shape != (batch,):
        raise InputError(f"pitch and roll must be ({batch},), got {tuple(pitch.shape)} and {tuple(roll.shape)}")
    dtype, device = image.dtype, image.device
    psi = column_azimuths(width, dtype, device)[None, None, :].expand(batch, height, width)
    t = row_tangents(height, width, dtype, device)[None, :, None].expand(batch, height, width)
    pitch, roll = pitch.to(dtype), roll.to(dtype)
    if to_level:
        psi_src, t_src = level_to_tilted(psi, t, pitch, roll)
    else:
        psi_src, t_src = tilted_to_level(psi, t, pitch, roll)
    u = torch.remainder(psi_src, 2.0 * math.pi) * (width / (2.0 * math.pi))
    v = tangent_to_row(t_src, height, width)
    pad = max(2, width // 16)
    padded = torch.cat([image[..., width - pad :], image, image[..., :pad]], dim=-1)
    grid = torch.stack([(u + pad) / (width + 2 * pad - 1) * 2.0 - 1.0, v / (height - 1) * 2.0 - 1.0], -1)
    return F.grid_sample(padded, grid, mode="bilinear", padding_mode="zeros", align_corners=True)


class LevelPanorama(nn.Module):
    """``warp_panorama(image, pitch, roll, to_level=True)`` as a module (exports to ONNX)."""

    def forward(self, image: torch.Tensor, pitch: torch.Tensor, roll: torch.Tensor) -> torch.Tensor:
        """(B, C, H, W) tilted panorama, (B,) pitch and roll in rad -> (B, C, H, W) levelled panorama."""
        return warp_panorama(image, pitch, roll, to_level=True)

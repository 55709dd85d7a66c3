"""Panorama cylinder geometry: S-curve closed form, round trips and levelling warp."""

import math

import pytest
import torch

from core.cylinder import (
    LevelPanorama,
    column_azimuths,
    interp_profile,
    level_to_tilted,
    row_tangents,
    s_curve,
    tilt_matrix,
    tilted_to_level,
    warp_panorama,
)


def _rotation(axis: str, angle: float) -> torch.Tensor:
    c, s = math.cos(angle), math.sin(angle)
    if axis == "x":
        return torch.tensor([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=torch.float64)
    return torch.tensor([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=torch.float64)


def test_tilt_matrix_conventions():
    pitch, roll = torch.tensor([0.1, -0.05], dtype=torch.float64), torch.tensor([0.03, 0.2], dtype=torch.float64)
    r = tilt_matrix(pitch, roll)
    for b in range(2):
        expected = _rotation("y", -pitch[b].item()) @ _rotation("x", roll[b].item())
        assert torch.allclose(r[b], expected, atol=1e-15)
    # Nose up: the forward axis points above the level plane; roll right-down: the left axis rises.
    forward = r[:, :, 0]
    left = tilt_matrix(torch.zeros(1, dtype=torch.float64), roll[:1])[0, :, 1]
    assert forward[0, 2] > 0 and left[2] > 0


def test_level_great_circle_is_the_s_curve_and_round_trip():
    pitch = torch.tensor([0.08, -0.03, 0.0], dtype=torch.float64)
    roll = torch.tensor([-0.05, 0.12, 0.07], dtype=torch.float64)
    psi_level = torch.linspace(0, 2 * math.pi, 97, dtype=torch.float64)[None].repeat(3, 1)
    psi_cam, t_cam = level_to_tilted(psi_level, torch.zeros_like(psi_level), pitch, roll)
    assert torch.allclose(t_cam, s_curve(psi_cam, pitch, roll), atol=1e-12)
    # Amplitude of the sinusoid = tan(tilt) with cos(tilt) = cos(p) cos(q).
    tilt = torch.acos(torch.cos(pitch) * torch.cos(roll))
    assert torch.allclose(t_cam.abs().max(1).values, torch.tan(tilt), rtol=1e-3)
    t = torch.randn(3, 97, dtype=torch.float64) * 0.2
    back_psi, back_t = tilted_to_level(*level_to_tilted(psi_level, t, pitch, roll), pitch, roll)
    assert torch.allclose(torch.remainder(back_psi - psi_level + 1, 2 * math.pi), torch.ones_like(t) % 1 + 1)
    assert torch.allclose(back_t, t, atol=1e-12)


def test_warp_levels_a_tilted_horizon():
    """A panorama whose rows are split by the S-curve becomes split by a straight row after levelling."""
    height, width = 64, 256
    pitch, roll = torch.tensor([0.04], dtype=torch.float64), torch.tensor([-0.06], dtype=torch.float64)
    psi = column_azimuths(width, torch.float64)
    t = row_tangents(height, width, torch.float64)
    boundary = s_curve(psi[None], pitch, roll)[0]  # tilted image: sky above the S-curve
    image = ((t[:, None] - boundary[None, :]) * width / (2 * math.pi) + 0.5).clamp(0, 1)[None, None]
    inner = slice(8, height - 8)  # rows that stay inside the image under the tilt
    tilted_edge = image[0, 0, inner].sum(0)  # sub-pixel edge position: sky pixels per column
    assert tilted_edge.max() - tilted_edge.min() > 4
    level = warp_panorama(image, pitch, roll)[0, 0]
    assert (level[inner].sum(0) - (height // 2 - 8)).abs().max() < 0.02
    again = warp_panorama(level[None, None], pitch, roll, to_level=False)[0, 0]
    assert (again[inner].sum(0) - tilted_edge).abs().max() < 0.02


@pytest.mark.parametrize("to_level", [True, False])
def test_warp_panorama_gradcheck(to_level):
    """The warp is differentiable in the image and in the tilt (bilinear sampling, wrap-around in azimuth)."""
    g = torch.Generator().manual_seed(0)
    image = torch.rand(2, 1, 6, 16, generator=g, dtype=torch.float64, requires_grad=True)
    pitch = torch.tensor([0.05, -0.11], dtype=torch.float64, requires_grad=True)
    roll = torch.tensor([-0.03, 0.07], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda i, p, r: warp_panorama(i, p, r, to_level=to_level), (image, pitch, roll))
    if to_level:
        assert torch.autograd.gradcheck(LevelPanorama(), (image, pitch, roll))


def test_tilt_and_profile_interpolation_gradcheck():
    g = torch.Generator().manual_seed(1)
    pitch = torch.tensor([0.05, -0.11], dtype=torch.float64, requires_grad=True)
    roll = torch.tensor([-0.03, 0.07], dtype=torch.float64, requires_grad=True)
    psi = (torch.rand(2, 5, generator=g, dtype=torch.float64) * 2 * math.pi).requires_grad_()
    t = (torch.rand(2, 5, generator=g, dtype=torch.float64) - 0.5).requires_grad_()
    assert torch.autograd.gradcheck(tilted_to_level, (psi, t, pitch, roll))
    assert torch.autograd.gradcheck(s_curve, (psi, pitch, roll))
    profile = torch.rand(2, 16, generator=g, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(interp_profile, (profile, psi))

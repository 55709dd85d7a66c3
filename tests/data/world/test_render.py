"""Panorama renderer: ground truth consistency and edges where the ground truth says."""

import math

import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, level_to_tilted, tangent_to_row
from core.errors import InputError
from core.raycast import VirtualHorizon
from data.world.dem import generate_archipelago
from data.world.render import Appearance, render_panorama


@pytest.fixture(scope="module")
def scene():
    dem = generate_archipelago(size_m=3000, cell=10, seed=2, land_fraction=0.2)
    caster = VirtualHorizon(dem, bins=512, max_range=2500.0, step=5.0).double()
    sea = np.argwhere(dem.z[50:250, 50:250] == 0) + 50
    rng = np.random.default_rng(1)
    picks = sea[rng.choice(len(sea), 3, replace=False)]
    poses = torch.tensor([[10.0 * c + 5, 3000 - 10.0 * r - 5, 2.0, rng.uniform(0, 6.3), 0.05 * (i - 1), 0.03]
                          for i, (r, c) in enumerate(picks)], dtype=torch.float64)
    clear = Appearance(*(torch.zeros(3, dtype=torch.float64) for _ in range(8)))
    clear.exposure += 1.0
    clear.sun_elevation += 0.5
    image, truth = render_panorama(caster, poses, width=512, height=96, appearance=clear,
                                   generator=torch.Generator().manual_seed(0))
    return image, truth, poses


def test_tilted_truth_matches_projected_level_truth(scene):
    _, truth, poses = scene
    width, height = 512, 96
    psi = column_azimuths(width, torch.float64)[None].expand(3, width)
    psi_cam, t_cam = level_to_tilted(psi, truth.horizon, truth.pitch, truth.roll)
    u = torch.remainder(psi_cam, 2 * math.pi) * width / (2 * math.pi)
    rows = tangent_to_row(t_cam, height, width)
    # Interpolate the tilted-image truth at the projected columns (independent of the bisection's columns).
    u0 = u.floor().long() % width
    frac = u - u.floor()
    tilted = truth.horizon_rows.gather(1, u0) * (1 - frac) + truth.horizon_rows.gather(1, (u0 + 1) % width) * frac
    flat = (truth.horizon_rows - truth.horizon_rows.roll(1, 1)).abs() < 0.2  # skip island edges
    smooth = flat.gather(1, u0) & flat.gather(1, (u0 + 1) % width)
    assert smooth.float().mean() > 0.3
    error = (tilted - rows)[smooth].abs()
    assert error.median() < 0.01 and error.quantile(0.95) < 0.05
    assert (truth.water_rows >= truth.horizon_rows - 1e-6).all()
    assert torch.allclose(truth.level_horizon_rows, tangent_to_row(truth.horizon, height, width))
    assert ((truth.horizon - truth.water) > 1e-3).any()  # some land in view


def test_edges_lie_on_the_truth(scene):
    image, truth, _ = scene
    gray = image.mean(1)  # (B, H, W)
    open_sea = (truth.water_rows - truth.horizon_rows).abs() < 1e-6
    assert open_sea.float().mean() > 0.2
    cols = torch.arange(512)
    for b in range(3):
        row = truth.horizon_rows[b]
        # Sky (bright) above the sea horizon, sea (dark) below, in every open-sea column.
        above = gray[b, (row - 2).round().long(), cols]
        below = gray[b, (row + 2).round().long(), cols]
        assert ((above - below)[open_sea[b]] > 0.2).all()
        # Sub-pixel: with the analytic coverage, the pixel holding the edge mixes sky and sea in proportion.
        v = row.round().long()
        mix = (gray[b, v, cols] - gray[b, v + 2, cols]) / (gray[b, v - 2, cols] - gray[b, v + 2, cols])
        coverage = (row - v.double() + 0.5).clamp(0, 1)
        assert ((mix - coverage)[open_sea[b]]).abs().median() < 0.2
        land = (truth.water_rows[b] - truth.horizon_rows[b]) > 3
        if land.any():
            mid = ((truth.water_rows[b] + truth.horizon_rows[b]) / 2).round().long()
            # Land is darker than the sky right above the horizon.
            assert (gray[b, mid, cols][land] < above[land]).float().mean() > 0.9


def test_render_bad_input():
    dem = generate_archipelago(size_m=500, cell=10, seed=0)
    caster = VirtualHorizon(dem, bins=64, max_range=300.0)
    with pytest.raises(InputError, match=r"\(B, 6\)"):
        render_panorama(caster, torch.zeros(2, 5))
    with pytest.raises(InputError, match="outside the DEM"):
        render_panorama(caster, torch.tensor([[900.0, 100.0, 2.0, 0.0, 0.0, 0.0]]), width=64, height=16)

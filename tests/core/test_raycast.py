"""Ray-cast virtual horizons against a brute-force per-ray loop and the curvature/refraction drop formula."""

import math

import numpy as np
import pytest
import torch

from core.errors import InputError
from core.raycast import VirtualHorizon, curvature_drop, effective_radius, virtual_horizon
from data.world.dem import Dem, generate_archipelago


def _brute_force(dem: Dem, xy, h_c, bins, max_range, step, k=0.13):
    """Independent scalar reference: walk every ray sample by sample in float64."""
    r_eff = 6371e3 / (1 - k)
    z = dem.z.astype(np.float64)
    rows, cols = z.shape

    def height(x, y, grid):
        c = (x - dem.x0) / dem.cell - 0.5
        r = (dem.y0 - y) / dem.cell - 0.5
        c0, r0 = math.floor(c), math.floor(r)
        total = 0.0
        for rr, wr in ((r0, 1 - (r - r0)), (r0 + 1, r - r0)):
            for cc, wc in ((c0, 1 - (c - c0)), (c0 + 1, c - c0)):
                if 0 <= rr < rows and 0 <= cc < cols:
                    total += wr * wc * grid[rr, cc]
        return total

    sea = -math.sqrt(2 * h_c / r_eff)
    horizon, water = np.zeros(bins), np.zeros(bins)
    n = math.ceil(max_range / step)
    for j in range(bins):
        psi = 2 * math.pi * j / bins
        best, shore, previous = sea, None, 0.0
        for s in range(1, n + 1):
            d = s * step
            x, y = xy[0] + d * math.sin(psi), xy[1] + d * math.cos(psi)
            best = max(best, (height(x, y, z) - h_c - d * d / (2 * r_eff)) / d)
            land = height(x, y, z > 0)
            if shore is None and land > 0.5:
                shore = d - step + step * (0.5 - previous) / (land - previous)
            previous = land
        horizon[j] = best
        if shore is not None and shore < math.sqrt(2 * r_eff * h_c):
            water[j] = (-h_c - shore * shore / (2 * r_eff)) / shore
        else:
            water[j] = sea
    return horizon, water


@pytest.fixture(scope="module")
def small_dem():
    dem = generate_archipelago(size_m=1200, cell=5, seed=7, land_fraction=0.25, max_height=20,
                               forest_height=10)
    sea = np.argwhere(dem.z == 0)
    rng = np.random.default_rng(0)
    picks = sea[rng.choice(len(sea), 3, replace=False)]
    xy = np.stack([dem.x0 + (picks[:, 1] + 0.3) * dem.cell, dem.y0 - (picks[:, 0] + 0.6) * dem.cell], -1)
    return dem, xy


def test_matches_brute_force_loop(small_dem):
    dem, xy = small_dem
    bins, max_range, step, h_c = 48, 700.0, 2.5, 2.0
    out = virtual_horizon(torch.from_numpy(dem.z.astype(np.float64)), dem.x0, dem.y0, dem.cell,
                          torch.from_numpy(xy), h_c, bins, max_range, step, chunk_samples=5000)
    for b in range(len(xy)):
        horizon, water = _brute_force(dem, xy[b], h_c, bins, max_range, step)
        assert np.abs(np.arctan(out.horizon[b].numpy()) - np.arctan(horizon)).max() < 1e-5
        assert np.abs(np.arctan(out.water[b].numpy()) - np.arctan(water)).max() < 1e-5
        assert (horizon > water + 1e-3).any()  # land is in view: the comparison is not trivial
    single = virtual_horizon(torch.from_numpy(dem.z).float(), dem.x0, dem.y0, dem.cell,
                             torch.from_numpy(xy).float(), h_c, bins, max_range, step)
    assert (single.horizon.double() - out.horizon).abs().max() < 1e-4


def test_curvature_drop_and_dip_match_the_formula():
    # Thesis ch. 4.2: drop with k = 0.13 and without refraction.
    for distance, with_k, without in ((1000, 0.07, 0.08), (5000, 1.71, 1.96), (10000, 6.83, 7.85)):
        assert curvature_drop(distance) == pytest.approx(with_k, abs=0.006)
        assert curvature_drop(distance, k=0.0) == pytest.approx(without, abs=0.006)
    assert effective_radius() == pytest.approx(7323e3, rel=1e-3)
    # A 30 m wall 10 km north of a camera 2 m above the sea, on a 50 m grid.
    z = np.zeros((240, 40))
    z[:10] = 30.0
    camera = torch.tensor([[1025.0, 12000.0 - 50.0 * 209.5]], dtype=torch.float64)  # cell centre, row 209
    out = virtual_horizon(torch.from_numpy(z), 0.0, 12000.0, 50.0, camera, 2.0, bins=8, max_range=11000.0,
                          step=5.0)
    distance = 50.0 * (209 - 9)  # to the centre of the wall's last row
    expected = (30.0 - 2.0 - distance**2 / (2 * 6371e3 / 0.87)) / distance
    assert out.horizon[0, 0].item() == pytest.approx(expected, abs=1e-9)
    assert out.horizon_distance[0, 0].item() == pytest.approx(distance)
    # Other azimuths see open sea: the sea horizon at the dip angle (0.042 deg at 2 m: atan(sqrt(2 h / R_eff))).
    dip = math.degrees(math.atan(-out.horizon[0, 2].item()))
    assert dip == pytest.approx(0.042, abs=5e-4)
    assert out.water[0, 2].item() == out.horizon[0, 2].item()
    # The wall's base lies beyond the 5.4 km sea-horizon distance: it is hidden, the water line is the sea.
    assert out.water[0, 0].item() == pytest.approx(out.horizon[0, 2].item())
    assert out.shore_distance[0, 0].item() == pytest.approx(50.0 * (209 - 9.5), abs=2.5)


def test_module_device_dtype_and_errors(small_dem):
    dem, xy = small_dem
    caster = VirtualHorizon(dem, bins=16, max_range=300.0).double()
    out = caster(torch.from_numpy(xy), torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64))
    assert out.horizon.shape == (3, 16) and out.horizon.dtype == torch.float64
    assert (out.water <= out.horizon).all()
    # A higher camera sees the same land lower.
    higher = caster(torch.from_numpy(xy), 10.0)
    assert (higher.horizon <= out.horizon + 1e-12).all()
    with pytest.raises(InputError, match="outside the DEM"):
        caster(torch.tensor([[-10.0, 50.0]], dtype=torch.float64), 2.0)
    with pytest.raises(InputError, match="camera_height"):
        caster(torch.from_numpy(xy), 0.0)
    with pytest.raises(InputError, match=r"\(B, 2\)"):
        caster(torch.zeros(3), 2.0)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_matches_cpu(small_dem):
    dem, xy = small_dem
    caster = VirtualHorizon(dem, bins=64, max_range=500.0).double()
    cpu = caster(torch.from_numpy(xy), 2.0)
    gpu = caster.cuda()(torch.from_numpy(xy).cuda(), 2.0)
    assert (gpu.horizon.cpu() - cpu.horizon).abs().max() < 1e-9

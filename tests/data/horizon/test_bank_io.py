"""Filter bank build and storage: stored filters against an independent numpy fp64 MOSSE, chunking, resume,
float16 storage, corrupt or mismatching banks."""

import json
import math

import numpy as np
import pytest
import torch

from core.errors import InputError
from core.raycast import virtual_horizon
from data.horizon.bank_io import FilterBank
from data.world.dem import generate_archipelago
from models.horizon.filter_bank import BankSettings, bank_grid, build_filter_bank

SETTINGS = BankSettings(spacing=25, bins=128, max_range=500, neighbourhood=50, sample_step=25, sample_sigma=20,
                        frequencies=40)
BOUNDS = (200, 200, 500, 450)


@pytest.fixture(scope="module")
def dem():
    return generate_archipelago(size_m=700, cell=10, seed=2, feature_scale_m=250, land_fraction=0.25,
                                forest_height=0.0)


@pytest.fixture(scope="module")
def bank32(dem, tmp_path_factory):
    return build_filter_bank(dem, SETTINGS, tmp_path_factory.mktemp("b32") / "bank", bounds=BOUNDS,
                             storage_dtype="float32", tile_points=30, progress=False)


def _numpy_filter(dem, xy):
    """MOSSE filter of one location in numpy fp64 from horizons rendered at its neighbourhood samples."""
    s = SETTINGS
    offsets = np.array([(dx, dy) for dy in (-25.0, 0.0, 25.0) for dx in (-25.0, 0.0, 25.0)])
    points = xy[None] + offsets
    sea = (dem.height_at(points) <= 0) & dem.contains(points)
    h = virtual_horizon(torch.from_numpy(dem.z).double(), dem.x0, dem.y0, dem.cell, torch.from_numpy(points[sea]),
                        s.camera_height, s.bins, s.max_range, dem.cell).horizon.numpy()
    deg = np.degrees(np.arctan(h))
    peak = deg.max(1, keepdims=True)
    deg = np.where(peak > s.norm_threshold_deg, deg / peak, deg)
    deg -= deg.mean(1, keepdims=True)
    weight = np.exp(-0.5 * (offsets[sea] ** 2).sum(1) / s.sample_sigma**2)[:, None]
    n = np.arange(s.bins)
    label = np.exp(-0.5 * (np.minimum(n, s.bins - n) / s.sigma) ** 2)
    X, Y = np.fft.rfft(deg, axis=1), np.fft.rfft(label)
    A = (weight * Y * X.conj()).sum(0)
    B = (weight * np.abs(X) ** 2).sum(0)
    return (A / (B + s.eps_rel * B.mean()))[: s.half_spectrum]


def test_locations_are_the_sea_grid_points(dem, bank32):
    grid = bank_grid(dem, SETTINGS.spacing, BOUNDS)
    rr, cc = np.meshgrid(np.arange(grid.rows), np.arange(grid.cols), indexing="ij")
    xy = grid.xy(rr, cc).reshape(-1, 2)
    sea = xy[dem.height_at(xy) <= 0]
    assert len(bank32.meta["chunks"]) > 1  # built in several tiles
    got = bank32.locations()
    assert len(got) == len(sea) > 20
    np.testing.assert_allclose(np.sort(got.view("f8,f8"), axis=0).view("f8"),
                               np.sort(sea.copy().view("f8,f8"), axis=0).view("f8"))


def test_stored_filters_match_numpy_mosse(dem, bank32):
    filters = np.concatenate([c.numpy() for c in bank32.chunks(7)])
    locations = bank32.locations()
    for i in np.linspace(0, len(locations) - 1, 6).astype(int):
        ref = _numpy_filter(dem, locations[i])
        got = filters[i, 0::2] + 1j * filters[i, 1::2]
        np.testing.assert_allclose(got, ref, atol=2e-4 * np.abs(ref).max())


def test_float16_storage_halves_the_size(dem, bank32, tmp_path):
    bank16 = build_filter_bank(dem, SETTINGS, tmp_path / "b16", bounds=BOUNDS, tile_points=30, progress=False)
    f16 = np.concatenate([np.asarray(c.filters) for c in bank16._chunks])
    f32 = np.concatenate([np.asarray(c.filters) for c in bank32._chunks])
    assert f16.dtype == np.float16 and f16.nbytes * 2 == f32.nbytes
    np.testing.assert_allclose(f16.astype(np.float32), f32, atol=2e-3 * np.abs(f32).max())
    assert math.isclose(len(bank16), len(bank32))


def test_interrupted_build_resumes(dem, bank32, tmp_path):
    out = tmp_path / "bank"
    build_filter_bank(dem, SETTINGS, out, bounds=BOUNDS, storage_dtype="float32", tile_points=30, progress=False)
    meta = json.loads((out / "bank.json").read_text())
    first = out / "chunks" / "filters_00000.npy"
    stamp = first.stat().st_mtime_ns
    meta["chunks"] = meta["chunks"][:1]
    meta["complete"] = False
    (out / "bank.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="incomplete"):
        FilterBank(out)
    resumed = build_filter_bank(dem, SETTINGS, out, bounds=BOUNDS, storage_dtype="float32", tile_points=30,
                                progress=False)
    assert first.stat().st_mtime_ns == stamp  # kept, not rebuilt
    np.testing.assert_array_equal(np.concatenate([c.numpy() for c in resumed.chunks()]),
                                  np.concatenate([c.numpy() for c in bank32.chunks()]))


def test_bad_banks_raise_clear_errors(dem, bank32, tmp_path):
    out = tmp_path / "bank"
    build_filter_bank(dem, SETTINGS, out, bounds=BOUNDS, tile_points=30, progress=False)
    other = BankSettings(spacing=30, bins=128, max_range=500)
    with pytest.raises(InputError, match="holds another filter bank"):
        build_filter_bank(dem, other, out, bounds=BOUNDS, progress=False)
    (out / "chunks" / "filters_00001.npy").write_bytes(b"not a numpy file")
    with pytest.raises(InputError, match="chunk 1 is missing or corrupt"):
        FilterBank(out)
    (out / "bank.json").write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        FilterBank(out)
    with pytest.raises(InputError, match="bad filter bank settings: spacing=-1"):
        BankSettings(spacing=-1)
    with pytest.raises(InputError, match="do not overlap"):
        bank_grid(dem, 10, (5000, 5000, 6000, 6000))

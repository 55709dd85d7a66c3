"""Horizon localisation: circular resampling, own-location queries with and without a prior window, bad input."""


import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, interp_profile
from core.errors import InputError
from core.raycast import virtual_horizon
from data.horizon.bank_io import FilterBank
from data.world.dem import generate_archipelago
from models.horizon.filter_bank import BankSettings, build_filter_bank
from models.horizon.localizer import locate, resample_profile


def test_resample_profile_is_circular():
    psi = column_azimuths(64, torch.float64)
    profile = torch.cos(psi)[None]
    out = resample_profile(profile, 256)
    np.testing.assert_allclose(out[0].numpy(), np.cos(column_azimuths(256, torch.float64).numpy()), atol=2e-3)


@pytest.fixture(scope="module")
def small_bank(tmp_path_factory):
    dem = generate_archipelago(size_m=900, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2,
                               forest_height=0.0)
    settings = BankSettings(spacing=20, bins=256, max_range=700, neighbourhood=40, sample_step=20, sample_sigma=10)
    bank = build_filter_bank(dem, settings, tmp_path_factory.mktemp("bank") / "bank",
                             bounds=(250, 250, 650, 650), tile_points=120, progress=False)
    return dem, settings, bank


def _own_queries(dem, settings, xy, heading_deg):
    h = virtual_horizon(torch.from_numpy(dem.z), dem.x0, dem.y0, dem.cell, torch.from_numpy(xy).float(),
                        settings.camera_height, settings.bins, settings.max_range, dem.cell).horizon
    psi = column_azimuths(settings.bins)[None] + torch.deg2rad(heading_deg)[:, None]
    return interp_profile(h, psi)  # column u looks at heading + 2 pi u / N


def test_own_virtual_horizon_returns_its_location_and_heading(small_bank):
    dem, settings, bank = small_bank
    locations = bank.locations()
    pick = np.arange(0, len(locations), 7)
    heading = torch.from_numpy(np.random.default_rng(1).uniform(0, 360, len(pick))).float()
    profile = _own_queries(dem, settings, locations[pick], heading)
    compass = torch.remainder(heading + 2.0, 360)  # compass 2 degrees off, inside the +-4 degree band
    result = locate(bank, profile, compass)
    np.testing.assert_array_equal(result.index, pick)
    assert np.abs((result.heading_deg - heading.numpy() + 180) % 360 - 180).max() < 0.5 * 360 / settings.bins
    assert np.linalg.norm(result.xy - locations[pick], axis=1).max() <= settings.spacing / 2


def test_prior_window_restricts_the_search(small_bank):
    dem, settings, bank = small_bank
    locations = bank.locations()
    pick = np.array([3, len(locations) // 2, len(locations) - 4])
    heading = torch.tensor([20.0, 200.0, 300.0])
    profile = _own_queries(dem, settings, locations[pick], heading)
    near = locate(bank, profile, heading, prior_xy=locations[pick] + 30.0, radius=60.0, keep_scores=True)
    np.testing.assert_array_equal(near.index, pick)
    distance = np.linalg.norm(locations[None] - (locations[pick] + 30.0)[:, None], axis=-1)
    assert np.isneginf(near.scores[distance > 60.0]).all() and np.isfinite(near.scores[distance <= 60.0]).all()
    gap = np.linalg.norm(locations[None] - locations[pick][:, None], axis=-1)
    far_prior = locations[np.argmax((gap > 100) & (gap < 200), axis=1)]  # another sea location 100-200 m away
    assert (np.linalg.norm(far_prior - locations[pick], axis=1) > 100).all()
    far = locate(bank, profile, heading, prior_xy=far_prior, radius=40.0)
    assert (np.linalg.norm(locations[far.index] - far_prior, axis=1) <= 40.0).all()
    with pytest.raises(InputError, match="no bank location lies within"):
        locate(bank, profile, heading, prior_xy=locations[pick] + 1e5, radius=10.0)


def test_bad_queries_raise_clear_errors(small_bank):
    dem, settings, bank = small_bank
    profile = torch.zeros(1, settings.bins)
    with pytest.raises(InputError, match="profile length 100 does not match the bank's 256"):
        locate(bank, torch.zeros(1, 100), torch.tensor([10.0]))
    with pytest.raises(InputError, match=r"outside \[0, 360\)"):
        locate(bank, profile, torch.tensor([360.0]))
    with pytest.raises(InputError, match=r"outside \[0, 360\)"):
        locate(bank, profile, torch.tensor([-1.0]))
    with pytest.raises(InputError, match="one compass heading per profile"):
        locate(bank, profile, torch.tensor([1.0, 2.0]))
    other = generate_archipelago(size_m=900, cell=10, seed=6)
    with pytest.raises(InputError, match="built for another DEM"):
        bank.check_dem(other)
    bank.check_dem(dem)  # its own DEM passes
    with pytest.raises(InputError, match="filter bank not found"):
        FilterBank(bank.path / "nowhere")

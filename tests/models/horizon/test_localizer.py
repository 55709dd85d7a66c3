"""Horizon localisation: band PSR against a brute-force full-response loop, sub-grid refinement against a
closed form, own-location queries, bad input."""

import math

import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, interp_profile
from core.errors import InputError
from core.raycast import virtual_horizon
from data.horizon.bank_io import FilterBank
from data.world.dem import generate_archipelago
from models.horizon.filter_bank import BankSettings, build_filter_bank, profile_normalize
from models.horizon.localizer import locate, resample_profile, subgrid_refine
from models.horizon.matching import band_psr


def _brute_psr(filters, profile, heading_deg, band_deg, exclude, threshold, drop=0):
    """Full irfft response per location (numpy fp64 loop), peak in the band, sidelobe by an explicit mask."""
    bins = profile.shape[-1]
    z = np.fft.rfft(profile_normalize(torch.from_numpy(profile), threshold).numpy())
    z[:, 1 : drop + 1] = 0
    band = max(1, math.ceil(band_deg * bins / 360))
    psr = np.zeros((len(profile), len(filters)))
    heading = np.zeros_like(psr)
    for b in range(len(profile)):
        centre = round(-heading_deg[b] * bins / 360)
        for i, f in enumerate(filters):
            h = np.zeros(bins // 2 + 1, complex)
            h[: len(f) // 2] = f[0::2] + 1j * f[1::2]
            r = np.fft.irfft(h * z[b], n=bins)
            lags = np.arange(centre - band, centre + band + 1)
            p = lags[np.argmax(r[lags % bins])]
            mask = np.ones(bins, bool)
            mask[np.arange(p - exclude // 2, p + exclude // 2 + 1) % bins] = False
            side = r[mask]
            psr[b, i] = (r[p % bins] - side.mean()) / side.std()
            lo, mid, hi = r[(p - 1) % bins], r[p % bins], r[(p + 1) % bins]
            delta = 0.5 * (lo - hi) / (lo - 2 * mid + hi) if lo - 2 * mid + hi < 0 else 0.0
            heading[b, i] = (-(p + np.clip(delta, -0.5, 0.5)) * 360 / bins) % 360
    return psr, heading


@pytest.mark.parametrize(("bins", "frequencies", "band_deg", "drop"), [(128, 65, 4.0, 0), (200, 40, 10.0, 1)])
def test_band_psr_matches_full_response_loop(bins, frequencies, band_deg, drop):
    gen = torch.Generator().manual_seed(bins)
    filters = torch.randn(37, 2 * frequencies, generator=gen, dtype=torch.float64)
    filters[:, 1] = 0  # DC and Nyquist of a real signal's spectrum are real
    if frequencies == bins // 2 + 1:
        filters[:, -1] = 0
    profile = torch.cumsum(torch.randn(3, bins, generator=gen, dtype=torch.float64), -1) * 0.01
    heading = torch.tensor([0.0, 123.4, 359.9], dtype=torch.float64)
    psr, est = band_psr(filters, profile, heading, band_deg, 11, 1.0, drop)
    ref_psr, ref_heading = _brute_psr(filters.numpy(), profile.numpy(), heading.numpy(), band_deg, 11, 1.0, drop)
    np.testing.assert_allclose(psr.numpy(), ref_psr, rtol=1e-9, atol=1e-9)
    diff = (est.numpy() - ref_heading + 180) % 360 - 180
    np.testing.assert_allclose(diff, 0, atol=1e-9)


def test_dropping_harmonic_one_ignores_a_tilt_sinusoid():
    gen = torch.Generator().manual_seed(3)
    filters = torch.randn(20, 2 * 129, generator=gen, dtype=torch.float64)
    filters[:, 1] = filters[:, -1] = 0
    psi = column_azimuths(256, torch.float64)
    base = 3.0 * torch.rand(1, 256, generator=gen, dtype=torch.float64)  # degrees, above the threshold
    tilted = base + 0.4 * torch.cos(psi - 0.7)  # a levelling error adds harmonic 1 (in elevation)
    to_tan = lambda deg: torch.tan(torch.deg2rad(deg))  # noqa: E731
    heading = torch.tensor([77.0], dtype=torch.float64)
    p0, h0 = band_psr(filters, to_tan(base), heading, drop_harmonics=1)
    p1, h1 = band_psr(filters, to_tan(tilted), heading, drop_harmonics=1)
    np.testing.assert_allclose(p1.numpy(), p0.numpy(), rtol=1e-9)  # PSR is scale invariant: max division is moot
    np.testing.assert_allclose(h1.numpy(), h0.numpy(), atol=1e-9)
    assert not np.allclose(band_psr(filters, to_tan(tilted), heading)[0].numpy(), p0.numpy(), rtol=1e-3)


def test_band_psr_float32_close_to_float64():
    gen = torch.Generator().manual_seed(0)
    filters = torch.randn(50, 2 * 129, generator=gen, dtype=torch.float64)
    profile = torch.cumsum(torch.randn(2, 256, generator=gen, dtype=torch.float64), -1) * 0.01
    heading = torch.tensor([10.0, 300.0], dtype=torch.float64)
    p64, _ = band_psr(filters, profile, heading)
    p32, _ = band_psr(filters.float(), profile.float(), heading.float())
    np.testing.assert_allclose(p32.double().numpy(), p64.numpy(), atol=1e-4 * p64.abs().max().item())


def test_subgrid_refine_recovers_quadratic_peak():
    rows, cols = 9, 11
    rr, cc = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    cells = np.stack([rr.ravel(), cc.ravel()], -1)
    peaks = np.array([[4.3, 5.0], [2.0, 7.45], [6.6, 3.8]])
    scores = np.stack([10 - 2 * (cells[:, 0] - r) ** 2 - 0.5 * (cells[:, 1] - c) ** 2 for r, c in peaks])
    best = scores.argmax(1)
    np.testing.assert_allclose(subgrid_refine(scores, cells, rows, cols, best), peaks, atol=1e-12)
    # at the grid border there is no neighbour on one side: no refinement along that axis
    edge = np.stack([10 - (cells[:, 0] - 0.2) ** 2 - (cells[:, 1] - 5.3) ** 2])
    out = subgrid_refine(edge, cells, rows, cols, edge.argmax(1))
    np.testing.assert_allclose(out, [[0.0, 5.3]], atol=1e-12)
    # neighbours outside a search window (-inf) count as missing
    edge[0, (cells[:, 1] == 6)] = -np.inf
    np.testing.assert_allclose(subgrid_refine(edge, cells, rows, cols, edge.argmax(1)), [[0.0, 5.0]], atol=1e-12)


def test_profile_normalize_rule():
    far = torch.full((1, 8), math.tan(math.radians(-0.04)))
    far[0, 3] = math.tan(math.radians(0.5))  # below the 1-degree threshold: kept in degrees
    near = far.clone()
    near[0, 3] = math.tan(math.radians(4.0))  # above: divided by the maximum
    out_far, out_near = profile_normalize(far, 1.0), profile_normalize(near, 1.0)
    deg_far = np.degrees(np.arctan(far.numpy()))
    np.testing.assert_allclose(out_far.numpy(), deg_far - deg_far.mean(), rtol=1e-5)
    deg_near = np.degrees(np.arctan(near.numpy())) / 4.0
    np.testing.assert_allclose(out_near.numpy(), deg_near - deg_near.mean(), rtol=1e-5)


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

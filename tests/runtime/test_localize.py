"""The runtime's localisation: its command, run without torch, against the PyTorch localiser on the same bank,
from profiles and from panoramas through the networks (the same best cells), and a bank that does not fit the
bundle's matcher."""

import csv
import shutil

import numpy as np
import pytest
import torch

from core.bank_reader import BankReader
from core.cylinder import column_azimuths, interp_profile
from core.errors import InputError
from core.raycast import virtual_horizon
from data.horizon.bank_io import FilterBank
from data.horizon.datamodule import read_full_panorama
from models.horizon.localizer import HorizonLocalizer
from runtime.localize import OnnxLocalizer
from tests.runtime.test_horizon import write_panoramas

pytestmark = pytest.mark.slow  # uses an exported bundle


def _track(path) -> np.ndarray:
    with path.open() as f:
        return np.array([[float(r["x"]), float(r["y"]), float(r["heading_deg"])] for r in csv.DictReader(f)])


def _own_profiles(setup, path) -> tuple[np.ndarray, np.ndarray]:
    """Virtual horizons of some bank locations seen at spread headings, as a profile file; (profiles, compass)."""
    dem, settings = setup["dem"], setup["bank_settings"]
    xy = BankReader(setup["bank"]).locations()[::5]
    heading = np.linspace(10, 350, len(xy))
    h = virtual_horizon(torch.from_numpy(dem.z), dem.x0, dem.y0, dem.cell, torch.from_numpy(xy).float(),
                        settings.camera_height, settings.bins, settings.max_range, dem.cell).horizon
    psi = column_azimuths(settings.bins)[None] + torch.deg2rad(torch.from_numpy(heading)).float()[:, None]
    profiles = interp_profile(h, psi)  # column u looks at heading + 2 pi u / N
    np.savez(path, horizon=profiles.numpy(), compass_deg=heading)
    return profiles.numpy(), heading


def test_profiles_without_torch_match_pytorch(torch_free, horizon_setup, tmp_path) -> None:
    s = horizon_setup
    profiles, heading = _own_profiles(s, tmp_path / "p.npz")
    torch_free("runtime.localize", "--bundle", s["bundle"], "--bank", s["bank"], "--profiles", tmp_path / "p.npz",
               "--out", tmp_path / "track.csv")
    ref = HorizonLocalizer(FilterBank(s["bank"])).from_profiles(torch.from_numpy(profiles).float(),
                                                                 torch.from_numpy(heading).float())
    got = _track(tmp_path / "track.csv")
    np.testing.assert_allclose(got[:, :2], ref.xy, atol=2e-3)  # the same cells: the CSV keeps 3 decimals
    np.testing.assert_allclose(got[:, 2], ref.heading_deg, atol=2e-3)
    assert np.abs(got[:, :2] - BankReader(s["bank"]).locations()[::5]).max() < 1.0  # own horizons come home


def test_panoramas_without_torch_match_pytorch(torch_free, horizon_setup, tmp_path) -> None:
    s = horizon_setup
    xy = BankReader(s["bank"]).locations()[:3]
    paths = write_panoramas(tmp_path / "img", s["dem"], xy, [20.0, 140.0, 300.0])
    (tmp_path / "compass.csv").write_text("image,compass_deg\n0.png,20\n1.png,140\n2.png,300\n")
    torch_free("runtime.localize", "--bundle", s["bundle"], "--bank", s["bank"], "--images", tmp_path / "img",
               "--compass", tmp_path / "compass.csv", "--out", tmp_path / "track.csv")
    localizer = HorizonLocalizer(FilterBank(s["bank"]), s["finder"], s["segmenter"], input_width=256)
    ref = localizer.from_images([read_full_panorama(p) for p in paths], torch.tensor([20.0, 140.0, 300.0]))
    runtime = OnnxLocalizer(s["bundle"], s["bank"], threads=1)
    _, _, _, cells = runtime.locate(runtime.image_profiles([read_full_panorama(p).numpy() for p in paths]),
                                    np.array([20.0, 140.0, 300.0]))
    np.testing.assert_array_equal(np.round(cells), np.round(ref.cell))
    np.testing.assert_allclose(_track(tmp_path / "track.csv")[:, :2], ref.xy, atol=2e-3)


def test_a_bank_of_other_bins_is_refused(horizon_setup, tmp_path) -> None:
    bank = shutil.copytree(horizon_setup["bank"], tmp_path / "bank")
    text = (bank / "bank.json").read_text().replace('"bins": 64', '"bins": 128')
    (bank / "bank.json").write_text(text)
    with pytest.raises(InputError, match="does not fit the bundle's matcher"):
        OnnxLocalizer(horizon_setup["bundle"], bank)

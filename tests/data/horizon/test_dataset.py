"""Dataset writer: trajectories over water, files and arrays written."""

import json

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.horizon.dataset import DatasetSettings, random_trajectories, read_split, write_dataset
from data.world.dem import generate_archipelago, load_dem


@pytest.fixture(scope="module")
def dem():
    return generate_archipelago(size_m=3000, cell=10, seed=4, land_fraction=0.15)


def test_trajectories_stay_on_open_water(dem):
    settings = DatasetSettings(count=60, frames_per_track=12, step_m=20.0, shore_m=(30.0, 800.0),
                               max_range_m=1600.0)
    poses = random_trajectories(dem, settings, np.random.default_rng(0))
    assert poses.shape == (60, 6)
    assert (dem.height_at(poses[:, :2]) == 0).all()
    land = np.argwhere(dem.z > 0)
    land_xy = np.stack([dem.x0 + (land[:, 1] + 0.5) * dem.cell, dem.y0 - (land[:, 0] + 0.5) * dem.cell], -1)
    nearest = np.sqrt(((poses[:, None, :2] - land_xy[None]) ** 2).sum(-1)).min(1)
    assert (nearest >= 30.0 - dem.cell).all() and (nearest <= 800.0 + dem.cell).all()
    steps = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    assert np.isclose(steps, 20.0).mean() > 0.8  # within trajectories; jumps where a new one starts
    assert np.abs(np.degrees(poses[:, 4:])).max() < 3.0 * 1.6
    with pytest.raises(InputError, match="no water"):
        random_trajectories(dem, DatasetSettings(shore_m=(5000.0, 6000.0), max_range_m=1600.0),
                            np.random.default_rng(0))


def test_write_dataset_layout(dem, tmp_path):
    settings = DatasetSettings(count=3, width=256, height=32, frames_per_track=2, degraded_fraction=0.5,
                               render_bins=512, label_bins=256, max_range_m=1600.0, seed=1)
    out = write_dataset(tmp_path / "set", dem, settings, batch=2, progress=False)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["count"] == 3 and meta["settings"]["width"] == 256
    image = cv2.imread(str(out / "images" / "000002.png"))
    assert image.shape == (32, 256, 3)
    labels, truth = read_split(out, "labels"), read_split(out, "truth")
    assert labels["horizon_rows"].shape == (3, 256) and labels["ok"].dtype == bool
    assert truth["pose"].shape == (3, 6) and truth["level_horizon_rows"].shape == (3, 256)
    np.testing.assert_allclose(truth["pitch"], truth["pose"][:, 4], atol=1e-6)
    assert np.array_equal(load_dem(out / "dem.tif").z, dem.z)
    with pytest.raises(InputError, match="render-dataset"):
        read_split(tmp_path / "missing", "labels")

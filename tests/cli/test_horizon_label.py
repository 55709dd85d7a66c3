"""infer.py horizon-label end to end, and clear one-line errors for bad input (exit code 2)."""

import json
import math

import cv2
import numpy as np
import pytest
import torch

import infer
from core.raycast import VirtualHorizon
from data.world.dem import Dem, generate_archipelago, save_dem
from data.world.render import Appearance, render_panorama


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    dem = generate_archipelago(size_m=3000, cell=10, seed=6, land_fraction=0.15, x0=500000.0, y0=6230000.0)
    save_dem(root / "dem.tif", dem)
    save_dem(root / "nocrs.npz", Dem(dem.z, dem.x0, dem.y0, dem.cell, crs=None))
    sea = np.argwhere(dem.z[100:200, 100:200] == 0)[0] + 100
    x, y = dem.x0 + (sea[1] + 0.5) * 10, dem.y0 - (sea[0] + 0.5) * 10
    pose = torch.tensor([[x, y, 2.0, 1.0, math.radians(2.0), math.radians(-1.5)]], dtype=torch.float64)
    generator = torch.Generator().manual_seed(0)
    image, truth = render_panorama(VirtualHorizon(dem, bins=2048, max_range=2000.0).double(), pose, 1024, 128,
                                   Appearance.sample(1, False, generator), generator)
    png = root / "pano.png"
    cv2.imwrite(str(png), (image[0].permute(1, 2, 0).numpy()[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str(root / "square.png"), np.zeros((100, 100, 3), np.uint8))
    return root, (x, y), truth


def test_horizon_label_command(scene, capsys):
    root, (x, y), truth = scene
    code = infer.main(["horizon-label", "--image", str(root / "pano.png"), "--dem", str(root / "dem.tif"),
                       "--position", str(x), str(y), "--compass", str(math.degrees(1.0) + 2.0),
                       "--max-range", "2000", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["ok"]
    assert abs(report["pitch_deg"] - 2.0) < 0.15 and abs(report["roll_deg"] + 1.5) < 0.15
    assert abs(report["heading_deg"] - math.degrees(1.0)) < 0.3


@pytest.mark.parametrize("change, message", [
    ({"--dem": "missing.tif"}, "DEM file not found"),
    ({"--image": "missing.png"}, "missing or unreadable"),
    ({"--image": "square.png"}, "at least twice as wide"),
    ({"--position": ["0", "0"]}, "outside the DEM"),
    ({"--dem": "nocrs.npz", "--position": None, "--lonlat": ["15.5", "56.2"]}, "no CRS"),
])
def test_bad_input_is_one_line_and_exit_2(scene, capsys, change, message):
    root, (x, y), _ = scene
    args = {"--image": "pano.png", "--dem": "dem.tif", "--position": [str(x), str(y)], "--compass": "10"}
    args.update(change)
    argv = ["horizon-label"]
    for key, value in args.items():
        if value is None:
            continue
        if isinstance(value, list):
            argv += [key, *value]
        else:
            argv += [key, str(root / value) if key in ("--image", "--dem") else value]
    assert infer.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err

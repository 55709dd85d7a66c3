"""infer.py localize end to end on a small written DEM and a bank from ``infer.py build-bank``: profiles from a
file (also through a horizon bundle and the runtime), panoramas through (untrained, tiny) horizon networks, and
bad input with one-line errors."""

import csv
import math

import cv2
import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, interp_profile
from core.raycast import VirtualHorizon, virtual_horizon
from data.world.dem import generate_archipelago, save_dem
from data.world.render import render_panorama
from infer import main


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    root = tmp_path_factory.mktemp("loc")
    dem = generate_archipelago(size_m=800, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2, forest_height=0)
    save_dem(root / "dem.tif", dem)
    code = main(["build-bank", "--dem", str(root / "dem.tif"), "--spacing", "20", "--bins", "256",
                 "--max-range", "600", "--neighbourhood", "40", "--bounds", "250", "250", "550", "550",
                 "--out", str(root / "bank")])
    assert code == 0
    return root, dem


def _locations(root):
    from data.horizon.bank_io import FilterBank

    return FilterBank(root / "bank").locations()


def _profiles_file(root, dem, path):
    """Own virtual horizons of every 9th bank location seen at spread headings, compass 1.5 degrees off, as
    ``localize --profiles`` reads them; returns the true positions and headings."""
    xy = _locations(root)[::9]
    heading = np.linspace(10, 350, len(xy))
    h = virtual_horizon(torch.from_numpy(dem.z), dem.x0, dem.y0, dem.cell, torch.from_numpy(xy).float(), 2.0, 256,
                        600, dem.cell).horizon
    profiles = interp_profile(h, column_azimuths(256)[None] + torch.deg2rad(torch.from_numpy(heading)).float()[:, None])
    np.savez(path, horizon=profiles.numpy(), compass_deg=(heading + 1.5) % 360)
    return xy, heading


def test_localize_profiles_file(world, tmp_path):
    root, dem = world
    xy, heading = _profiles_file(root, dem, tmp_path / "p.npz")
    assert main(["localize", "--bank", str(root / "bank"), "--profiles", str(tmp_path / "p.npz"),
                 "--dem", str(root / "dem.tif"), "--out", str(tmp_path / "track.csv")]) == 0
    with (tmp_path / "track.csv").open() as f:
        rows = list(csv.DictReader(f))
    got = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    assert np.linalg.norm(got - xy, axis=1).max() <= 10.0
    got_heading = np.array([float(r["heading_deg"]) for r in rows])
    assert np.abs((got_heading - heading + 180) % 360 - 180).max() < 360 / 256


@pytest.mark.slow  # uses an exported bundle
def test_localize_with_a_bundle_runs_the_runtime(horizon_setup, tmp_path, capsys):
    """``--onnx BUNDLE``: the runtime's localisation (the same track as ``runtime.localize``)."""
    from runtime.localize import localize_files

    s = horizon_setup
    profiles = np.zeros((2, 64))
    profiles[:, 10:20] = 0.02
    np.savez(tmp_path / "p.npz", horizon=profiles, compass_deg=np.array([10.0, 200.0]))
    assert main(["localize", "--bank", str(s["bank"]), "--profiles", str(tmp_path / "p.npz"), "--onnx",
                 str(s["bundle"]), "--out", str(tmp_path / "cli.csv")]) == 0
    assert "onnxruntime" in capsys.readouterr().out
    localize_files(s["bundle"], s["bank"], tmp_path / "runtime.csv", profiles=tmp_path / "p.npz")
    assert (tmp_path / "cli.csv").read_text() == (tmp_path / "runtime.csv").read_text()


def test_localize_bad_input(world, tmp_path, capsys):
    root, dem = world
    bank = str(root / "bank")
    np.savez(tmp_path / "short.npz", horizon=np.zeros((2, 100)), compass_deg=np.zeros(2))
    assert main(["localize", "--bank", bank, "--profiles", str(tmp_path / "short.npz"), "--out", "x.csv"]) == 2
    assert "short.npz has 100 azimuth bins per profile, the bank" in capsys.readouterr().err
    np.savez(tmp_path / "north.npz", horizon=np.zeros((1, 256)), compass_deg=np.array([360.0]))
    assert main(["localize", "--bank", bank, "--profiles", str(tmp_path / "north.npz"), "--out", "x.csv"]) == 2
    assert "outside [0, 360)" in capsys.readouterr().err
    save_dem(tmp_path / "other.tif", generate_archipelago(size_m=800, cell=10, seed=6))
    np.savez(tmp_path / "ok.npz", horizon=np.zeros((1, 256)), compass_deg=np.array([10.0]))
    assert main(["localize", "--bank", bank, "--profiles", str(tmp_path / "ok.npz"), "--dem",
                 str(tmp_path / "other.tif"), "--out", "x.csv"]) == 2
    assert "built for another DEM" in capsys.readouterr().err
    assert main(["localize", "--bank", str(tmp_path / "none"), "--profiles", str(tmp_path / "ok.npz"),
                 "--out", "x.csv"]) == 2
    assert "filter bank not found" in capsys.readouterr().err


def _tiny_checkpoint(system_class, path):
    from lightning.pytorch import Trainer

    system = system_class(backbone="resnet18", stage="layer1", heads=2, head_channels=4, channels=8)
    trainer = Trainer(logger=False, enable_checkpointing=False, accelerator="cpu", devices=1)
    trainer.strategy.connect(system)
    trainer.save_checkpoint(path)
    return path


def test_localize_images_through_networks(world, tmp_path):
    from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem

    root, dem = world
    xy = _locations(root)[:2]
    poses = torch.tensor([[*xy[0], 2.0, 0.3, 0.01, -0.02], [*xy[1], 2.0, 4.0, 0.0, 0.01]])
    image, _ = render_panorama(VirtualHorizon(dem, bins=512, max_range=600), poses, 256, 32)
    (tmp_path / "img").mkdir()
    for i in range(2):
        cv2.imwrite(str(tmp_path / "img" / f"{i}.png"), (image[i].permute(1, 2, 0).numpy()[..., ::-1] * 255).round())
    (tmp_path / "compass.csv").write_text(
        "image,compass_deg\n" + "".join(f"{i}.png,{math.degrees(poses[i, 3].item()):.2f}\n" for i in range(2)))
    finder = _tiny_checkpoint(HorizonFinderSystem, tmp_path / "finder.ckpt")
    segmenter = _tiny_checkpoint(HorizonSegmenterSystem, tmp_path / "segmenter.ckpt")
    assert main(["localize", "--bank", str(root / "bank"), "--images", str(tmp_path / "img"), "--compass",
                 str(tmp_path / "compass.csv"), "--finder", str(finder), "--segmenter", str(segmenter),
                 "--input-width", "256", "--out", str(tmp_path / "track.csv")]) == 0
    with (tmp_path / "track.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["name"] for r in rows] == ["0.png", "1.png"]  # untrained networks: only the chain is checked
    assert all(np.isfinite(float(r["x"])) and np.isfinite(float(r["psr"])) for r in rows)
    (tmp_path / "bad.csv").write_text("image,compass_deg\nmissing.png,3\n")
    assert main(["localize", "--bank", str(root / "bank"), "--images", str(tmp_path / "img"), "--compass",
                 str(tmp_path / "bad.csv"), "--finder", str(finder), "--segmenter", str(segmenter),
                 "--out", str(tmp_path / "t.csv")]) == 2

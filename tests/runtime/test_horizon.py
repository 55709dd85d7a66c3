"""The runtime's horizon chain: its command, run without torch, against the PyTorch chain on the same rendered
panorama (pitch and roll within 0.01 deg, profiles within 0.05 px), profile resampling, panoramas that do not fit
the bundle."""

import json
import math

import cv2
import numpy as np
import pytest
import torch

from core.cylinder import column_azimuths, interp_profile
from core.errors import InputError
from core.raycast import VirtualHorizon
from data.horizon.datamodule import read_full_panorama
from data.world.render import render_panorama
from models.horizon.localizer import panorama_profiles
from runtime.horizon import HorizonChain, read_panorama, resample_profile

pytestmark = pytest.mark.slow  # uses an exported bundle


def write_panoramas(folder, dem, xy, headings, width: int = 256, height: int = 32) -> list:
    """Tilted panoramas rendered over ``dem`` at positions ``xy`` (M, 2) as PNG files ``<i>.png``; their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    poses = torch.tensor([[x, y, 2.0, math.radians(h), 0.02 * (-1) ** i, -0.015]
                          for i, ((x, y), h) in enumerate(zip(xy, headings, strict=True))])
    images, _ = render_panorama(VirtualHorizon(dem, bins=2 * width, max_range=600), poses, width, height,
                                generator=torch.Generator().manual_seed(0))
    paths = []
    for i, image in enumerate(images):
        paths.append(folder / f"{i}.png")
        cv2.imwrite(str(paths[-1]), (image.permute(1, 2, 0).numpy()[..., ::-1] * 255).round().astype(np.uint8))
    return paths


def test_command_without_torch_matches_pytorch(torch_free, horizon_setup, tmp_path) -> None:
    s = horizon_setup
    (path,) = write_panoramas(tmp_path, s["dem"], [(300.0, 280.0)], [40.0])
    proc = torch_free("runtime.horizon", "--bundle", s["bundle"], "--image", path, "--out", tmp_path / "p.npz",
                      "--json")
    report, got = json.loads(proc.stdout), np.load(tmp_path / "p.npz")
    profiles, pitch, roll = panorama_profiles(read_full_panorama(path), s["finder"], s["segmenter"], 256)
    assert abs(math.degrees(float(got["pitch"]) - pitch.item())) < 0.01
    assert abs(math.degrees(float(got["roll"]) - roll.item())) < 0.01
    focal = 256 / (2 * math.pi)
    assert np.abs(np.stack([got["horizon"], got["water"]]) - profiles[0].numpy()).max() * focal < 0.05
    assert report["pitch_deg"] == pytest.approx(math.degrees(float(got["pitch"])))


def test_wider_panoramas_and_bad_sizes(horizon_setup, tmp_path) -> None:
    s = horizon_setup
    chain = HorizonChain(s["bundle"], threads=1)
    image = np.random.default_rng(0).random((2, 3, 32, 256), dtype=np.float32)
    profiles, pitch, roll = chain(image)
    with torch.no_grad():
        ref, ref_pitch, _ = panorama_profiles(torch.from_numpy(image), s["finder"], s["segmenter"], 256)
    assert profiles.shape == (2, 2, 256) and np.abs(pitch - ref_pitch.numpy()).max() < 1e-4
    with pytest.raises(InputError, match="does not fit the bundle"):
        chain(np.zeros((1, 3, 64, 512), np.float32))
    cv2.imwrite(str(tmp_path / "square.png"), np.zeros((32, 40, 3), np.uint8))
    with pytest.raises(InputError, match="at least twice as wide"):
        read_panorama(tmp_path / "square.png")


def test_profile_resampling_is_torchs() -> None:
    profile = torch.rand(2, 64, generator=torch.Generator().manual_seed(1))
    expected = interp_profile(profile, column_azimuths(200)[None].expand(2, 200)).numpy()
    np.testing.assert_allclose(resample_profile(profile.numpy(), 200), expected, atol=1e-6)

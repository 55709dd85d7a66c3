"""``infer.py horizon`` on one panorama with (tiny, untrained) HorizonFinder / HorizonSegmenter checkpoints and
with a horizon bundle (the runtime's path, matching PyTorch on the bundle's networks); the input width and the
model options are checked."""

import json
import math

import cv2
import numpy as np
import pytest
import torch

import infer
from data.horizon.datamodule import read_full_panorama
from models.horizon.lit import HorizonFinderSystem, HorizonSegmenterSystem
from models.horizon.localizer import panorama_profiles
from runtime.horizon import horizon_file
from tests.models.test_checkpoint import save_checkpoint

TINY = {"backbone": "resnet18", "stage": "layer1", "heads": 2, "head_channels": 4, "channels": 8}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 32 x 256 panorama (sky over sea with a darker island band) and checkpoints of both networks."""

    root = tmp_path_factory.mktemp("horizon_cli")
    rows = np.linspace(0.0, 1.0, 32)[:, None, None]
    image = np.where(rows < 0.5, [230, 200, 170], [90, 60, 30]) * np.ones((32, 256, 3))
    image[12:16, 40:120] = 40
    cv2.imwrite(str(root / "pano.png"), image.astype(np.uint8))
    torch.manual_seed(0)
    for name, system_class in (("finder", HorizonFinderSystem), ("segmenter", HorizonSegmenterSystem)):
        system = system_class(**TINY)
        save_checkpoint(system, root / f"{name}.ckpt")
    return root


def _args(root, tmp_path, finder=None, width="256"):
    return ["horizon", "--image", str(root / "pano.png"), "--input-width", width, "--json", "--out",
            str(tmp_path / "p.npz"), "--finder", str(finder or root / "finder.ckpt"), "--segmenter",
            str(root / "segmenter.ckpt")]


def test_horizon_with_checkpoints(scene, tmp_path, capsys):
    assert infer.main(_args(scene, tmp_path)) == 0
    from_ckpt = json.loads(capsys.readouterr().out)
    assert set(from_ckpt) == {"pitch_deg", "roll_deg", "horizon_row_median", "land_columns"}
    saved = np.load(tmp_path / "p.npz")
    assert saved["horizon"].shape == (256,) and abs(math.degrees(saved["pitch"]) - from_ckpt["pitch_deg"]) < 1e-9
    assert infer.main(_args(scene, tmp_path, width="250")) == 2
    assert "multiple of 32" in capsys.readouterr().err


@pytest.mark.slow  # uses an exported bundle
def test_horizon_with_a_bundle_runs_the_runtime(scene, horizon_setup, capsys):
    argv = ["horizon", "--image", str(scene / "pano.png"), "--json", "--onnx", str(horizon_setup["bundle"])]
    assert infer.main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    assert report == horizon_file(horizon_setup["bundle"], scene / "pano.png")
    _, pitch, roll = panorama_profiles(read_full_panorama(scene / "pano.png"), horizon_setup["finder"],
                                       horizon_setup["segmenter"], 256)
    assert abs(report["pitch_deg"] - math.degrees(pitch.item())) < 0.01
    assert infer.main([*argv, "--finder", str(scene / "finder.ckpt")]) == 2
    assert "not both" in capsys.readouterr().err
    assert infer.main(["horizon", "--image", str(scene / "pano.png"), "--finder", str(scene / "finder.ckpt")]) == 2
    assert "give --finder CKPT and --segmenter CKPT" in capsys.readouterr().err

"""bench/horizon_networks.py: the chain's speed in PyTorch and in the deployment runtime, same run."""

import pytest

from bench.horizon_networks import chain_speed
from core.errors import InputError
from export.horizon_onnx import render_panoramas


@pytest.mark.slow  # uses an exported bundle
def test_chain_speed_of_pytorch_and_a_bundle(horizon_setup, tmp_path) -> None:
    render_panoramas(tmp_path / "data", 4, 32, 256, seed=4)
    s = horizon_setup
    speed = chain_speed(s["finder"], s["segmenter"], [s["bundle"]], tmp_path / "data", 256, repeats=1)
    assert set(speed) == {"speed/pytorch_images_per_s", f"speed/onnx:{s['bundle'].name}_images_per_s"}
    assert all(v > 0 for v in speed.values())
    with pytest.raises(InputError, match="takes networks of width 256"):
        chain_speed(s["finder"], s["segmenter"], [s["bundle"]], tmp_path / "data", 512, repeats=1)

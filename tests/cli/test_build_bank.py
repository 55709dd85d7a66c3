"""``infer.py build-bank``: a small bank with the requested settings, a missing DEM in one line, and a killed
build that resumes to the same bytes."""

import pytest

from data.horizon.bank_io import FilterBank
from data.world.dem import generate_archipelago, save_dem
from infer import main
from tests.cli.conftest import kill_and_resume, run_infer, tree_bytes


def test_build_bank_writes_the_requested_bank(tmp_path, capsys):
    dem = generate_archipelago(size_m=600, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2, forest_height=0)
    save_dem(tmp_path / "dem.tif", dem)
    assert main(["build-bank", "--dem", str(tmp_path / "dem.tif"), "--spacing", "50", "--bins", "64",
                 "--max-range", "300", "--neighbourhood", "0", "--bounds", "150", "150", "450", "450", "--float32",
                 "--out", str(tmp_path / "bank")]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {tmp_path / 'bank'}: ")
    bank = FilterBank(tmp_path / "bank")
    assert bank.settings["spacing"] == 50 and bank.settings["bins"] == 64 and bank.meta["storage_dtype"] == "float32"
    xy = bank.locations()
    assert len(xy) > 0 and (dem.height_at(xy) <= 0).all()
    assert ((xy >= 150) & (xy <= 450)).all()


def test_build_bank_missing_dem(tmp_path, capsys):
    assert main(["build-bank", "--dem", str(tmp_path / "missing.tif"), "--spacing", "5", "--out", "b"]) == 2
    assert "DEM file not found" in capsys.readouterr().err


@pytest.fixture(scope="module")
def fifteen_tiles(tmp_path_factory) -> list[str]:
    """build-bank arguments (no --out) of a 1.5 km map whose bank has 15 tiles (one bank.json, 2 files a tile)."""
    root = tmp_path_factory.mktemp("bank_dem")
    dem = generate_archipelago(size_m=1500, cell=10, seed=5, feature_scale_m=300, land_fraction=0.2, forest_height=0)
    save_dem(root / "dem.tif", dem)
    return ["build-bank", "--dem", str(root / "dem.tif"), "--spacing", "10", "--bins", "128", "--max-range", "600",
            "--tile-points", "1500"]


@pytest.mark.slow
def test_killed_build_resumes_to_the_same_bank(fifteen_tiles, tmp_path):
    run_infer([*fifteen_tiles, "--out", str(tmp_path / "whole")])
    hit = kill_and_resume([*fifteen_tiles, "--out", str(tmp_path / "killed")], tmp_path / "killed", kills=3, seed=1,
                          max_extra_s=0.3)
    assert hit == 3
    whole = tree_bytes(tmp_path / "whole")
    assert len(whole) == 1 + 2 * 15 and tree_bytes(tmp_path / "killed") == whole


@pytest.mark.slow
def test_distributed_build_equals_one_process(fifteen_tiles, tmp_path):
    """``--devices 2``: two CPU processes (Lightning DDP, gloo) write the same bank, byte for byte."""
    run_infer([*fifteen_tiles, "--out", str(tmp_path / "one")])
    run_infer([*fifteen_tiles, "--devices", "2", "--out", str(tmp_path / "two")])
    one = tree_bytes(tmp_path / "one")
    assert len(one) == 1 + 2 * 15 and tree_bytes(tmp_path / "two") == one

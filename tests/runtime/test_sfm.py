"""The runtime's numpy Bundler and BAL readers give the same reconstructions and tracks as ``data.sfm``."""

import numpy as np
import pytest

from core.errors import InputError
from data.sfm.bal import read_bal as torch_read_bal
from data.sfm.bundler import read_bundler as torch_read_bundler
from runtime.sfm import read_bal, read_bundler
from tests.cli.test_triangulate import write_bundler


def _same_tracks(recon, reference, views: int) -> None:
    for got, want in zip(recon.tracks(views), reference.tracks(views), strict=True):
        np.testing.assert_allclose(got, want.numpy(), rtol=1e-12, atol=1e-9)


def test_bundler_reader_matches_data_sfm(tmp_path) -> None:
    write_bundler(tmp_path / "cube.out", points=20)
    recon, reference = read_bundler(tmp_path / "cube.out"), torch_read_bundler(tmp_path / "cube.out")
    np.testing.assert_array_equal(recon.colors, reference.colors.numpy())
    np.testing.assert_allclose(recon.rotation, reference.rotation.numpy())
    _same_tracks(recon, reference, 3)


def test_shared_reconstructions_match_data_sfm(shared_data) -> None:
    path = shared_data / "sfm" / "Balbianello.out"
    _same_tracks(read_bundler(path), torch_read_bundler(path), 3)
    bal = shared_data / "sfm" / "dubrovnik-3-7-pre.txt"
    recon, reference = read_bal(bal), torch_read_bal(bal)
    np.testing.assert_allclose(recon.rotation, reference.rotation.numpy(), atol=1e-12)
    _same_tracks(recon, reference, 2)


def test_reader_errors_name_the_file_and_line(tmp_path) -> None:
    (tmp_path / "bad.out").write_text("# Bundle file v0.3\n1 0\n500 0 zero\n")
    with pytest.raises(InputError, match=r"bad.out:3: expected a number for camera 0, got 'zero'"):
        read_bundler(tmp_path / "bad.out")
    (tmp_path / "other.out").write_text("ply\n")
    with pytest.raises(InputError, match="not a Bundler file"):
        read_bundler(tmp_path / "other.out")
    write_bundler(tmp_path / "cube.out", points=3)
    with pytest.raises(InputError, match="views must be at least 2"):
        read_bundler(tmp_path / "cube.out").tracks(1)

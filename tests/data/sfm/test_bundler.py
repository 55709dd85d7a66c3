"""Bundler v0.3 reader: the shared Balbianello reconstruction, a small hand-written file, corrupt files."""

import pytest

from core.errors import InputError
from data.sfm.bundler import read_bundler


def test_bundler_reference_points_reproject_to_subpixel(shared_data, reproject_distorted):
    recon = read_bundler(shared_data / "sfm" / "Balbianello.out")
    assert recon.focal.shape == (5,) and recon.points.shape == (544, 3)
    err = (reproject_distorted(recon) - recon.obs_xy).norm(dim=-1)
    assert 0.05 < err.median() < 0.3  # the data README: about 0.13 px after bundle adjustment
    P, x, reference, index = recon.tracks(3)
    assert P.shape == (225, 3, 3, 4) and x.shape == (225, 3, 2) and len(index) == 225


BUNDLER = """# Bundle file v0.3
2 2
500 0 0
1 0 0
0 1 0
0 0 1
0 0 -5
0 0 0
0 0 0
0 0 0
0 0 0
0 0 0
0.1 0.2 0.3
255 0 0
2 0 1 10.5 -3.5 1 2 11 4
0 0 0
1 1 1
1 0 3 1 1
"""


def test_bundler_small_file_and_unregistered_camera(tmp_path):
    path = tmp_path / "small.out"
    path.write_text(BUNDLER)
    recon = read_bundler(path)
    assert recon.registered.tolist() == [True, False]
    assert recon.obs_xy.tolist() == [[10.5, -3.5], [11.0, 4.0], [1.0, 1.0]]
    P, _, _, _ = recon.tracks(2)
    assert P.shape[0] == 0  # point 0 has only one registered view


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (BUNDLER.replace("0.1 0.2 0.3", "0.1 zz 0.3"), r"small.out:13: expected a number"),
        (BUNDLER.replace("2 0 1 10.5", "2 7 1 10.5"), r"small.out:15: point 0 refers to camera 7"),
        (BUNDLER[: BUNDLER.index("1 1 1")], r"file ends early .* point 1"),
        ("hello\n", r"small.out:1: not a Bundler file"),
        (BUNDLER + "9\n", r"small.out:19: unexpected trailing data"),
    ],
)
def test_corrupt_bundler_files_name_the_line(tmp_path, text, message):
    path = tmp_path / "small.out"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_bundler(path)

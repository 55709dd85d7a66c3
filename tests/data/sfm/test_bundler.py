import pytest
import torch

from core.errors import InputError
from data.sfm.bal import read_bal
from data.sfm.bundler import read_bundler
from data.sfm.reconstruction import Reconstruction, undistort_radial


def reproject_distorted(recon: Reconstruction) -> torch.Tensor:
    """Forward camera model of the format, written out directly: (K, 2) predicted observations."""
    R = recon.rotation[recon.obs_camera]
    t = recon.translation[recon.obs_camera]
    Xc = torch.einsum("kij,kj->ki", R, recon.points[recon.obs_point]) + t
    p = -Xc[:, :2] / Xc[:, 2:]
    r2 = p.square().sum(-1, keepdim=True)
    k = recon.radial[recon.obs_camera]
    return recon.focal[recon.obs_camera, None] * (1 + k[:, :1] * r2 + k[:, 1:] * r2.square()) * p


def test_undistortion_inverts_the_distortion_model():
    g = torch.Generator().manual_seed(0)
    p = (torch.rand(500, 2, generator=g, dtype=torch.float64) - 0.5) * 0.8
    f = torch.full((500,), 500.0, dtype=torch.float64)
    k = torch.tensor([[-0.12, 0.03]], dtype=torch.float64).expand(500, 2)
    r2 = p.square().sum(-1, keepdim=True)
    distorted = f[:, None] * (1 + k[:, :1] * r2 + k[:, 1:] * r2.square()) * p
    torch.testing.assert_close(undistort_radial(distorted, f, k), f[:, None] * p, rtol=0, atol=1e-8)


def test_bundler_reference_points_reproject_to_subpixel(shared_data):
    recon = read_bundler(shared_data / "sfm" / "Balbianello.out")
    assert recon.focal.shape == (5,) and recon.points.shape == (544, 3)
    err = (reproject_distorted(recon) - recon.obs_xy).norm(dim=-1)
    assert 0.05 < err.median() < 0.3  # the data README: about 0.13 px after bundle adjustment
    P, x, reference, index = recon.tracks(3)
    assert P.shape == (225, 3, 3, 4) and x.shape == (225, 3, 2) and len(index) == 225


def test_bal_reader_parses_pre_bundle_adjustment_problem(shared_data):
    recon = read_bal(shared_data / "sfm" / "dubrovnik-3-7-pre.txt")
    assert recon.focal.shape == (3,) and recon.points.shape == (7, 3) and recon.obs_xy.shape == (19, 2)
    err = (reproject_distorted(recon) - recon.obs_xy).norm(dim=-1)
    assert 5 < err.median() < 20  # before bundle adjustment: about 11 px


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


def test_bal_errors_name_the_line(tmp_path):
    path = tmp_path / "p.txt"
    path.write_text("1 1 1\n\n0 0 1.0 2.0\n0 0 0 0 0 0 500 0\n")
    with pytest.raises(InputError, match=r"p.txt:4: .* camera 0|file ends early .*camera 0"):
        read_bal(path)
    with pytest.raises(InputError, match="no such file"):
        read_bal(tmp_path / "missing.txt")

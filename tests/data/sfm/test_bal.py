"""BAL reader: the shared Dubrovnik problem before bundle adjustment, and errors that name the line."""

import pytest

from core.errors import InputError
from data.sfm.bal import read_bal


def test_bal_reader_parses_pre_bundle_adjustment_problem(shared_data, reproject_distorted):
    recon = read_bal(shared_data / "sfm" / "dubrovnik-3-7-pre.txt")
    assert recon.focal.shape == (3,) and recon.points.shape == (7, 3) and recon.obs_xy.shape == (19, 2)
    err = (reproject_distorted(recon) - recon.obs_xy).norm(dim=-1)
    assert 5 < err.median() < 20  # before bundle adjustment: about 11 px


def test_bal_errors_name_the_line(tmp_path):
    path = tmp_path / "p.txt"
    path.write_text("1 1 1\n\n0 0 1.0 2.0\n0 0 0 0 0 0 500 0\n")
    with pytest.raises(InputError, match=r"p.txt:4: .* camera 0|file ends early .*camera 0"):
        read_bal(path)
    with pytest.raises(InputError, match="no such file"):
        read_bal(tmp_path / "missing.txt")

"""ASCII PLY writer: header, points and colours read back, no partial file left, a missing folder named."""

import numpy as np
import pytest
import torch

from core.errors import InputError
from data.sfm.ply import write_ply


def test_points_and_colours_read_back(tmp_path):
    points = torch.tensor([[0.5, -1.25, 3.0], [1e-3, 2.0, -4.5]], dtype=torch.float64)
    colors = torch.tensor([[255, 0, 10], [1, 2, 3]], dtype=torch.uint8)
    write_ply(tmp_path / "p.ply", points, colors)
    lines = (tmp_path / "p.ply").read_text().splitlines()
    end = lines.index("end_header")
    assert lines[:3] == ["ply", "format ascii 1.0", "element vertex 2"] and "property uchar red" in lines[:end]
    rows = np.loadtxt(lines[end + 1 :])
    np.testing.assert_allclose(rows[:, :3], points.numpy(), rtol=1e-9)
    assert rows[:, 3:].tolist() == colors.tolist()
    assert [p.name for p in tmp_path.iterdir()] == ["p.ply"]  # written under a temporary name, then renamed


def test_points_only_and_missing_folder(tmp_path):
    write_ply(tmp_path / "q.ply", torch.zeros(3, 3))
    lines = (tmp_path / "q.ply").read_text().splitlines()
    end = lines.index("end_header")
    assert "property uchar red" not in lines[:end] and len(lines) - end - 1 == 3
    with pytest.raises(InputError, match="does not exist"):
        write_ply(tmp_path / "none" / "x.ply", torch.zeros(1, 3))

"""Point files: every format :func:`core.frames.read_points` documents, and its refusals."""

import numpy as np
import pytest

from core.errors import InputError
from core.frames import read_points

POINTS = np.array([[10.5, 20.0], [3.0, 4.25], [100.0, 0.0]])


@pytest.mark.parametrize(
    "name, text",
    [
        ("points.txt", "10.5 20\n3 4.25\n100 0\n"),
        ("points.txt", "# x y\n10.5, 20\n3 4.25\n\n100,0  # last\n"),
        ("points.csv", "10.5,20\n3,4.25\n100,0\n"),
    ],
)
def test_text_points_with_blanks_commas_and_comments(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    np.testing.assert_array_equal(read_points(path), POINTS)


def test_numpy_points(tmp_path):
    np.save(tmp_path / "p.npy", POINTS.astype(np.float32))
    np.testing.assert_allclose(read_points(tmp_path / "p.npy"), POINTS)
    np.savez(tmp_path / "named.npz", other=np.zeros((1, 2)), points=POINTS)
    np.testing.assert_array_equal(read_points(tmp_path / "named.npz"), POINTS)  # "points" before the first array
    np.savez(tmp_path / "first.npz", POINTS, np.zeros((1, 2)))
    np.testing.assert_array_equal(read_points(tmp_path / "first.npz"), POINTS)


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("p.txt", "1 2 3\n", r"\(P, 2\)"),
        ("p.txt", "1 two\n", "cannot read points"),
        ("p.txt", "", "empty"),
        ("p.txt", "1 nan\n", "NaN"),
        ("p.txt", b"\xff\xfe\x00binary", "cannot read points"),
    ],
)
def test_bad_point_files_are_refused_naming_the_file(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(InputError, match=message) as err:
        read_points(path)
    assert str(path) in str(err.value)
    with pytest.raises(InputError, match="not found"):
        read_points(tmp_path / "missing.txt")

"""Frames from a video file, and point files: every format :func:`core.frames.read_points` documents, and its
refusals."""

import cv2
import numpy as np
import pytest

from core.errors import InputError
from core.frames import read_frames, read_points

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


def test_a_missing_point_file_is_named(tmp_path):
    with pytest.raises(InputError, match=f"not found: {tmp_path / 'missing.txt'}"):
        read_points(tmp_path / "missing.txt")


def test_video_frames_decode_close_to_the_frames_written(tmp_path):
    # smooth gray frames through a lossy MPEG-4 file: the decoded gray frames stay within a few gray levels
    y, x = np.mgrid[0:64, 0:96]
    written = [(128 + 80 * np.sin(x / 9.0 + t) * np.cos(y / 13.0)).astype(np.uint8) for t in range(5)]
    video = tmp_path / "clip.MP4"  # the suffix in any case
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (96, 64))
    for frame in written:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
    writer.release()
    frames, names = read_frames(video)
    assert [str(n) for n in names] == [f"{video}#{t}" for t in range(5)]
    for frame, truth in zip(frames, written, strict=True):
        assert frame.dtype == np.float32 and frame.shape == (64, 96)
        assert np.abs(frame - truth).mean() < 4.0
    assert len(read_frames(video, limit=2)[0]) == 2
    (tmp_path / "broken.avi").write_bytes(b"RIFF not a video")
    with pytest.raises(InputError, match="broken.avi: not a readable video"):
        read_frames(tmp_path / "broken.avi")

"""Middlebury .flo reading and writing, corrupt files, and the real Sintel flow against OpenCV's reader."""

import struct

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.flow import read_flo, write_flo


def _flo_bytes(flow: np.ndarray) -> bytes:
    h, w = flow.shape[:2]
    return struct.pack("<fii", 202021.25, w, h) + flow.astype("<f4").tobytes()


def test_read_handmade_file(tmp_path):
    flow = np.random.default_rng(0).normal(size=(3, 5, 2)).astype(np.float32)
    flow[1, 2] = [1e10, 1e10]
    (tmp_path / "a.flo").write_bytes(_flo_bytes(flow))
    got = read_flo(tmp_path / "a.flo")
    assert got.shape == (3, 5, 2)
    assert np.isnan(got[1, 2]).all()
    mask = ~np.isnan(got)
    np.testing.assert_array_equal(got[mask], flow[mask])


def test_round_trip(tmp_path):
    flow = np.random.default_rng(1).normal(size=(4, 6, 2)).astype(np.float32)
    flow[0, 0, 1] = np.nan
    write_flo(tmp_path / "b.flo", flow)
    np.testing.assert_array_equal(read_flo(tmp_path / "b.flo"), flow)


@pytest.mark.parametrize(
    "content, message",
    [
        (b"abc", "not a .flo"),
        (struct.pack("<fii", 1.0, 2, 2) + bytes(32), "magic"),
        (struct.pack("<fii", 202021.25, 4, 4) + bytes(40), "truncated"),
        (struct.pack("<fii", 202021.25, -1, 4), "implausible"),
    ],
)
def test_corrupt_files_are_rejected(tmp_path, content, message):
    path = tmp_path / "bad.flo"
    path.write_bytes(content)
    with pytest.raises(InputError, match=message):
        read_flo(path)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_flo(tmp_path / "missing.flo")


def test_sintel_flow_matches_opencv(shared_data):
    path = shared_data / "sintel" / "alley_1" / "clean" / "gt" / "frame_0002.flo"
    got = read_flo(path)
    assert got.shape == (436, 1024, 2)
    np.testing.assert_array_equal(got, cv2.readOpticalFlow(str(path)))

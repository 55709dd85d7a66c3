"""Sintel folder reader on the shared alley_1 data and on malformed folders."""

import cv2
import numpy as np
import pytest

from core.errors import InputError
from data.flow import read_sintel_pair, read_sintel_sequence, write_flo


def test_alley_pair(shared_data):
    pair = read_sintel_pair(shared_data / "sintel" / "alley_1" / "final")
    assert pair.frame0.shape == pair.frame1.shape == pair.bad.shape == (436, 1024)
    assert pair.flow.shape == (436, 1024, 2)
    assert 0.0 < pair.bad.mean() < 0.5
    assert pair.frame0.dtype == np.float32 and 0 <= pair.frame0.min() and pair.frame0.max() <= 255


def test_missing_and_mismatched(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_sintel_pair(tmp_path / "nope")
    (tmp_path / "gt").mkdir()
    with pytest.raises(InputError, match="no gt"):
        read_sintel_pair(tmp_path)
    write_flo(tmp_path / "gt" / "frame_0001.flo", np.zeros((8, 10, 2), np.float32))
    cv2.imwrite(str(tmp_path / "frame_0001.png"), np.zeros((8, 10), np.uint8))
    cv2.imwrite(str(tmp_path / "frame_0002.png"), np.zeros((9, 10), np.uint8))
    with pytest.raises(InputError, match="differ in size"):
        read_sintel_pair(tmp_path)


def test_sequence_chains_consecutive_flows(tmp_path):
    (tmp_path / "gt").mkdir()
    for f in range(3, 7):
        cv2.imwrite(str(tmp_path / f"frame_{f:04d}.png"), np.full((12, 16), 10 * f, np.uint8))
    for f in (3, 4, 5):
        write_flo(tmp_path / "gt" / f"frame_{f:04d}.flo", np.full((12, 16, 2), f, np.float32))
    pairs = read_sintel_sequence(tmp_path)
    assert len(pairs) == 3 and [p.flow[0, 0, 0] for p in pairs] == [3, 4, 5]
    assert pairs[-1].frame1[0, 0] == 60
    assert len(read_sintel_sequence(tmp_path, max_pairs=2)) == 2

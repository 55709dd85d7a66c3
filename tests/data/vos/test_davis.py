"""DAVIS reader on crafted 2016 / 2017 layouts and on ../shared/data/davis2016."""

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from core.errors import InputError
from data.vos.davis import davis_sequences
from data.vos.io import write_mask


def make_davis(root: Path, res: str, split_lines: list[str], gray: bool) -> None:
    for seq in ("a", "b"):
        (root / "JPEGImages" / res / seq).mkdir(parents=True)
        (root / "Annotations" / res / seq).mkdir(parents=True)
        for t in range(3):
            frame = Image.fromarray(np.full((6, 8, 3), 40 * t, np.uint8))
            frame.save(root / "JPEGImages" / res / seq / f"{t:05d}.jpg")
            labels = np.zeros((6, 8), np.uint8)
            labels[1:3, 2:5] = 1
            labels[4, 4] = 2
            if gray:
                Image.fromarray((labels > 0).astype(np.uint8) * 255).save(
                    root / "Annotations" / res / seq / f"{t:05d}.png"
                )
            else:
                write_mask(root / "Annotations" / res / seq / f"{t:05d}.png", torch.from_numpy(labels))
    (root / "ImageSets" / res).mkdir(parents=True)
    (root / "ImageSets" / res / "val.txt").write_text("\n".join(split_lines) + "\n")


def test_davis_2017_layout_names_split(tmp_path: Path) -> None:
    make_davis(tmp_path, "480p", ["a", "b"], gray=False)
    seqs = davis_sequences(tmp_path, "val", "480p")
    assert [s.name for s in seqs] == ["a", "b"] and len(seqs[0]) == 3
    frames, labels = seqs[1].load()
    assert frames.shape == (3, 3, 6, 8) and frames.dtype == torch.uint8
    assert labels.shape == (3, 6, 8) and set(labels.unique().tolist()) == {0, 1, 2}


def test_davis_2016_layout_frame_lines_and_gray_masks(tmp_path: Path) -> None:
    lines = [f"/JPEGImages/480p/{s}/0000{t}.jpg /Annotations/480p/{s}/0000{t}.png" for s in "ba" for t in "0"]
    make_davis(tmp_path, "480p", lines, gray=True)
    seqs = davis_sequences(tmp_path, "val", "480p", names=["a"])
    assert [s.name for s in seqs] == ["a"]
    _, labels = seqs[0].load()
    assert set(labels.unique().tolist()) == {0, 1}


def test_reader_errors(tmp_path: Path) -> None:
    make_davis(tmp_path, "480p", ["a", "b"], gray=False)
    with pytest.raises(InputError, match="split 'train'"):
        davis_sequences(tmp_path, "train", "480p")
    with pytest.raises(InputError, match="JPEGImages/240p"):
        davis_sequences(tmp_path, "val", "240p")
    (tmp_path / "Annotations/480p/a/00000.png").unlink()
    with pytest.raises(InputError, match="first-frame annotation"):
        davis_sequences(tmp_path, "val", "480p")
    write_mask(tmp_path / "Annotations/480p/b/00001.png", torch.zeros(5, 8, dtype=torch.long))
    with pytest.raises(InputError, match="00001.png is"):
        davis_sequences(tmp_path, "val", "480p", names=["b"])[0].load()


def test_shared_davis2016_240p(shared_data: Path) -> None:
    seqs = davis_sequences(shared_data / "davis2016", "train", "240p")
    assert len(seqs) == 30 and sum(len(s) for s in seqs) == 2079
    frames, labels = seqs[0].load(max_frames=2)
    assert frames.shape == (2, 3, 240, 427) and set(labels.unique().tolist()) == {0, 1}

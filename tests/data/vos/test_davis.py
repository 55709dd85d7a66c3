"""DAVIS / YouTube-VOS readers and mask I/O on crafted layouts and on ../shared/data/davis2016."""

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from core.errors import InputError
from data.vos.davis import davis_sequences
from data.vos.io import davis_palette, read_frame, read_mask, write_mask
from data.vos.ytvos import first_frames, ytvos_sequences


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


def test_palette_roundtrip_and_davis_colours(tmp_path: Path) -> None:
    labels = torch.tensor([[0, 1, 2], [3, 255, 0]])
    write_mask(tmp_path / "m.png", labels)
    image = Image.open(tmp_path / "m.png")
    assert image.mode == "P" and image.getpalette()[3:9] == [128, 0, 0, 0, 128, 0]
    assert torch.equal(read_mask(tmp_path / "m.png"), labels)
    assert davis_palette()[765:768] == [224, 224, 192]  # void colour of index 255


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
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="cannot be read"):
        read_frame(tmp_path / "bad.png")
    with pytest.raises(InputError, match="does not exist"):
        read_mask(tmp_path / "missing.png")
    write_mask(tmp_path / "Annotations/480p/b/00001.png", torch.zeros(5, 8, dtype=torch.long))
    with pytest.raises(InputError, match="00001.png is"):
        davis_sequences(tmp_path, "val", "480p", names=["b"])[0].load()


def test_ytvos_layout_sparse_annotations(tmp_path: Path) -> None:
    base = tmp_path / "train"
    (base / "JPEGImages/v1").mkdir(parents=True)
    (base / "Annotations/v1").mkdir(parents=True)
    for t in range(0, 15, 5):
        Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(base / f"JPEGImages/v1/{t:05d}.jpg")
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(base / "JPEGImages/v1/00001.jpg")
    write_mask(base / "Annotations/v1/00000.png", torch.ones(4, 4, dtype=torch.long))
    (base / "meta.json").write_text(json.dumps({"videos": {"v1": {"objects": {"1": {"frames": ["00000"]}}}}}))
    seq = ytvos_sequences(tmp_path, "train")[0]
    assert [m is not None for m in seq.masks] == [True, False, False, False]
    _, labels = seq.load()
    assert labels[0].eq(1).all() and labels[1].eq(-1).all()
    assert first_frames(tmp_path, "train") == {"v1": {1: "00000"}}


def test_shared_davis2016_240p(shared_data: Path) -> None:
    seqs = davis_sequences(shared_data / "davis2016", "train", "240p")
    assert len(seqs) == 30 and sum(len(s) for s in seqs) == 2079
    frames, labels = seqs[0].load(max_frames=2)
    assert frames.shape == (2, 3, 240, 427) and set(labels.unique().tolist()) == {0, 1}

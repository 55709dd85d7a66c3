"""YouTube-VOS reader: sparse annotations and the first frame of each object."""

import json
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from data.vos.io import write_mask
from data.vos.ytvos import first_frames, ytvos_sequences


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

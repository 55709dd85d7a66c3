"""VOS frames and masks in numpy: the palette PNGs written here read back (with PIL too) as the same labels,
PIL's palette PNGs and gray masks read as ``data.vos.io`` reads them, the DAVIS palette, bad files."""

import numpy as np
import pytest
import torch
from PIL import Image

from core.errors import InputError
from data.vos import io
from runtime.vos_io import davis_palette, list_frames, read_frame, read_mask, write_mask


def test_palette_masks_round_trip_both_ways(tmp_path) -> None:
    labels = np.random.default_rng(0).integers(0, 4, (30, 40))
    labels[0, 0] = 255  # void
    write_mask(tmp_path / "ours.png", labels)
    io.write_mask(tmp_path / "pil.png", torch.from_numpy(labels))
    assert Image.open(tmp_path / "ours.png").mode == "P"
    np.testing.assert_array_equal(io.read_mask(tmp_path / "ours.png").numpy(), labels)
    np.testing.assert_array_equal(read_mask(tmp_path / "pil.png"), labels)
    np.testing.assert_array_equal(read_mask(tmp_path / "ours.png"), labels)
    assert davis_palette().ravel().tolist() == io.davis_palette()


def test_gray_masks_and_frames_read_like_data_vos_io(tmp_path) -> None:
    gray = (np.random.default_rng(1).random((20, 24)) > 0.5).astype(np.uint8) * 255
    Image.fromarray(gray).save(tmp_path / "gray.png")
    np.testing.assert_array_equal(read_mask(tmp_path / "gray.png"), io.read_mask(tmp_path / "gray.png").numpy())
    rgb = np.random.default_rng(2).integers(0, 256, (20, 24, 3), dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "frame.png")
    np.testing.assert_array_equal(read_frame(tmp_path / "frame.png"), io.read_frame(tmp_path / "frame.png").numpy())
    assert list_frames(tmp_path) == sorted(tmp_path.glob("*.png"))


def test_bad_files_are_named(tmp_path) -> None:
    (tmp_path / "bad.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(InputError, match="bad.png cannot be read"):
        read_mask(tmp_path / "bad.png")
    with pytest.raises(InputError, match="bad.png does not exist or cannot be read"):
        read_frame(tmp_path / "bad.png")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="holds no"):
        list_frames(tmp_path / "empty")
    with pytest.raises(InputError, match="values 0..255"):
        write_mask(tmp_path / "x.png", np.full((2, 2), 300))

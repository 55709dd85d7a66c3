"""Frame and palette-mask I/O: round trip with the DAVIS colours, unreadable and missing files."""

from pathlib import Path

import pytest
import torch
from PIL import Image

from core.errors import InputError
from data.vos.io import davis_palette, read_frame, read_mask, write_mask


def test_palette_roundtrip_and_davis_colours(tmp_path: Path) -> None:
    labels = torch.tensor([[0, 1, 2], [3, 255, 0]])
    write_mask(tmp_path / "m.png", labels)
    image = Image.open(tmp_path / "m.png")
    assert image.mode == "P" and image.getpalette()[3:9] == [128, 0, 0, 0, 128, 0]
    assert torch.equal(read_mask(tmp_path / "m.png"), labels)
    assert davis_palette()[765:768] == [224, 224, 192]  # void colour of index 255


def test_read_errors(tmp_path: Path) -> None:
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="cannot be read"):
        read_frame(tmp_path / "bad.png")
    with pytest.raises(InputError, match="does not exist"):
        read_mask(tmp_path / "missing.png")

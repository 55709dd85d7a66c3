"""Frame and mask files of VOS datasets: JPEG/PNG frames, gray (DAVIS 2016) and palette (DAVIS 2017,
YouTube-VOS) label masks, and the sequence record the readers return.

Label maps are (H, W) int64 tensors: 0 = background, 1..N = objects, 255 = void (palette masks only).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from PIL import Image, UnidentifiedImageError

from core.errors import InputError
from core.files import atomic_path

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")


def davis_palette() -> list[int]:
    """The 256-colour DAVIS/PASCAL palette (bit-interleaved colour map) as a flat RGB list."""
    palette = []
    for i in range(256):
        r = g = b = 0
        c = i
        for j in range(8):
            r |= ((c >> 0) & 1) << (7 - j)
            g |= ((c >> 1) & 1) << (7 - j)
            b |= ((c >> 2) & 1) << (7 - j)
            c >>= 3
        palette += [r, g, b]
    return palette


def _open(path: Path, what: str) -> Image.Image:
    if not path.is_file():
        raise InputError(f"{what} {path} does not exist")
    try:
        image = Image.open(path)
        image.load()
    except (UnidentifiedImageError, OSError) as err:
        raise InputError(f"{what} {path} cannot be read as an image ({err})") from err
    return image


def read_frame(path: str | Path) -> torch.Tensor:
    """Read an RGB frame as a (3, H, W) uint8 tensor."""
    image = _open(Path(path), "frame").convert("RGB")
    return torch.from_numpy(np.asarray(image).copy()).permute(2, 0, 1).contiguous()


def read_mask(path: str | Path) -> torch.Tensor:
    """Read a label mask as an (H, W) int64 tensor.

    Palette ('P') PNGs give their indices (DAVIS 2017, YouTube-VOS; 255 = void). Gray or colour masks are
    binary (DAVIS 2016: 255 = object): any channel above 127 is object 1.
    """
    image = _open(Path(path), "mask")
    if image.mode == "P":
        array = np.asarray(image).astype(np.int64)
    else:
        gray = np.asarray(image.convert("RGB")).max(axis=2)
        array = (gray > 127).astype(np.int64)
    return torch.from_numpy(array.copy())


def write_mask(path: str | Path, labels: torch.Tensor) -> None:
    """Write an (H, W) label map (values 0..255) as a palette PNG with the DAVIS colours (atomically)."""
    if labels.ndim != 2:
        raise InputError(f"a label map must be (H, W), got shape {tuple(labels.shape)}")
    image = Image.fromarray(labels.to(torch.uint8).cpu().numpy(), mode="P")
    image.putpalette(davis_palette())
    with atomic_path(path) as tmp:
        image.save(tmp, format="PNG")


def list_frames(directory: str | Path) -> list[Path]:
    """Image files of a video folder, sorted by name."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"video folder {directory} does not exist")
    frames = sorted(p for p in directory.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not frames:
        raise InputError(f"video folder {directory} holds no {'/'.join(IMAGE_SUFFIXES)} images")
    return frames


@dataclass
class VOSSequence:
    """One video: its frame files and, per frame, the annotation file or None where not annotated."""

    name: str
    frames: list[Path]
    masks: list[Path | None] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.frames)

    def load(self, max_frames: int | None = None) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Frames (T, 3, H, W) uint8 and label maps (T, H, W) int64 (-1 where a frame has no annotation, None
        if no frame is annotated); masks of another size than the frames raise ``InputError``."""
        n = len(self.frames) if max_frames is None else min(max_frames, len(self.frames))
        frames = torch.stack([read_frame(p) for p in self.frames[:n]])
        masks = self.masks[:n]
        if not any(m is not None for m in masks):
            return frames, None
        h, w = frames.shape[-2:]
        labels = torch.full((n, h, w), -1, dtype=torch.int64)
        for t, path in enumerate(masks):
            if path is None:
                continue
            mask = read_mask(path)
            if mask.shape != (h, w):
                raise InputError(f"mask {path} is {tuple(mask.shape)} but frame {self.frames[t]} is {(h, w)}")
            labels[t] = mask
        return frames, labels

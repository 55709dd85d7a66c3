"""Frames and label masks of VOS videos in numpy and OpenCV (the runtime's counterpart of ``data.vos.io``): RGB
frames, gray (DAVIS 2016) and palette (DAVIS 2017, YouTube-VOS) masks, and palette PNGs written with the DAVIS
colours (OpenCV cannot write indexed PNGs, so the few PNG chunks are written here with ``zlib``).

Label maps are (H, W) int64 arrays: 0 = background, 1..N = objects, 255 = void (palette masks only).
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError
from core.files import write_bytes

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def davis_palette() -> np.ndarray:
    """The 256-colour DAVIS/PASCAL palette (bit-interleaved colour map), (256, 3) uint8 RGB."""
    index = np.arange(256)
    palette = np.zeros((256, 3), np.int64)
    for j in range(8):
        for channel in range(3):
            palette[:, channel] |= ((index >> (3 * j + channel)) & 1) << (7 - j)
    return palette.astype(np.uint8)


def list_frames(directory: str | Path) -> list[Path]:
    """Image files of a video folder, sorted by name."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"video folder {directory} does not exist")
    frames = sorted(p for p in directory.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not frames:
        raise InputError(f"video folder {directory} holds no {'/'.join(IMAGE_SUFFIXES)} images")
    return frames


def read_frame(path: str | Path) -> np.ndarray:
    """An RGB frame as a (3, H, W) uint8 array."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"frame {path} does not exist or cannot be read as an image")
    return np.ascontiguousarray(image[..., ::-1].transpose(2, 0, 1))


def _png_palette(data: bytes) -> np.ndarray | None:
    """(P, 3) uint8 palette of an indexed PNG (colour type 3), None for other PNGs."""
    if not data.startswith(PNG_SIGNATURE) or len(data) < 33 or data[25] != 3:  # IHDR colour type
        return None
    at = 8
    while at + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[at : at + 8])
        if kind == b"PLTE":
            return np.frombuffer(data[at + 8 : at + 8 + length], np.uint8).reshape(-1, 3)
        at += 12 + length
    return None


def _rgb_code(rgb: np.ndarray) -> np.ndarray:
    """One int64 per colour of (..., 3) uint8 RGB."""
    rgb = rgb.astype(np.int64)
    return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]


def read_mask(path: str | Path) -> np.ndarray:
    """A label mask as an (H, W) int64 array: an indexed PNG gives its palette indices (the first index of each
    colour; 255 = void), gray or colour masks are binary (any channel above 127 is object 1)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"mask {path} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"mask {path} cannot be read as an image")
    palette = _png_palette(path.read_bytes())
    if palette is None:
        return (image.max(axis=2) > 127).astype(np.int64)
    colours, first = np.unique(_rgb_code(palette), return_index=True)
    pixels = _rgb_code(image[..., ::-1])
    slot = np.clip(np.searchsorted(colours, pixels), 0, len(colours) - 1)
    if not np.array_equal(colours[slot], pixels):
        raise InputError(f"mask {path} has colours outside its palette")
    return first[slot].astype(np.int64)


def _chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def palette_png(labels: np.ndarray) -> bytes:
    """The bytes of an indexed PNG of an (H, W) label map (values 0..255) with the DAVIS palette."""
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.min(initial=0) < 0 or labels.max(initial=0) > 255:
        raise InputError(f"a label map must be (H, W) with values 0..255, got shape {labels.shape}")
    h, w = labels.shape
    rows = np.concatenate([np.zeros((h, 1), np.uint8), labels.astype(np.uint8)], 1)  # filter byte 0 per row
    header = struct.pack(">IIBBBBB", w, h, 8, 3, 0, 0, 0)
    return (PNG_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"PLTE", davis_palette().tobytes())
            + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _chunk(b"IEND", b""))


def write_mask(path: str | Path, labels: np.ndarray) -> None:
    """Write an (H, W) label map as a palette PNG with the DAVIS colours (atomically)."""
    write_bytes(path, palette_png(labels))

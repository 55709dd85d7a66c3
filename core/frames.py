"""Gray frames, frame folders or glob patterns, and point lists (the ``track`` command and the runtime's
point tracker). Torch-free."""

from __future__ import annotations

import glob
import warnings
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


def read_frame_gray(path: str | Path) -> np.ndarray:
    """Read an image file as a ``(H, W)`` float32 gray frame in [0, 255]."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"frame not found: {path}")
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise InputError(f"{path}: not a readable image")
    return image.astype(np.float32)


def frame_paths(spec: str | Path) -> list[Path]:
    """Image files of a folder (sorted by name) or of a glob pattern such as ``clip/*.png``."""
    path = Path(spec)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    else:
        files = sorted(Path(p) for p in glob.glob(str(spec)) if Path(p).suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError(f"no image frames found at {spec}")
    return files


def read_frames(spec: str | Path, limit: int | None = None) -> tuple[list[np.ndarray], list[Path]]:
    """Gray frames ``(H, W)`` float32 in [0, 255] of a folder or glob, all of one size, and their paths (the first
    ``limit`` only, if given)."""
    paths = frame_paths(spec)[:limit]
    frames = [read_frame_gray(p) for p in paths]
    for path, frame in zip(paths, frames, strict=True):
        if frame.shape != frames[0].shape:
            raise InputError(f"frame {path} has size {frame.shape}, {paths[0]} has {frames[0].shape}")
    return frames, paths


def read_points(path: str | Path) -> np.ndarray:
    """``(P, 2)`` (x, y) points from ``.npy``, ``.npz`` (array ``points`` or the first one) or text (two
    numbers per line, separated by spaces or commas; ``#`` comments)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"points file not found: {path}")
    try:
        if path.suffix == ".npy":
            points = np.load(path)
        elif path.suffix == ".npz":
            with np.load(path) as data:
                points = data["points"] if "points" in data else data[data.files[0]]
        else:  # commas read as blanks, so "x, y" and "x y" lines may mix
            lines = path.read_text().replace(",", " ").splitlines()
            with warnings.catch_warnings():  # an empty file is reported below, not as a warning
                warnings.simplefilter("ignore", UserWarning)
                points = np.loadtxt(lines, ndmin=2)
    except (ValueError, OSError, IndexError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: cannot read points ({err})") from err
    points = np.asarray(points, dtype=np.float64)
    if points.size == 0:
        raise InputError(f"{path}: the point set is empty")
    if points.ndim != 2 or points.shape[1] != 2:
        raise InputError(f"{path}: points must be (P, 2) (x, y), got shape {points.shape}")
    if not np.isfinite(points).all():
        raise InputError(f"{path}: points contain NaN or infinity")
    return points

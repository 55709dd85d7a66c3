"""Gray frames, frame folders, glob patterns or video files, and point lists (the ``track`` command and the runtime's
point tracker). Torch-free."""

from __future__ import annotations

import glob
import os
import warnings
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")


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


def read_video_gray(path: str | Path, limit: int | None = None) -> list[np.ndarray]:
    """The frames of a video file (OpenCV's decoders) as ``(H, W)`` float32 gray frames in [0, 255] (the first
    ``limit`` only, if given); ``InputError`` for a file that does not open or holds no frame."""
    path = Path(path)
    # FFmpeg's own log lines would come before the one error line a bad file gets (-8: FFmpeg's AV_LOG_QUIET); read
    # when OpenCV opens its first video, so a level the user set stays
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    capture = cv2.VideoCapture(str(path))
    frames: list[np.ndarray] = []
    try:
        while capture.isOpened() and (limit is None or len(frames) < limit):
            ok, image = capture.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.float32))
    finally:
        capture.release()
    if not frames:
        raise InputError(f"{path}: not a readable video (no frame decoded)")
    return frames


def read_frames(spec: str | Path, limit: int | None = None) -> tuple[list[np.ndarray], list[Path]]:
    """Gray frames ``(H, W)`` float32 in [0, 255] of a folder, glob or video file, all of one size, and their paths
    (a video's frames as ``VIDEO#index``; the first ``limit`` only, if given)."""
    video = Path(spec)
    if video.is_file() and video.suffix.lower() in VIDEO_SUFFIXES:
        frames = read_video_gray(video, limit)
        return frames, [Path(f"{video}#{t}") for t in range(len(frames))]
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

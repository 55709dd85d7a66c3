"""Inputs and outputs of ``infer.py localize``: compass CSV, profile files, panorama folders, track CSV.

- compass CSV: a header with ``compass_deg`` and, for panoramas, ``image`` (file name in the folder); one row
  per frame, degrees clockwise from north of panorama column 0.
- profile file: ``.npz`` with ``horizon`` (T, N) tan elevations (column u at heading + 360 u / N degrees) and
  optionally ``compass_deg`` (T,); or ``.npy`` (T, N) with the headings from a compass CSV (rows in order).
- track CSV: ``name, x, y, heading_deg, psr`` per frame (map metres of the bank's DEM).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from core.errors import InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def read_compass_csv(path: str | Path, need_image: bool) -> tuple[list[str], np.ndarray]:
    """(image names or row numbers, (T,) compass degrees) of a compass CSV."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"compass CSV not found: {path}")
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or "compass_deg" not in rows[0] or (need_image and "image" not in rows[0]):
        need = "image,compass_deg" if need_image else "compass_deg"
        raise InputError(f"compass CSV {path} needs a header with {need} and at least one row")
    names, headings = [], []
    for line, row in enumerate(rows, start=2):
        try:
            headings.append(float(row["compass_deg"]))
        except (TypeError, ValueError) as err:
            message = f"compass CSV {path}, line {line}: compass_deg {row['compass_deg']!r} is not a number"
            raise InputError(message) from err
        names.append(row.get("image") or str(line - 2))
    return names, np.asarray(headings)


def read_profiles(path: str | Path, compass_csv: str | Path | None = None) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, (T, N) profiles, (T,) compass degrees) of a profile file (module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"profile file not found: {path}")
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as data:
                key = "horizon" if "horizon" in data else "profiles"
                profiles = np.asarray(data[key], dtype=np.float64)
                compass = np.asarray(data["compass_deg"], dtype=np.float64) if "compass_deg" in data else None
        elif path.suffix.lower() == ".npy":
            profiles, compass = np.asarray(np.load(path, allow_pickle=False), dtype=np.float64), None
        else:
            raise InputError(f"profile file {path}: use .npz (horizon, compass_deg) or .npy")
    except (KeyError, ValueError, OSError) as err:
        raise InputError(f"profile file {path} is not readable as profiles (horizon (T, N)): {err}") from err
    if profiles.ndim == 1:
        profiles = profiles[None]
    if profiles.ndim != 2:
        raise InputError(f"profile file {path}: profiles must be (T, N), got shape {profiles.shape}")
    if not np.isfinite(profiles).all():
        raise InputError(f"profile file {path} holds {int((~np.isfinite(profiles)).sum())} NaN or infinite values")
    names = [str(i) for i in range(len(profiles))]
    if compass_csv is not None:
        _, compass = read_compass_csv(compass_csv, need_image=False)
    if compass is None:
        raise InputError(f"profile file {path} has no compass_deg: pass --compass CSV")
    if compass.shape != (len(profiles),):
        raise InputError(f"{len(profiles)} profiles but {compass.size} compass headings")
    return names, profiles, compass


def image_paths(folder: str | Path, names: list[str]) -> list[Path]:
    """Panorama files of the compass CSV's ``image`` names in ``folder`` (each must exist)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"image folder not found: {folder}")
    paths = [folder / n for n in names]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        raise InputError(f"image {missing[0]} listed in the compass CSV does not exist")
    return paths


def write_track(path: str | Path, names: list[str], xy: np.ndarray, heading_deg: np.ndarray, psr: np.ndarray) -> None:
    """Write the track CSV."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["name", "x", "y", "heading_deg", "psr"])
        for name, (x, y), h, p in zip(names, xy, heading_deg, psr, strict=True):
            writer.writerow([name, f"{x:.3f}", f"{y:.3f}", f"{h:.3f}", f"{p:.3f}"])

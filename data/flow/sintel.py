"""MPI-Sintel frame pairs in the layout of ``../shared/data/sintel/alley_1/clean``: ``frame_XXXX.png`` plus
``gt/frame_XXXX.flo`` (flow from frame XXXX to the next), ``gt/occlusions/frame_XXXX.png`` and
``gt/invalid/frame_XXXX.png`` (nonzero = bad).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError
from core.frames import read_frame_gray
from data.flow.flo import read_flo


def _read_mask(path: Path, shape: tuple[int, int]) -> np.ndarray:
    if not path.is_file():
        return np.zeros(shape, dtype=bool)
    mask = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if mask is None or mask.shape != shape:
        raise InputError(f"{path}: unreadable mask or size differs from the flow {shape}")
    return mask > 0


@dataclass
class SintelPair:
    """Two consecutive gray frames ``(H, W)`` float32, the flow between them ``(H, W, 2)`` and a
    bad-pixel mask
    ``(H, W)`` (occluded, invalid or unknown flow)."""

    frame0: np.ndarray
    frame1: np.ndarray
    flow: np.ndarray
    bad: np.ndarray
    name: str


def read_sintel_pair(folder: str | Path, frame: int | None = None) -> SintelPair:
    """Read the pair ``frame -> frame + 1`` (default: the first frame with a ``gt/*.flo``) from a Sintel
    folder.

    Raises:
        InputError: missing folder, frames or flow; frames and flow of different sizes.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"Sintel folder not found: {folder}")
    flows = sorted((folder / "gt").glob("frame_*.flo"))
    if frame is None:
        if not flows:
            raise InputError(f"{folder}: no gt/frame_*.flo ground-truth flow")
        frame = int(flows[0].stem.split("_")[1])
    flow = read_flo(folder / "gt" / f"frame_{frame:04d}.flo")
    frame0 = read_frame_gray(folder / f"frame_{frame:04d}.png")
    frame1 = read_frame_gray(folder / f"frame_{frame + 1:04d}.png")
    shape = flow.shape[:2]
    if frame0.shape != shape or frame1.shape != shape:
        raise InputError(f"{folder}: frames {frame0.shape}/{frame1.shape} and flow {shape} differ in size")
    name = f"frame_{frame:04d}.png"
    bad = _read_mask(folder / "gt" / "occlusions" / name, shape) | _read_mask(
        folder / "gt" / "invalid" / name, shape
    )
    bad |= ~np.isfinite(flow).all(axis=2)
    return SintelPair(frame0, frame1, flow, bad, f"{folder.parent.name}/{folder.name}")


def read_sintel_sequence(folder: str | Path, max_pairs: int | None = None) -> list[SintelPair]:
    """Consecutive pairs from the first ground-truth flow on, as long as the next ``gt/frame_XXXX.flo`` exists
    (at most ``max_pairs``), for ground truth chained over several frames (thesis 3.4)."""
    first = read_sintel_pair(folder)
    pairs = [first]
    start = min(int(p.stem.split("_")[1]) for p in Path(folder, "gt").glob("frame_*.flo"))
    frame = start + 1
    while (max_pairs is None or len(pairs) < max_pairs) and Path(
        folder, "gt", f"frame_{frame:04d}.flo"
    ).is_file():
        pairs.append(read_sintel_pair(folder, frame))
        frame += 1
    return pairs

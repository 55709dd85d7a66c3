"""Real image sequences with known homographies from their first frame, read from a folder in the layout of the
Oxford affine-region sets (Mikolajczyk et al. 2005: ``img1.ppm`` ... ``img6.ppm`` with ``H1to2p`` ... ``H1to6p``)
or of HPatches (``1.ppm`` ... ``6.ppm`` with ``H_1_2`` ... ``H_1_6``): the sets of blur (``bikes``, ``trees``),
JPEG compression (``ubc``) and light (``leuven``, HPatches' ``i_*``) whose ground truth is exact.

A frame's index is the last number in its file name; the lowest is the reference frame ``r``, and every other
frame ``k`` needs a homography file from ``r`` to ``k``, named ``H{r}to{k}p``, ``H{r}to{k}`` or ``H_{r}_{k}``
(optionally ``.txt``): 3 x 3 numbers in rows, mapping a point ``x`` of frame ``r`` to ``H x`` in frame ``k``.
Frames of different sizes are padded to the largest (:func:`read_homography_folder`).
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError
from core.frames import frame_paths, read_frame_gray
from data.flow.homography import HomographySequence


def homography_file_names(reference: int, index: int) -> tuple[str, ...]:
    """The file names tried, in order, for the homography from frame ``reference`` to frame ``index``."""
    stems = (f"H{reference}to{index}p", f"H{reference}to{index}", f"H_{reference}_{index}")
    return tuple(name for stem in stems for name in (stem, f"{stem}.txt"))


def read_homography(path: str | Path) -> np.ndarray:
    """A ``(3, 3)`` float64 homography from a text file of 9 numbers (3 rows of 3), scaled to ``H[2, 2] = 1``
    where that entry is not 0; ``InputError`` for another count, a non-finite entry or a singular matrix."""
    path = Path(path)
    try:
        values = np.array(path.read_text().split(), dtype=np.float64)
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise InputError(f"{path}: not a homography (9 numbers in 3 rows): {err}") from err
    if values.size != 9 or not np.isfinite(values).all():
        raise InputError(f"{path}: a homography is 9 finite numbers in 3 rows, got {values.size} numbers")
    matrix = values.reshape(3, 3)
    if abs(np.linalg.det(matrix)) < 1e-12 * np.abs(matrix).max() ** 3:
        raise InputError(f"{path}: the homography is singular")
    return matrix / matrix[2, 2] if matrix[2, 2] != 0 else matrix


def _index(path: Path) -> int:
    numbers = re.findall(r"\d+", path.stem)
    if not numbers:
        raise InputError(f"{path}: a frame of a homography folder needs its index in its name (img1, 1, ...)")
    return int(numbers[-1])


def read_homography_folder(folder: str | Path) -> HomographySequence:
    """Frames ``(T, H, W)`` (gray, float32 in [0, 255], ordered by index) and homographies ``(T, 3, 3)`` from the
    first frame to each (the first the identity) of a folder in the layout of the module docstring. Frames of
    different sizes (HPatches has some) are padded at the bottom and right, their borders repeated, to the largest;
    the sequence's ``sizes`` keep their own, so that a point is valid only inside its frame. ``InputError`` names
    the folder or file: no folder, fewer than 2 frames, two frames of one index, a missing or malformed homography
    file."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"homography folder not found: {folder}")
    paths = sorted(frame_paths(folder), key=_index)
    indices = [_index(p) for p in paths]
    if len(paths) < 2:
        raise InputError(f"{folder}: a homography sequence needs at least 2 frames, found {len(paths)}")
    if len(set(indices)) != len(indices):
        raise InputError(f"{folder}: two frames share an index: {', '.join(p.name for p in paths)}")
    homographies = [np.eye(3)]
    for index in indices[1:]:
        names = homography_file_names(indices[0], index)
        found = [folder / name for name in names if (folder / name).is_file()]
        if not found:
            raise InputError(f"{folder}: no homography from frame {indices[0]} to frame {index} "
                             f"(looked for {', '.join(names)})")
        homographies.append(read_homography(found[0]))
    frames = [read_frame_gray(p) for p in paths]
    sizes = np.array([f.shape for f in frames])
    height, width = sizes.max(0)
    padded = [cv2.copyMakeBorder(f, 0, int(height) - f.shape[0], 0, int(width) - f.shape[1], cv2.BORDER_REPLICATE)
              for f in frames]
    return HomographySequence(np.stack(padded), np.stack(homographies), None if (sizes == sizes[0]).all() else sizes)

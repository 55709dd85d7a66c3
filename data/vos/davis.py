"""DAVIS layout reader (2016 binary and 2017 palette masks, any resolution folder, ImageSets split lists).

    ROOT/JPEGImages/<resolution>/<sequence>/00000.jpg
    ROOT/Annotations/<resolution>/<sequence>/00000.png
    ROOT/ImageSets/<resolution or year>/<split>.txt

Split files hold one sequence name per line (DAVIS 2017) or ``/JPEGImages/480p/bear/00000.jpg ...`` frame
lines (DAVIS 2016); both are understood.
"""

from __future__ import annotations

from pathlib import Path

from torch import Tensor

from core.errors import InputError
from data.vos.io import VOSSequence, list_frames


def split_file(root: Path, split: str, resolution: str) -> Path:
    """The ImageSets list for ``split``: ``ImageSets/<resolution>/`` first, then other ImageSets folders."""
    candidates = [root / "ImageSets" / resolution / f"{split}.txt"]
    candidates += sorted((root / "ImageSets").glob(f"*/{split}.txt"))
    for path in candidates:
        if path.is_file():
            return path
    raise InputError(f"DAVIS split {split!r} not found: no ImageSets/*/{split}.txt under {root}")


def read_split(path: Path) -> list[str]:
    """Sequence names of a split file, in order of first appearance."""
    names: list[str] = []
    for line in path.read_text().splitlines():
        token = line.strip().split()[0] if line.strip() else ""
        if not token:
            continue
        name = Path(token).parent.name if "/" in token else token
        if name not in names:
            names.append(name)
    if not names:
        raise InputError(f"DAVIS split file {path} lists no sequences")
    return names


def davis_sequences(
    root: str | Path, split: str = "val", resolution: str = "480p", names: list[str] | None = None
) -> list[VOSSequence]:
    """Sequences of a DAVIS split with all frames annotated.

    Args:
        root: DAVIS root (holding JPEGImages/, Annotations/, ImageSets/).
        split: split name (``train``, ``val``, ``test-dev``...) read from ImageSets.
        resolution: resolution folder (``480p``, ``Full-Resolution``, ``240p``...).
        names: optional subset of sequence names (kept in split order).
    """
    root = Path(root)
    if not (root / "JPEGImages" / resolution).is_dir():
        raise InputError(f"{root} is not a DAVIS root with JPEGImages/{resolution}/")
    seq_names = read_split(split_file(root, split, resolution))
    if names is not None:
        missing = sorted(set(names) - set(seq_names))
        if missing:
            raise InputError(f"sequences {missing} are not in DAVIS split {split!r}")
        seq_names = [n for n in seq_names if n in names]
    sequences = []
    for name in seq_names:
        frames = list_frames(root / "JPEGImages" / resolution / name)
        ann_dir = root / "Annotations" / resolution / name
        masks = [ann_dir / f"{f.stem}.png" for f in frames]
        masks = [m if m.is_file() else None for m in masks]
        if masks[0] is None:
            first = ann_dir / f"{frames[0].stem}.png"
            raise InputError(f"DAVIS sequence {name}: first-frame annotation {first} is missing")
        sequences.append(VOSSequence(name, frames, masks))
    return sequences


def load_davis_videos(
    root: str | Path, split: str = "val", resolution: str = "480p", names: list[str] | None = None,
    max_frames: int | None = None,
) -> list[tuple[str, Tensor, Tensor]]:
    """The sequences of :func:`davis_sequences` loaded: (name, frames uint8 (T, 3, H, W), labels (T, H, W)), the
    first ``max_frames`` frames of each (all with None)."""
    return [(seq.name, *seq.load(max_frames)) for seq in davis_sequences(root, split, resolution, names)]

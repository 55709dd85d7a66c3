"""YouTube-VOS layout reader.

    ROOT/<split>/JPEGImages/<video>/<frame>.jpg
    ROOT/<split>/Annotations/<video>/<frame>.png      (palette; every 5th frame in train, first ones in valid)
    ROOT/<split>/meta.json                            (optional: objects and the frame each first appears in)

Objects may first appear after frame 0; ``first_frames`` tells the tracker when to add them.
"""

from __future__ import annotations

import json
from pathlib import Path

from core.errors import InputError
from data.vos.io import VOSSequence, list_frames


def ytvos_sequences(
    root: str | Path, split: str = "valid", names: list[str] | None = None
) -> list[VOSSequence]:
    """Videos of a YouTube-VOS split; frames without an annotation file get ``None`` masks."""
    base = Path(root) / split
    if not (base / "JPEGImages").is_dir():
        raise InputError(f"{root} is not a YouTube-VOS root with {split}/JPEGImages/")
    video_names = sorted(p.name for p in (base / "JPEGImages").iterdir() if p.is_dir())
    if names is not None:
        missing = sorted(set(names) - set(video_names))
        if missing:
            raise InputError(f"videos {missing} are not in YouTube-VOS split {split!r}")
        video_names = [n for n in video_names if n in names]
    sequences = []
    for name in video_names:
        frames = list_frames(base / "JPEGImages" / name)
        ann = base / "Annotations" / name
        masks = [ann / f"{f.stem}.png" for f in frames]
        sequences.append(VOSSequence(name, frames, [m if m.is_file() else None for m in masks]))
    return sequences


def first_frames(root: str | Path, split: str = "valid") -> dict[str, dict[int, str]]:
    """``{video: {object id: first frame name}}`` from meta.json (empty if the file is absent)."""
    path = Path(root) / split / "meta.json"
    if not path.is_file():
        return {}
    try:
        meta = json.loads(path.read_text())["videos"]
    except (json.JSONDecodeError, KeyError) as err:
        raise InputError(f"YouTube-VOS meta file {path} is malformed ({err})") from err
    return {
        video: {int(obj): info["frames"][0] for obj, info in entry["objects"].items() if info.get("frames")}
        for video, entry in meta.items()
    }

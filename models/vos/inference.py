"""Running the VOS trackers (FRTM, LWL, DAVOS) on folders of frames and on DAVIS splits (used by ``infer.py
segment``): input checks, palette PNG output, overlay videos and J&F scoring."""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from core.errors import InputError
from core.files import partial_name, remove_partials, writable_folder, write_text
from data.vos.datamodule import synthetic_videos
from data.vos.davis import davis_sequences
from data.vos.io import davis_palette, list_frames, read_frame, read_mask, write_mask
from models.checkpoint import datamodule_settings
from models.vos.metrics import evaluate_sequence, write_csv
from models.vos.video_loop import VideoLoop

#: Synthetic video settings when a checkpoint stores no data module: key -> (data-module name, default).
SYNTHETIC_DEFAULTS = {"height": ("height", 96), "width": ("width", 160), "n_objects": ("eval_objects", 2),
                      "n_distractors": ("n_distractors", 1), "object_scale": ("object_scale", (0.15, 0.3))}


def synthetic_test_settings(ckpt: str | Path | None = None, **given) -> dict:
    """Settings of ``data.vos.datamodule.synthetic_videos`` for held-out videos like a checkpoint's training data:
    ``given`` values (None = not given), else the checkpoint's data module, else ``SYNTHETIC_DEFAULTS``."""
    stored = datamodule_settings(ckpt) if ckpt else {}
    unknown = sorted(set(given) - set(SYNTHETIC_DEFAULTS))
    if unknown:
        raise InputError(f"unknown synthetic video settings {unknown}")
    out = {}
    for key, (stored_key, default) in SYNTHETIC_DEFAULTS.items():
        value = given.get(key)
        out[key] = value if value is not None else stored.get(stored_key, default)
    out["object_scale"] = tuple(float(v) for v in out["object_scale"])
    return out


def checkpoint_test_videos(
    ckpt: str | Path | None, count: int, n_frames: int = 20, **given
) -> list[tuple[str, torch.Tensor, torch.Tensor]]:
    """``count`` held-out (``test`` seeds) synthetic videos of ``n_frames`` with ``synthetic_test_settings``."""
    if count <= 0:
        return []
    return synthetic_videos("test", count, 0, n_frames=n_frames, **synthetic_test_settings(ckpt, **given))


def check_first_frame(frames: list[Path], mask_path: str | Path) -> torch.Tensor:
    """Read and validate the first-frame mask against the first frame; returns the (H, W) label map."""
    mask = read_mask(mask_path)
    first = read_frame(frames[0])
    if mask.shape != first.shape[-2:]:
        raise InputError(f"mask {mask_path} is {tuple(mask.shape)} (H, W) but frame {frames[0]} is "
                         f"{tuple(first.shape[-2:])}")
    if not ((mask > 0) & (mask < 255)).any():
        raise InputError(f"mask {mask_path} labels no object (it is empty)")
    return mask


def _overlay(image: torch.Tensor, labels: torch.Tensor, palette: np.ndarray, ids: list[int],
             distractors: torch.Tensor | None = None) -> np.ndarray:
    """BGR overlay frame: the objects in their palette colours; with DAVOS distractor maps (N, H, W) a second
    panel beside it tints each object's regenerated distractor map (what its target model must not take for it)
    in that object's colour."""
    rgb = image.permute(1, 2, 0).numpy().astype(np.float32)
    colour = palette[labels.numpy().clip(0, 255)]
    alpha = (labels.numpy() > 0)[..., None] * 0.5
    panel = rgb * (1 - alpha) + colour * alpha
    if distractors is not None:
        tinted = rgb * 0.5
        for obj, p in zip(ids, distractors.float().cpu().numpy(), strict=True):
            a = 0.7 * p[..., None]
            tinted = tinted * (1 - a) + palette[obj] * a
        panel = np.concatenate([panel, tinted], 1)
    return cv2.cvtColor(panel.clip(0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR)


def later_masks(frames: list[Path], annotations: str | Path, first: torch.Tensor) -> dict[int, torch.Tensor]:
    """``{frame index: label map}`` of the annotation PNGs in folder ``annotations`` named after frames (besides
    the first): objects whose id is new there start at that frame (YouTube-VOS style); each map must match the
    first mask's size, and a PNG named after no frame is an ``InputError``."""
    folder = Path(annotations)
    if not folder.is_dir():
        raise InputError(f"annotation folder {folder} does not exist")
    index = {p.stem: t for t, p in enumerate(frames)}
    masks = {}
    for png in sorted(folder.glob("*.png")):
        if png.stem not in index:
            raise InputError(f"annotation {png} is named after no frame of the video")
        mask = read_mask(png)
        if mask.shape != first.shape:
            raise InputError(f"annotation {png} is {tuple(mask.shape)} but the first mask is {tuple(first.shape)}")
        if index[png.stem] > 0:
            masks[index[png.stem]] = mask
    return masks


def segment_folder(
    tracker: VideoLoop, video: str | Path, mask_path: str | Path, out: str | Path, overlay: str | None = None,
    fps: float = 24.0, annotations: str | Path | None = None, max_frames: int | None = None,
) -> tuple[int, float]:
    """Segment the frames of ``video`` (the first ``max_frames``; None: all) from the first-frame mask; write
    ``out/<frame>.png`` palette masks and optionally an overlay video (twice as wide for DAVOS: the regenerated
    distractor maps beside the masks). Objects that appear later are given by ``annotations`` (``later_masks``).
    Returns (frames, seconds).

    The masks (and the video) are written under hidden temporary names and moved into place when every frame
    was segmented, so a bad frame half-way leaves no masks behind."""
    frames = list_frames(video)
    mask = check_first_frame(frames, mask_path)
    masks = {0: mask, **(later_masks(frames, annotations, mask) if annotations is not None else {})}
    frames = frames[:max_frames]
    masks = {t: m for t, m in masks.items() if t < len(frames)}
    final = writable_folder(out)
    staging = final.with_name(f".{final.name}.partial")
    shutil.rmtree(staging, ignore_errors=True)
    video_tmp = partial_name(Path(overlay)) if overlay else None
    if video_tmp is not None:
        writable_folder(video_tmp.parent)
    palette = np.array(davis_palette(), dtype=np.float32).reshape(256, 3)
    writer = None
    start = time.perf_counter()
    images = (read_frame(p) for p in frames)
    try:
        for path, (image, labels) in zip(frames, _with_images(tracker, images, masks), strict=True):
            write_mask(staging / f"{path.stem}.png", labels.to(torch.uint8))
            if video_tmp is not None:
                frame = _overlay(image, labels, palette, tracker.ids, tracker.distractor_maps(labels.shape))
                if writer is None:
                    writer = cv2.VideoWriter(str(video_tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps,
                                             (frame.shape[1], frame.shape[0]))
                writer.write(frame)
        if writer is not None:
            writer.release()
            writer = None
            os.replace(video_tmp, overlay)
        for png in sorted(staging.iterdir()):
            os.replace(png, final / png.name)
    finally:
        if writer is not None:
            writer.release()
        if video_tmp is not None:
            video_tmp.unlink(missing_ok=True)
        shutil.rmtree(staging, ignore_errors=True)
    return len(frames), time.perf_counter() - start


def _with_images(tracker: VideoLoop, images, masks: dict[int, torch.Tensor]):
    """Yield (image, labels) pairs while the tracker consumes the same frames; checks frame sizes."""
    size = masks[0].shape
    kept: list[torch.Tensor] = []

    def frames():
        for i, image in enumerate(images):
            if image.shape[-2:] != size:
                raise InputError(f"frame {i} is {tuple(image.shape[-2:])} but the first mask is {tuple(size)}")
            kept.append(image)
            yield image

    for labels in tracker.segment(frames(), masks):
        yield kept.pop(0), labels


#: Per-sequence scores of ``segment_davis``, written after the sequence's masks: a finished sequence.
SCORES_FILE = ".scores.json"
#: What an output folder of ``segment_davis`` was written by (a resumed run must match it).
JOB_FILE = "segment_job.json"


def segment_davis(
    tracker: VideoLoop, root: str | Path, split: str, resolution: str, out: str | Path,
    max_frames: int | None = None, job: dict | None = None,
) -> tuple[dict[str, float], float]:
    """Segment every sequence of a DAVIS split, write palette PNGs under ``out/<sequence>/`` and the
    per-object CSV ``out/per_sequence.csv``; returns (global J&F statistics, FPS of the sequences run).

    ``tracker`` may also be the deployment runtime's (``runtime.vos.OnnxFRTMTracker``, numpy masks out).
    Resumable: a sequence's scores are stored beside its masks once all of them are written, so a rerun after an
    interruption skips finished sequences, removes what a killed writer left half-written and writes the same
    CSV. ``job`` (e.g. the model's path) identifies the run: an ``out`` written by another job is an
    ``InputError``.
    """
    out = Path(out)
    sequences = davis_sequences(root, split, resolution)  # a bad DAVIS root fails before anything is written
    job = json.loads(json.dumps({**(job or {}), "split": split, "resolution": resolution, "max_frames": max_frames}))
    if (out / JOB_FILE).is_file():
        if json.loads((out / JOB_FILE).read_text()) != job:
            raise InputError(f"{out} holds masks of another segmentation run ({out / JOB_FILE}); use another --out")
    else:
        write_text(out / JOB_FILE, json.dumps(job, indent=1))
    remove_partials(out)
    per_seq, n_frames, seconds = {}, 0, 0.0
    for seq in sequences:
        scores = out / seq.name / SCORES_FILE
        if scores.is_file():
            per_seq[seq.name] = {int(k): v for k, v in json.loads(scores.read_text()).items()}
            continue
        remove_partials(out / seq.name)
        frames, labels = seq.load(max_frames)
        start = time.perf_counter()
        pred = torch.stack([torch.as_tensor(p) for p in tracker.segment(frames, {0: labels[0]})])
        seconds += time.perf_counter() - start
        n_frames += frames.shape[0]
        for path, lab in zip(seq.frames, pred, strict=False):
            write_mask(out / seq.name / f"{path.stem}.png", lab.to(torch.uint8))
        gt = torch.where(labels < 0, 0, labels)
        per_seq[seq.name] = evaluate_sequence(pred, gt)
        write_text(scores, json.dumps(per_seq[seq.name]))
    return write_csv(per_seq, out / "per_sequence.csv"), n_frames / max(seconds, 1e-9)

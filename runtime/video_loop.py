"""The frame loop of the runtime's VOS trackers, in numpy (``models.vos.video_loop.VideoLoop`` without torch):
objects from the first-frame label map or appearing in a later one, one ``step`` per frame, an ``update`` that
feeds the result back, and writing a video's masks as palette PNGs."""

from __future__ import annotations

import argparse
import os
import shutil
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from core.command import CommandParser, run_command
from core.errors import InputError
from core.files import staging_folder, writable_folder
from core.processing_size import check_process_height, nearest_indices, processing_size
from core.progress import progress as progress_line
from runtime.bundle import add_runtime_arguments
from runtime.vos_io import list_frames, read_frame, read_mask, write_mask


class NumpyVideoLoop(ABC):
    """Host side of a bundle's tracker. Subclasses set ``min_size`` / ``max_size`` (frame sides the graphs take)
    and implement ``add_objects``, ``step`` and ``update``; ``reset`` must call ``super().reset()``.

    Args:
        process_height: as ``models.vos.video_loop.VideoLoop``: frames are resized (bilinear; masks by nearest
            neighbour) to this many rows, aspect kept, and the label maps back to the input size; 0: input size.
    """

    min_size: int
    max_size: int

    def __init__(self, process_height: int = 0) -> None:
        self.process_height = check_process_height(process_height)
        self.reset()

    def reset(self) -> None:
        """Forget the current video."""
        self.ids: list[int] = []
        self.frame = 0
        self.previous_labels: np.ndarray | None = None  # the last frame's labels at the processing size

    @abstractmethod
    def add_objects(self, image: np.ndarray, labels: np.ndarray, ids: list[int]) -> None:
        """Start tracking objects ``ids`` (masks ``labels == id``) in the (3, H, W) image in [0, 1]."""

    @abstractmethod
    def step(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Labels (H, W), per-object memory labels (N, ..., H, W) and features of one frame."""

    @abstractmethod
    def update(self, memory_labels: np.ndarray, features: np.ndarray) -> None:
        """Feed one frame's memory labels (zero where new objects start) and features to the memories."""

    def _image(self, frame: np.ndarray, index: int) -> np.ndarray:
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[0] != 3:
            raise InputError(f"frame {index} is {frame.shape}: the bundle takes (3, H, W) RGB frames")
        return frame.astype(np.float32) / np.float32(255) if frame.dtype == np.uint8 else frame.astype(np.float32)

    def _check_size(self, image: np.ndarray, index: int) -> None:
        if not all(self.min_size <= n <= self.max_size for n in image.shape[1:]):
            raise InputError(f"frame {index} is {image.shape} where it is processed: the bundle takes (3, H, W) RGB "
                             f"frames of {self.min_size} to {self.max_size} px a side")

    def segment(self, frames: Iterable[np.ndarray], masks: dict[int, np.ndarray]) -> Iterator[np.ndarray]:
        """Segment a video.

        Args:
            frames: (3, H, W) RGB frames, uint8 or float in [0, 1].
            masks: ``{frame index: (H, W) label map}``; frame 0 must be present; objects whose id first appears in
                a later map start there (their given mask overrides the prediction).

        Yields:
            (H, W) int64 label maps, one per frame, at the input size (see ``process_height``).
        """
        if 0 not in masks:
            raise InputError("the first frame has no mask")
        self.reset()
        for t, frame in enumerate(frames):
            image = self._image(frame, t)
            given = None if masks.get(t) is None else np.asarray(masks[t])
            if given is not None and given.shape != image.shape[-2:]:
                raise InputError(f"mask of frame {t} is {given.shape}, the frame {image.shape[-2:]}")
            self.frame = t
            new_ids = [] if given is None else [int(i) for i in np.unique(given) if i not in (0, 255)
                                                 and i not in self.ids]
            if t == 0 and not new_ids:
                raise InputError("the first-frame mask is empty: it labels no object")
            size = image.shape[-2:]
            work = processing_size(size, self.process_height)
            if work == size:
                self._check_size(image, t)
                yield self._segment_frame(image, given, new_ids)
                continue
            image = cv2.resize(image.transpose(1, 2, 0), work[::-1], interpolation=cv2.INTER_LINEAR).transpose(2, 0, 1)
            self._check_size(image, t)
            given_work = None if given is None else _resize_labels(given, work)
            labels = _resize_labels(self._segment_frame(image, given_work, new_ids), size)
            if new_ids:  # new objects' masks as given, at the input size
                labels = np.where(np.isin(given, new_ids), given, labels).astype(np.int64)
            yield labels

    def _segment_frame(self, image: np.ndarray, given: np.ndarray | None, new_ids: list[int]) -> np.ndarray:
        """Labels (h, w) of the current frame (3, h, w) at the processing size, with its given label map (h, w)
        or None, whose objects ``new_ids`` start here."""
        if self.ids:
            labels, memory_labels, features = self.step(image)
            if new_ids:
                new = np.isin(given, new_ids)
                labels = np.where(new, given, labels).astype(np.int64)
                memory_labels = memory_labels * ~new
            self.update(memory_labels, features)
        else:
            labels = np.where(np.isin(given, new_ids), given, 0).astype(np.int64)
        if new_ids:
            self.add_objects(image, labels, new_ids)
        self.previous_labels = labels
        return labels


def _resize_labels(labels: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A label map resized to ``size = (h, w)`` by nearest neighbour (``core.processing_size.nearest_indices``)."""
    rows, cols = nearest_indices(labels.shape[0], size[0]), nearest_indices(labels.shape[1], size[1])
    return labels[rows[:, None], cols]


def segment_folder(tracker: NumpyVideoLoop, video: str | Path, mask_path: str | Path, out: str | Path,
                   progress: bool = False, max_frames: int | None = None) -> tuple[int, float]:
    """Segment the frames of ``video`` (the first ``max_frames``; None: all) from the first-frame mask and write
    ``out/<frame>.png`` palette masks, all moved into place only when every frame was segmented (``progress``: a
    progress line on stderr). Returns (frames, seconds)."""
    frames = list_frames(video)[:max_frames]
    mask = read_mask(mask_path)
    first = read_frame(frames[0])
    if mask.shape != first.shape[1:]:
        raise InputError(f"mask {mask_path} is {mask.shape} (H, W) but frame {frames[0]} is {first.shape[1:]}")
    if not ((mask > 0) & (mask < 255)).any():
        raise InputError(f"mask {mask_path} labels no object (it is empty)")
    final = writable_folder(out)
    staging = staging_folder(final)
    start = time.perf_counter()

    def images() -> Iterator[np.ndarray]:
        for i, path in enumerate(frames):
            image = first if i == 0 else read_frame(path)
            if image.shape != first.shape:
                raise InputError(f"frame {path} is {image.shape[1:]} but the first frame is {first.shape[1:]}")
            yield image

    try:
        segmented = zip(frames, tracker.segment(images(), {0: mask}), strict=True)
        for path, labels in progress_line(segmented, "segment (onnxruntime)", len(frames), enabled=progress):
            write_mask(staging / f"{path.stem}.png", labels)
        seconds = time.perf_counter() - start
        for png in sorted(staging.iterdir()):
            os.replace(png, final / png.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return len(frames), seconds


def video_command(prog: str, description: str, make_tracker: Callable[..., NumpyVideoLoop],
                  argv: list[str] | None = None) -> int:
    """The command line of a VOS runtime task: ``--bundle``, ``--threads``, ``--provider``, ``--video``, ``--mask``,
    ``--out``; ``make_tracker(bundle, threads, provider)`` builds the tracker. Returns the exit code."""
    parser = CommandParser(prog=prog, description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_runtime_arguments(parser)
    parser.add_argument("--video", type=Path, required=True, help="folder of frames (sorted by name)")
    parser.add_argument("--mask", type=Path, required=True, help="first-frame mask PNG (palette ids or binary gray)")
    parser.add_argument("--out", type=Path, required=True, help="output folder for the palette PNG masks")
    args = parser.parse_args(argv)

    def run() -> None:
        tracker = make_tracker(args.bundle, args.threads, args.provider)
        n, seconds = segment_folder(tracker, args.video, args.mask, args.out, progress=True)
        print(f"segmented {n} frames in {seconds:.1f} s ({n / seconds:.2f} FPS, onnxruntime); masks in {args.out}")

    return run_command(prog, run)

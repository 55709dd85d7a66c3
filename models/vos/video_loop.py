"""The frame loop every VOS tracker shares (FRTM, LWL and DAVOS; thesis ch. 5.3 and 6): objects given by a
first-frame label map (or appearing in a later one), one ``step`` per frame that segments it, an ``update`` that
feeds the result back into the objects' memories, and per-component timings."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections import defaultdict
from collections.abc import Iterable, Iterator

import torch
import torch.nn.functional as F

from core.errors import InputError
from core.processing_size import check_process_height, nearest_indices, processing_size


class VideoLoop(ABC):
    """Host side of a memory-based VOS tracker.

    Subclasses implement ``reset`` (which must call ``super().reset()``), ``add_objects``, ``step`` and
    ``update``; ``segment`` runs them over a video. ``timings`` accumulates milliseconds per component.

    Args:
        process_height: rows of the frames the tracker works at (``segment`` resizes frames bilinearly and masks
            by nearest neighbour to this height, aspect kept, and the label maps back to the input size); 0
            works at the input size.
    """

    def __init__(self, process_height: int = 0) -> None:
        self.process_height = check_process_height(process_height)
        self.timings: dict[str, float] = defaultdict(float)
        self.reset()

    def reset(self) -> None:
        """Forget the current video."""
        self.ids: list[int] = []
        self.frame = 0
        self.previous_labels: torch.Tensor | None = None  # the last frame's labels at the processing size

    def _tic(self, device: torch.device) -> float:
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter()

    def _toc(self, name: str, start: float, device: torch.device) -> None:
        self.timings[name] += (self._tic(device) - start) * 1000

    @abstractmethod
    def add_objects(self, image: torch.Tensor, labels: torch.Tensor, ids: list[int]) -> None:
        """Start tracking the objects ``ids`` whose masks are ``labels == id`` in ``image`` (3, H, W); ``labels``
        (H, W) also holds the other objects of the frame."""

    @abstractmethod
    def step(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Segment one frame (3, H, W): labels (H, W) int64, per-object memory labels (N, ..., H, W), features."""

    @abstractmethod
    def update(self, memory_labels: torch.Tensor, features: torch.Tensor) -> None:
        """Feed one frame's memory labels (zero where new objects start) and features to the objects' memories."""

    def distractor_maps(self, size: tuple[int, int]) -> torch.Tensor | None:
        """Per-object distractor maps (N, H, W) of the last frame, for overlays; None for trackers without."""
        return None

    @torch.inference_mode()
    def segment(
        self, frames: Iterable[torch.Tensor], masks: dict[int, torch.Tensor]
    ) -> Iterator[torch.Tensor]:
        """Segment a video.

        Args:
            frames: (3, H, W) RGB frames in [0, 1] (float tensors, or uint8 scaled by 1/255).
            masks: ``{frame index: (H, W) label map}``; frame 0 must be present; objects whose id first
                appears in a later map start there (their given mask overrides the prediction).

        Yields:
            (H, W) int64 label maps, one per frame, at the input size (see ``process_height``).
        """
        if 0 not in masks:
            raise InputError("the first frame has no mask")
        self.reset()
        for t, frame in enumerate(frames):
            image = frame.float() / 255 if frame.dtype == torch.uint8 else frame
            given = masks.get(t)
            if given is not None and given.shape != image.shape[-2:]:
                raise InputError(f"mask of frame {t} is {tuple(given.shape)}, the frame {tuple(image.shape[-2:])}")
            self.frame = t
            new_ids = [] if given is None else [i for i in given.unique().tolist() if i not in (0, 255)
                                                 and i not in self.ids]
            if t == 0 and not new_ids:
                raise InputError("the first-frame mask is empty: it labels no object")
            size = (image.shape[-2], image.shape[-1])
            work = processing_size(size, self.process_height)
            if work == size:
                yield self._segment_frame(image, given, new_ids)
                continue
            image = F.interpolate(image[None], size=work, mode="bilinear", align_corners=False)[0]
            given_work = None if given is None else _resize_labels(given, work)
            labels = _resize_labels(self._segment_frame(image, given_work, new_ids), size)
            if new_ids:  # new objects' masks as given, at the input size
                new = torch.isin(given, torch.tensor(new_ids, device=given.device)).to(labels.device)
                labels = torch.where(new, given.to(labels.device, labels.dtype), labels)
            yield labels

    def _segment_frame(self, image: torch.Tensor, given: torch.Tensor | None, new_ids: list[int]) -> torch.Tensor:
        """Labels (h, w) of the current frame (3, h, w) at the processing size, with its given label map (h, w)
        or None, whose objects ``new_ids`` start here."""
        if self.ids:
            labels, memory_labels, features = self.step(image)
            if new_ids:
                new = torch.isin(given, torch.tensor(new_ids, device=given.device)).to(labels.device)
                labels = torch.where(new, given.to(labels.device, labels.dtype), labels)
                memory_labels = memory_labels * (~new).to(memory_labels.dtype)
            self.update(memory_labels, features)
        else:
            labels = torch.where(torch.isin(given, torch.tensor(new_ids)), given, 0).long()
        if new_ids:
            self.add_objects(image, labels.to(image.device), new_ids)
        self.previous_labels = labels
        return labels


def _resize_labels(labels: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """A label map (H, W) resized to ``size = (h, w)`` by nearest neighbour (``nearest_indices``)."""
    rows, cols = (torch.from_numpy(nearest_indices(n, m)).to(labels.device)
                  for n, m in zip(labels.shape, size, strict=True))
    return labels[rows[:, None], cols]

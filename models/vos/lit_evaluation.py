"""What the VOS LightningModules (FRTM, LWL/DAVOS) share: weights from an ``init_checkpoint`` before fitting,
and validation/test of the full tracker on whole videos with the DAVIS protocol (J&F over every object of
every sequence, gathered over the ranks of a distributed run; FPS; a per-object CSV after testing)."""

from __future__ import annotations

import time
from pathlib import Path

import lightning as L
import torch

from core.errors import InputError
from models.checkpoint import read_checkpoint
from models.distributed import gather_dicts, gather_objects
from models.vos.metrics import evaluate_sequence, summarize, write_csv
from models.vos.video_loop import VideoLoop


def first_masks(labels: torch.Tensor) -> dict[int, torch.Tensor]:
    """The annotated label maps where an object id first appears (frame 0 always): ``{frame: (H, W)}`` of a
    (T, H, W) label video (-1 = frame not annotated); later objects start at their first annotation."""
    masks, seen = {0: labels[0]}, set(labels[0].unique().tolist())
    for t in range(1, labels.shape[0]):
        ids = set(labels[t].unique().tolist()) - {-1, 0, 255}
        if ids - seen:
            masks[t] = torch.where(labels[t] < 0, 0, labels[t])
            seen |= ids
    return masks


class VOSEvaluation(L.LightningModule):
    """Base of the VOS systems: subclasses define ``make_tracker()`` and have an ``init_checkpoint``
    hyper-parameter."""

    def __init__(self) -> None:
        super().__init__()
        self._eval: dict[str, dict[int, dict[str, float]]] = {}
        self._frames = 0
        self._seconds = 0.0

    def make_tracker(self) -> VideoLoop:
        raise NotImplementedError

    def setup(self, stage: str) -> None:
        """Load ``init_checkpoint``'s weights before fitting (before Lightning restores a ``--ckpt_path``)."""
        path = self.hparams.init_checkpoint
        if stage != "fit" or not path:
            return
        state = read_checkpoint(path, "init_checkpoint")["state_dict"]
        try:
            self.load_state_dict(state)
        except RuntimeError as err:  # missing, unexpected or differently shaped weights
            raise InputError(f"init_checkpoint {path} does not match this model: {err}") from err

    def _evaluate(self, batch: dict) -> None:
        frames, labels = batch["frames"], batch["labels"]
        tracker = self.make_tracker()
        start = time.perf_counter()
        pred = torch.stack(list(tracker.segment(frames, first_masks(labels))))
        self._seconds += time.perf_counter() - start
        self._frames += frames.shape[0]
        annotated = (labels >= 0).flatten(1).all(1)  # sparse annotations (YouTube-VOS) score where they exist
        late = pred > int(labels[0].clamp(0, 254).max())  # objects after frame 0 are not scored (DAVIS protocol)
        pred = torch.where(late, torch.zeros_like(pred), pred)
        self._eval[batch["name"]] = evaluate_sequence(pred[annotated].cpu(), labels[annotated].cpu())

    def on_validation_epoch_start(self) -> None:
        self._eval, self._frames, self._seconds = {}, 0, 0.0

    on_test_epoch_start = on_validation_epoch_start

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._evaluate(batch)

    def test_step(self, batch: dict, batch_idx: int) -> None:
        self._evaluate(batch)

    def _report(self, stage: str) -> dict[str, float]:
        """J&F over every object of every sequence (gathered over the ranks of a distributed run) and FPS."""
        self._eval = gather_dicts(self._eval)
        frames, seconds = (sum(v) for v in zip(*gather_objects((self._frames, self._seconds)), strict=True))
        glob = summarize(self._eval)
        fps = frames / max(seconds, 1e-9)
        self.log_dict({f"{stage}/jf": glob["J&F-Mean"], f"{stage}/j": glob["J-Mean"], f"{stage}/f": glob["F-Mean"],
                       f"{stage}/fps": fps}, prog_bar=stage == "val")
        return {**glob, "FPS": fps}

    def on_validation_epoch_end(self) -> None:
        if self._eval:
            self._report("val")

    def on_test_epoch_end(self) -> None:
        if not self._eval:
            return
        result = self._report("test")
        log_dir = Path(self.trainer.log_dir or ".") if self.trainer is not None else Path(".")  # on every rank
        if self.global_rank != 0:
            return
        write_csv(self._eval, log_dir / "per_sequence.csv")
        print(f"J&F {100 * result['J&F-Mean']:.1f}  J {100 * result['J-Mean']:.1f}  F {100 * result['F-Mean']:.1f}  "
              f"FPS {result['FPS']:.2f}  ({len(self._eval)} sequences; per object: {log_dir / 'per_sequence.csv'})")

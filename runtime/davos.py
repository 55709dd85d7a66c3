"""DAVOS and LWL video object segmentation (thesis ch. 6) from the exported graphs, torch-free.

    python -m runtime.davos --bundle DIR --video DIR --mask FIRST.png --out DIR [--threads N]
                            [--provider cpu|cuda|tensorrt|coreml]

The host loop of ``models.vos.davos_tracker.DAVOSTracker`` in numpy: a new object's label [target, distractor]
(the distractor: the other labelled objects) is encoded (``encode`` graph) and a zero filter trained on it
(``fit_init``), which starts its memory; per frame the ``frame`` graph gives every object's logits, the target
logits are merged by soft aggregation, each object's distractor map is regenerated (eqs. 6.1-6.5), and the new
labels are encoded and inserted (``insert``) before the filters are re-trained (``fit_update``, one object per
call). Masks are written as palette PNGs named after the frames, all at once when every frame was segmented.
"""

from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from runtime.bundle import Bundle
from runtime.video_loop import NumpyVideoLoop, video_command

#: Clamp of the per-object probabilities in the soft aggregation (``models.vos.merge``).
EPS = 1e-7


def soft_aggregate(logits: np.ndarray) -> np.ndarray:
    """Merged probabilities (N + 1, H, W), background first, of per-object logits (N, H, W): p_0 = prod(1 - p_i),
    then a softmax of the log-odds (``models.vos.merge.soft_aggregate``)."""
    p = np.clip(1 / (1 + np.exp(-logits.astype(np.float32))), np.float32(EPS), np.float32(1 - EPS))
    p0 = np.clip(np.prod(1 - p, axis=0, keepdims=True), np.float32(EPS), np.float32(1 - EPS))
    probs = np.concatenate([p0, p])  # float32 throughout, as PyTorch computes it
    odds = np.log(probs) - np.log1p(-probs)
    odds = np.exp(odds - odds.max(0, keepdims=True))
    return (odds / odds.sum(0, keepdims=True)).astype(np.float32)


def regenerate_distractors(probs: np.ndarray, labels: np.ndarray, ids: list[int], winner_takes_all: bool = True
                           ) -> np.ndarray:
    """Distractor maps (N, H, W) of target probabilities (N, H, W) and merged labels (H, W), eqs. 6.1-6.5, or the
    soft union of the other objects without ``winner_takes_all`` (``models.vos.distractors``)."""
    n = probs.shape[0]
    if not winner_takes_all:
        if n == 1:
            return np.zeros_like(probs)
        others = ~np.eye(n, dtype=bool)[:, :, None, None]
        return np.where(others, probs[None], 0).max(1).astype(np.float32)
    fg = (labels > 0)[None].astype(np.float32)
    distractor = fg * (labels[None] != np.asarray(ids)[:, None, None])
    return (distractor * probs.max(0, keepdims=True) + (1 - fg) * probs.min(0, keepdims=True)).astype(np.float32)


class OnnxDAVOSTracker(NumpyVideoLoop):
    """DAVOS (or LWL) on a ``davos`` bundle; ``segment`` takes and yields numpy arrays like
    ``DAVOSTracker.segment`` tensors.

    Args:
        bundle: the bundle folder; threads, provider: as ``runtime.session.Graph``.

    Attributes:
        timings: accumulated milliseconds of ``frame``, ``update`` and ``init``; distractors: the maps
            regenerated at the last frame.
    """

    GRAPHS = ("features", "frame", "encode", "insert", "fit_init", "fit_update")

    def __init__(self, bundle: str | Path, threads: int | None = None, provider: str = "cpu") -> None:
        self.bundle = Bundle(bundle, "davos", threads, provider)
        self.settings = self.bundle.section("settings")
        network = self.bundle.section("network")
        self.label_channels = int(network["label_channels"])
        self.filter_shape = tuple(int(v) for v in network["filter_shape"])
        size = self.bundle.section("input")
        self.min_size, self.max_size = int(size["min_size"]), int(size["max_size"])
        self.graphs = {name: self.bundle.graph(name) for name in self.GRAPHS}
        self.timings: dict[str, float] = defaultdict(float)
        super().__init__()

    def reset(self) -> None:
        """Forget the current video."""
        super().reset()
        self.tau: np.ndarray | None = None
        self.memory: list[np.ndarray] = []  # features, encodings, weights, sample weights, newest
        self.distractors: np.ndarray | None = None

    def _tick(self, name: str, start: float) -> None:
        self.timings[name] += (time.perf_counter() - start) * 1000

    def _labels(self, target: np.ndarray, distractor: np.ndarray) -> np.ndarray:
        if self.label_channels == 1:
            return target[:, None].astype(np.float32)
        if not self.settings["use_distractors"]:
            distractor = np.zeros_like(distractor)
        return np.stack([target, distractor], 1).astype(np.float32)

    def _fit(self, name: str) -> None:
        n = int((self.memory[3] > 0).sum(1).max())
        rows = [self.graphs[name](self.tau[i : i + 1], *(m[i : i + 1, :n] for m in self.memory[:4]))
                for i in range(len(self.ids))]
        self.tau = np.concatenate(rows)

    def add_objects(self, image: np.ndarray, labels: np.ndarray, ids: list[int]) -> None:
        """Train filters for objects ``ids`` (masks ``labels == id`` in the (3, H, W) image in [0, 1])."""
        start = time.perf_counter()
        target = (labels[None] == np.asarray(ids)[:, None, None]).astype(np.float32)
        labelled = (labels > 0) & (labels != 255)
        distractor = (labelled[None] & (labels[None] != np.asarray(ids)[:, None, None])).astype(np.float32)
        x = self.graphs["features"](image[None])
        encodings, weights = self.graphs["encode"](self._labels(target, distractor))
        n, capacity = len(ids), int(self.settings["memory_size"])
        memory = [np.zeros((n, capacity, *x.shape[1:]), np.float32), np.zeros((n, capacity, *encodings.shape[1:]),
                  np.float32), np.zeros((n, capacity, *weights.shape[1:]), np.float32),
                  np.zeros((n, capacity), np.float32), np.full(n, -1, np.int64)]
        memory[0][:, 0], memory[1][:, 0], memory[2][:, 0], memory[3][:, 0] = x[0], encodings, weights, 1.0
        zero = np.zeros((1, *self.filter_shape), np.float32)
        tau = np.concatenate([self.graphs["fit_init"](zero, *(m[i : i + 1, :1] for m in memory[:4]))
                              for i in range(n)])
        if self.ids:
            memory = [np.concatenate([a, b]) for a, b in zip(self.memory, memory, strict=True)]
            tau = np.concatenate([self.tau, tau])
        self.ids += list(ids)
        self.tau, self.memory = tau, memory
        self._tick("init", start)

    def step(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Labels (H, W), memory labels (N, L, H, W) and features (1, P, h, w) of a frame (3, H, W)."""
        start = time.perf_counter()
        logits, x = self.graphs["frame"](image[None], self.tau)
        self._tick("frame", start)
        merged = soft_aggregate(logits[:, 0])
        labels = np.array([0, *self.ids], np.int64)[merged.argmax(0)]
        distractor = np.zeros_like(merged[1:])
        if self.label_channels == 2:
            p = 1 / (1 + np.exp(-logits[:, 0].astype(np.float32)))
            distractor = regenerate_distractors(p, labels, self.ids, self.settings["winner_takes_all"])
            self.distractors = distractor
        return labels, self._labels(merged[1:], distractor), x

    def update(self, memory_labels: np.ndarray, features: np.ndarray) -> None:
        """Encode and insert the memory labels (N, L, H, W) with the features; re-train every ``update_every``."""
        start = time.perf_counter()
        encodings, weights = self.graphs["encode"](memory_labels.astype(np.float32))
        n = len(self.ids)
        x = np.broadcast_to(features, (n, *features.shape[1:])).copy()
        self.memory = list(self.graphs["insert"](*self.memory, x, encodings, weights))
        s = self.settings
        if self.frame % int(s["update_every"]) == 0 and int(s["update_iters"]) > 0:
            self._fit("fit_update")
        self._tick("update", start)


def main(argv: list[str] | None = None) -> int:
    return video_command("runtime.davos", __doc__, OnnxDAVOSTracker, argv)


if __name__ == "__main__":
    raise SystemExit(main())

"""FRTM video object segmentation (thesis ch. 5) from the exported graphs, torch-free.

    python -m runtime.vos --bundle DIR --video DIR --mask FIRST.png --out DIR [--threads N]
                          [--provider cpu|cuda|tensorrt|coreml]

The host loop of ``models.vos.tracker.FRTMLoop`` in numpy: objects from the first-frame mask (or appearing in a
later one), the first-frame augmentation (``core.first_frame_augment``, the same samples as the PyTorch tracker),
per object a joint W_p/W_f fit (``init`` graph), the memory as numpy arrays (``insert`` graph per frame and
object), W_f updates every ``update_every`` frames (``update`` graph, with its CG state), and per frame the
``frame`` graph (backbone, target models, decoder) followed by the soft aggregation of the objects (thesis eq.
5.3); the frame loop is ``runtime.video_loop``. Masks are written as palette PNGs named after the frames, all at
once when every frame was segmented.
"""

from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from core.errors import InputError
from core.first_frame_augment import first_frame_augment
from core.search_region import (
    DROPPED_LOGIT,
    ignore_band,
    main_component,
    outside_search_region,
    unsupported_components,
)
from runtime.area import area_resize
from runtime.bundle import Bundle
from runtime.video_loop import NumpyVideoLoop, video_command

#: Clamp of the per-object probabilities in the soft aggregation (``models.vos.merge``).
EPS = 1e-7


def merge_objects(logits: np.ndarray, ids: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Soft aggregation of per-object logits (N, H, W): labels (H, W) int64 in {0} + ids, and each object's
    merged probability where it won (N, H, W) (its memory label)."""
    p = np.clip(1 / (1 + np.exp(-logits)), EPS, 1 - EPS)
    p0 = np.clip(np.prod(1 - p, axis=0, keepdims=True), EPS, 1 - EPS)
    probs = np.concatenate([p0, p])
    odds = np.log(probs) - np.log1p(-probs)
    odds = np.exp(odds - odds.max(0, keepdims=True))
    probs = odds / odds.sum(0, keepdims=True)
    win = probs.argmax(0)
    labels = np.array([0, *ids], np.int64)[win]
    won = win[None] == np.arange(1, len(ids) + 1)[:, None, None]
    return labels, (probs[1:] * won).astype(np.float32)


def target_score(z: np.ndarray, wf: np.ndarray) -> np.ndarray:
    """Target-model scores W_f * z (``models.vos.target_model.apply_filter``: zero padding, same size) of projected
    features (N, C, h, w) and filters (N, C, k, k) -> (N, h, w)."""
    n, _, h, w = z.shape
    k = wf.shape[-1]
    padded = np.pad(z, ((0, 0), (0, 0), (k // 2, k // 2), (k // 2, k // 2)))
    out = np.zeros((n, h, w), np.float32)
    for dy in range(k):  # k * k taps of the small filter, each one product over all pixels
        for dx in range(k):
            out += np.einsum("nc,nchw->nhw", wf[:, :, dy, dx], padded[:, :, dy : dy + h, dx : dx + w])
    return out


def hinge_pixel_weights(labels: np.ndarray, fg_target: float, min_pixels: int) -> np.ndarray:
    """FRTM's residual weights v = sqrt(w) of soft labels (..., H, W) (``models.vos.target_model``): a small
    object carries ``fg_target`` of the weight, larger ones are left unweighted."""
    fg = labels > 0.5
    n_fg = fg.sum((-2, -1)).astype(np.float32)
    a_f = n_fg / np.float32(labels.shape[-1] * labels.shape[-2])
    a_f = np.where(n_fg < min_pixels, np.float32(fg_target), a_f)
    t_f = np.maximum(a_f, np.float32(fg_target))
    w_fg = t_f / np.maximum(a_f, 1e-12)
    w_bg = np.where(a_f < 1, (1 - t_f) / np.maximum(1 - a_f, 1e-12), 1.0)
    return np.sqrt(np.where(fg, w_fg[..., None, None], w_bg[..., None, None])).astype(np.float32)


class OnnxFRTMTracker(NumpyVideoLoop):
    """FRTM on a VOS bundle; ``segment`` (``runtime.video_loop.NumpyVideoLoop``) takes and yields numpy arrays like
    ``FRTMLoop.segment`` tensors.

    Args:
        bundle: the bundle folder; threads, provider: as ``runtime.session.Graph``.

    Attributes:
        timings: accumulated milliseconds of ``frame`` (the frame graph), ``update`` and ``init``.
    """

    def __init__(self, bundle: str | Path, threads: int | None = None, provider: str = "cpu") -> None:
        self.bundle = Bundle(bundle, "vos", threads, provider)
        self.settings = self.bundle.section("settings")
        size = self.bundle.section("input")
        self.min_size, self.max_size = int(size["min_size"]), int(size["max_size"])
        self.graphs = {name: self.bundle.graph(name) for name in ("frame", "features", "init", "insert", "update")}
        self.timings: dict[str, float] = defaultdict(float)
        super().__init__(int(self.settings.get("process_height", 0)))

    def reset(self) -> None:
        """Forget the current video."""
        super().reset()
        self.wp = self.wf = None
        self.memory: list[np.ndarray] = []  # features, labels, pixel weights, weights, newest (one row per object)
        self.cg_state: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _tick(self, name: str, start: float) -> None:
        self.timings[name] += (time.perf_counter() - start) * 1000

    def _label_res(self, masks: np.ndarray) -> np.ndarray:
        """(..., H, W) soft masks at the memory label resolution (area resize by ``label_stride``)."""
        stride = int(self.settings["label_stride"])
        if stride == 1:
            return masks
        h, w = masks.shape[-2:]
        return area_resize(masks, (max(1, h // stride), max(1, w // stride)))

    def _pixel_weights(self, labels: np.ndarray) -> np.ndarray:
        if not self.settings["pixel_weighting"]:
            return np.ones_like(labels)
        return hinge_pixel_weights(labels, self.settings["fg_target"], self.settings["min_update_pixels"])

    def add_objects(self, image: np.ndarray, labels: np.ndarray, ids: list[int]) -> None:
        """Train target models for objects ``ids`` (masks ``labels == id`` in the (3, H, W) image in [0, 1])."""
        start = time.perf_counter()
        s = self.settings
        samples = [first_frame_augment(image, (labels == obj).astype(np.float32), s["num_aug"],
                                       s["seed"] + 7919 * i + obj) for i, obj in enumerate(ids)]
        b, k = len(ids), s["num_aug"]
        feats = self.graphs["features"](np.concatenate([im for im, _ in samples]))
        x = feats.reshape(b, k, *feats.shape[1:])
        y = self._label_res(np.stack([m for _, m in samples]))
        v = self._pixel_weights(y)
        gamma = np.ones((b, k), np.float32)
        gamma[:, 0] = 2
        gamma /= gamma.sum(1, keepdims=True)
        fits = [self.graphs["init"](x[i : i + 1], y[i : i + 1], v[i : i + 1], gamma[i : i + 1]) for i in range(b)]
        wp, wf = np.concatenate([f[0] for f in fits]), np.concatenate([f[1] for f in fits])
        z = np.einsum("bcd,bkdhw->bkchw", wp, x, optimize=True).astype(np.float32)
        weights = np.ones((b, k), np.float32)
        weights[:, 0] = 2.0
        memory = self._initial_memory(z, y, v, weights / weights.sum(1, keepdims=True))
        if self.ids:
            memory = [np.concatenate([a, c]) for a, c in zip(self.memory, memory, strict=True)]
            wp, wf = np.concatenate([self.wp, wp]), np.concatenate([self.wf, wf])
        self.ids += list(ids)
        self.wp, self.wf, self.memory, self.cg_state = wp, wf, memory, None
        self.optimize_filters()
        self._tick("init", start)

    def _initial_memory(self, z: np.ndarray, y: np.ndarray, v: np.ndarray, weights: np.ndarray) -> list[np.ndarray]:
        """The memory of ``memory_size`` slots holding the K initial samples (``models.vos.memory.memory_init``)."""
        capacity = int(self.settings["memory_size"])
        b, k = z.shape[:2]
        if capacity < k:
            raise InputError(f"memory capacity {capacity} is smaller than the {k} initial samples")

        def grow(a: np.ndarray) -> np.ndarray:
            return np.concatenate([a, np.zeros((b, capacity - k, *a.shape[2:]), a.dtype)], 1)

        return [grow(z), grow(y), grow(v), grow(weights), np.full(b, -1, np.int64)]

    def optimize_filters(self) -> None:
        """Re-optimise W_f of every object on its filled memory slots (one ``update`` graph call each)."""
        n = max(2, int((self.memory[3] > 0).sum(1).max()))
        if self.cg_state is None:
            self.cg_state = (np.zeros_like(self.wf), np.ones(len(self.wf), np.float32), np.zeros_like(self.wf))
        p, rho, r_prev = self.cg_state
        rows = [self.graphs["update"](*(m[i : i + 1, :n] for m in self.memory[:4]), self.wf[i : i + 1],
                                      p[i : i + 1], rho[i : i + 1], r_prev[i : i + 1]) for i in range(len(self.wf))]
        wf, p, rho, r_prev = (np.concatenate(column) for column in zip(*rows, strict=True))
        self.wf, self.cg_state = wf, (p, rho, r_prev)

    def step(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Labels (H, W), merged soft masks (N, H, W) and projected features (N, C, h, w) of a frame (3, H, W); the
        search region and the score support as ``FRTMLoop.step``."""
        start = time.perf_counter()
        logits, z = self.graphs["frame"](image[None], self.wp, self.wf)
        self._tick("frame", start)
        labels, soft = merge_objects(logits, self.ids)
        radius = float(self.settings.get("search_radius", 0.0))
        if radius > 0 and self.previous_labels is not None:
            drop = outside_search_region(labels, self.previous_labels, self.ids, radius)
            if drop.any():
                logits = np.where(drop, np.float32(DROPPED_LOGIT), logits)
                labels, soft = merge_objects(logits, self.ids)
        if self.settings.get("score_support", False):
            drop = unsupported_components(labels, target_score(z, self.wf), self.ids)
            if drop.any():
                logits = np.where(drop, np.float32(DROPPED_LOGIT), logits)
                labels, soft = merge_objects(logits, self.ids)
        return labels, soft, z

    def update(self, soft: np.ndarray, z: np.ndarray) -> None:
        """Insert soft masks (N, H, W) and features into the memory (as ``FRTMLoop.update``); optimise W_f every
        ``update_every`` frames."""
        start = time.perf_counter()
        if self.settings.get("memory_main_component", False):
            soft = soft * main_component(soft > 0.5)
        y = self._label_res(soft)
        rows = [self.graphs["insert"](*(m[i : i + 1] for m in self.memory), z[i : i + 1], y[i : i + 1])
                for i in range(len(self.ids))]
        self.memory = [np.concatenate(column) for column in zip(*rows, strict=True)]
        width = float(self.settings.get("ignore_band", 0.0))
        if width > 0:  # the inserted slots' pixel weights, zero on the band (the insert graph has no such input)
            inserted = np.nonzero((y > 0.5).sum((-2, -1)) >= int(self.settings["min_update_pixels"]))[0]
            slots, weights = self.memory[4][inserted], self.memory[2]
            band = ignore_band(y[inserted] > 0.5, width)
            weights[inserted, slots] = np.where(band, np.float32(0), weights[inserted, slots])
        if self.frame % int(self.settings["update_every"]) == 0:
            self.optimize_filters()
        self._tick("update", start)


def main(argv: list[str] | None = None) -> int:
    return video_command("runtime.vos", __doc__, OnnxFRTMTracker, argv)


if __name__ == "__main__":
    raise SystemExit(main())

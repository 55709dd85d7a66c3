"""Point-tracking benchmark (thesis fig. 3.3): C-COT (with memory and retrained every frame), MOSSE and
OpenCV's pyramidal Lucas-Kanade (KLT) from the same good-features-to-track start points.

Datasets: folders laid out like ``../shared/data/sintel/alley_1/clean`` (frames plus ``gt/``: Sintel, and the
Middlebury pairs in ``../shared/data/middlebury/<Seq>``; from the first ground-truth flow on, chained over
consecutive flows, ground truth by the thesis protocol; named ``<parent>_<folder>``; ``--sintel-conditions`` adds
the same folders under the photometric stress conditions below, dark, low contrast, illumination change, JPEG or
dark frames stored as JPEG at quality 90, named ``<parent>_<folder>_<condition>``), a seeded synthetic sequence
with chained ground truth (``--synthetic``) and the synthetic stress conditions of :mod:`data.flow.stress`
(``--stress [CONDITION ...]``, named ``stress_<condition>``: dark, low contrast, motion blur, fast motion,
illumination change, JPEG, a long run, occluders, dark frames stored as JPEG at quality 90) and
real photographs seen through chains of small homographies under growing defocus or motion blur, JPEG compression or
darkness (:mod:`data.flow.homography`, ``--homography IMAGE ...``, named ``homography_<condition>_<folder>_<file
stem>``, 6 frames; the conditions ``stress_dark`` etc. put every frame under a photometric stress condition
instead; ``--homography-cameras moving fixed`` adds the same sets seen by a fixed camera, as the Oxford
sets are, named ``homography_fixed_<condition>_...``; ``fixed`` alone runs only those; ``--homography-geometry G``
multiplies each step's rotation, scale change and tilt by G, a faster-turning and zooming camera, and
``--homography-step PX`` sets each step's largest translation per axis (default 6 px), a faster-moving one, both
recorded in the JSON), real sequences with known
homographies from their first frame, such as the Oxford sets or HPatches themselves (``--homography-folder DIR ...``,
:mod:`data.flow.homography_folder`, named ``homography_folder_<parent>_<folder>``) and real videos without
ground truth played forward and back (``--roundtrip DIR ...``, e.g. the DAVIS folders, named ``roundtrip_<folder>``:
``--roundtrip-frames`` frames from ``--roundtrip-start`` (default 0) on, every ``--roundtrip-stride``-th (default 1;
more: faster real motion), enlarged ``--roundtrip-scale`` times (default 1; bicubic, a stand-in for the same video at
a higher resolution, whose motion in pixels grows alike), then the same frames in reverse order back to the first, so
every point's truth at the last frame is its start; this measures the drift and the false tracks that real motion,
motion blur and deformation cause over many frames, but it would also reward a tracker that never moves, so it
complements the sets with ground truth rather than replacing them; ``--roundtrip-conditions`` adds sets of rows with
every frame degraded as in the homography sets, at ``--roundtrip-strength`` (1: as their last frame), or as in a
photometric stress set (``stress_dark`` etc.), named ``roundtrip_<condition>_<folder>``). Metrics at the last frame,
per method and dataset: ``epe_median``, ``epe_mean``, ``inlier_frac`` (not lost and EPE < 3 px), ``inlier_epe_mean``,
``precision_at`` (fraction not lost with EPE below 1, 2, 3 px), ``lost_frac``, ``point_frames_per_s``,
``first_call_s``, with KLT in the run ``speed_vs_klt`` (the ratio of point-frames per second) and, where an occluder
hid some points (``stress_occlusion``), ``occluded_lost_frac``: the fraction of those flagged lost. Lost points keep
their last position for the EPE statistics and never count as inliers. With KLT in the run, ``summary`` (JSON; the
table's last lines) counts per group of rows (``pairs``: the ``--sintel`` folders, ``pairs_<condition>``,
``synthetic``, ``stress``, ``homography[_fixed]_<condition>``, ``homography_folder``, ``roundtrip[_<condition>]``) and
over ``all`` of them the rows where each other method has at least KLT's inlier fraction and at most its mean inlier
EPE (a KLT row without inliers counts as beaten on precision), names the rows it loses and gives every method's means.

Timing: on the CPU every method is timed by the CPU time of this process (``time.process_time``) with torch and
OpenCV held to the same thread count, so the ratios hold on a machine shared with other jobs; with a CUDA device by
the wall clock after synchronisation. The JSON names the clock. The process keeps freed heap memory for reuse, as
``infer.py track`` does (:func:`core.allocator.retain_freed_memory`; ``retained_freed_memory`` in the JSON says
whether that took): the trackers' large temporaries are not faulted in afresh every frame. Every method first runs
once on the first two frames (warm-up; its wall time from a cold start, tracker construction included, is
``first_call_s``), then ``--repeats`` times (default 3) with the methods taking turns; the best time counts.
``--compile`` adds ``ccot_compiled``: ``ccot`` with its per-frame step through ``torch.compile`` (compiled during the
warm-up).
``--methods ... ccot_ort`` adds the deployment runtime's tracker (``runtime.tracking``: the exported ``ccot`` graphs
in onnxruntime with ``--threads`` threads) on ``--bundle DIR`` or a bundle exported into a temporary folder.
``--tracker KEY=JSON ...`` sets arguments of the DCF trackers (:class:`~models.tracking.PointTracker`, e.g.
``noise_reg=0``); the JSON echoes them under ``tracker``.

    python -m bench.point_tracking --sintel ../shared/data/sintel/alley_1/clean --synthetic --json \
        --plot docs/figures/point_tracking.png
    python -m bench.point_tracking --stress --methods ccot klt --plot stress.png   # also stress_conditions.png
    python -m bench.point_tracking --methods ccot klt --json \
        --homography ../shared/data/middlebury/{Dimetrodon,Hydrangea,RubberWhale,Venus}/frame_0010.png
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch

from core.allocator import retain_freed_memory
from core.checks import check_device
from core.errors import InputError
from core.frames import read_frame_gray, read_frames
from core.settings import parse_tracker
from core.threads import cpu_threads
from data.flow import (
    HOMOGRAPHY_CONDITIONS,
    PHOTOMETRIC_CONDITIONS,
    STRESS_CONDITIONS,
    degrade,
    homography_sequence,
    read_homography_folder,
    read_sintel_sequence,
    stress_frames,
    stress_sequence,
    synthetic_sequence,
    tracks_from_flow,
)
from models.tracking import PointTracker, good_features_to_track
from models.tracking.klt import klt_track

METHODS = ("ccot", "ccot_ff", "mosse", "klt")
STRESS_PREFIX = "stress_"  # sequence conditions taken from the stress sets (data.flow.stress_frames)
# the conditions of the homography sets and the round trips
SEQUENCE_CONDITIONS = (*HOMOGRAPHY_CONDITIONS, *(STRESS_PREFIX + c for c in PHOTOMETRIC_CONDITIONS))
COMPILED = "ccot_compiled"  # ccot with its step through torch.compile (--compile)
ORT = "ccot_ort"  # the runtime's tracker on a ccot bundle (onnxruntime)
_TRACKERS: dict[tuple, PointTracker] = {}
_ORT_TRACKERS: dict[tuple[str | None, int], object] = {}
THRESHOLDS = (1, 2, 3)


@dataclass
class Dataset:
    """Frames ``(T, H, W)`` uint8, start points ``(P, 2)``, ground truth at the last frame ``(P, 2)``, valid
    ``(P,)`` and, where known, ``occluded`` ``(P,)``: hidden by an occluder in some frame (they should be lost)."""

    frames: np.ndarray
    points: np.ndarray
    truth: np.ndarray
    valid: np.ndarray
    occluded: np.ndarray | None = None


@dataclass(frozen=True)
class Detector:
    """Start points: up to ``n`` good features to track in a uint8 frame, corners above ``quality`` times the
    strongest and ``spacing`` px apart (:func:`~models.tracking.good_features_to_track`), as (x, y) float64.
    The defaults give about 2900 points on a 1024 x 436 Sintel frame, spacing 1 and quality 0.0003 give 10000."""

    spacing: int = 3
    quality: float = 0.003

    def __post_init__(self) -> None:
        if not (self.spacing >= 1 and 0 < self.quality < 1):
            raise InputError(f"the detector's spacing (--spacing) must be at least 1 px and its quality "
                             f"(--quality) in (0, 1), got {self.spacing} and {self.quality}")

    def __call__(self, frame: np.ndarray, n: int) -> np.ndarray:
        corners = good_features_to_track(torch.from_numpy(frame.astype(np.float32)), n, self.quality, self.spacing)
        return corners.numpy().astype(np.float64)


DETECTOR = Detector()


def sintel_dataset(folder: str | Path, n_points: int, detector: Detector = DETECTOR,
                   condition: str | None = None, seed: int = 0) -> Dataset:
    """Sintel folder from its first ground-truth flow on, over every consecutive ground-truth flow (one pair
    in ``../shared/data``), ground truth chained from flow with occluded and divergent points removed;
    ``condition``: the frames under that photometric stress condition (:func:`data.flow.stress_frames`, seeded),
    the start points detected in the degraded first frame."""
    pairs = read_sintel_sequence(folder)
    frames = np.stack([pairs[0].frame0] + [p.frame1 for p in pairs])
    if condition is not None:
        frames = stress_frames(frames, condition, seed)
    frames = frames.round().clip(0, 255).astype(np.uint8)
    points = detector(frames[0], n_points)
    tracks, valid = tracks_from_flow(points, [p.flow for p in pairs], [p.bad for p in pairs])
    return Dataset(frames, points, tracks[-1], valid[-1])


def _tracked(seq, n_points: int, detector: Detector) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A generated sequence's frames as uint8 ``(T, H, W)``, start points detected in frame 0 and their ground
    truth (``seq.track``): frames, points, tracks ``(T, P, 2)``, valid ``(T, P)``."""
    frames = seq.frames.round().clip(0, 255).astype(np.uint8)
    points = detector(frames[0], n_points)
    return frames, points, *seq.track(points)


def synthetic_dataset(n_frames: int, n_points: int, seed: int = 0, detector: Detector = DETECTOR) -> Dataset:
    """Synthetic sequence (large motion, blur, noise, brightness change), ground truth at the last frame."""
    frames, points, tracks, valid = _tracked(synthetic_sequence(frames=n_frames, seed=seed), n_points, detector)
    return Dataset(frames, points, tracks[-1], valid[-1])


def stress_dataset(condition: str, n_frames: int, n_points: int, seed: int = 0,
                   detector: Detector = DETECTOR) -> Dataset:
    """The synthetic sequence under one stress condition (:mod:`data.flow.stress`), ground truth at the last
    frame."""
    seq = stress_sequence(condition, frames=n_frames, seed=seed)
    frames, points, tracks, valid = _tracked(seq, n_points, detector)
    occluded = seq.hidden(tracks).any(0) if seq.occluder is not None else None
    return Dataset(frames, points, tracks[-1], valid[-1], occluded)


def homography_dataset(image: str | Path, condition: str, n_points: int, seed: int = 0,
                       detector: Detector = DETECTOR, frames: int = 6, moving: bool = True,
                       geometry: float = 1.0, step: float = 6.0) -> Dataset:
    """A real photograph (read as gray) through ``frames`` chained homographies under ``condition``
    (:func:`data.flow.homography_sequence`; ``moving=False``: a fixed camera; ``geometry``: the multiplier of
    each step's rotation, scale change and tilt; ``step``: the largest translation of a step per axis, px) or,
    for ``stress_<condition>``, the undegraded views under that photometric stress condition
    (:func:`data.flow.stress_frames`, seeded: every frame at full strength), ground truth at the last frame."""
    stress = condition.removeprefix(STRESS_PREFIX) if condition.startswith(STRESS_PREFIX) else None
    photograph = read_frame_gray(image)
    try:
        seq = homography_sequence(photograph, "none" if stress else condition, frames, seed, step, moving=moving,
                                  geometry=geometry)
    except InputError as err:  # the sequence's own checks do not know the file
        raise InputError(f"{image}: {err}") from err
    if stress:
        seq.frames = stress_frames(seq.frames, stress, seed)
    frames_u8, points, tracks, valid = _tracked(seq, n_points, detector)
    return Dataset(frames_u8, points, tracks[-1], valid[-1])


def homography_folder_dataset(folder: str | Path, n_points: int, detector: Detector = DETECTOR) -> Dataset:
    """A real sequence with known homographies from its first frame (:func:`data.flow.read_homography_folder`:
    the Oxford sets' or HPatches' layout), ground truth at the last frame (points that stay 6 px inside every
    frame)."""
    frames, points, tracks, valid = _tracked(read_homography_folder(folder), n_points, detector)
    return Dataset(frames, points, tracks[-1], valid[-1])


def roundtrip_dataset(folder: str | Path, n_frames: int, n_points: int, detector: Detector = DETECTOR,
                      condition: str = "none", strength: float = 1.0, seed: int = 0,
                      start: int = 0, stride: int = 1, scale: float = 1.0) -> Dataset:
    """``n_frames`` frames of a real video (a folder of images, :func:`~core.frames.read_frames`) from frame
    ``start`` on, every ``stride``-th (2 or more: the video's own motion that many times faster per frame), and
    then the same frames back to the first (``2 n_frames - 1`` in all), every frame degraded by ``condition`` at
    ``strength`` (:func:`data.flow.degrade`, seeded; ``motion`` in one direction drawn from the seed) or, for
    ``stress_<condition>``, by that photometric stress condition (:func:`data.flow.stress_frames`, seeded; no
    strength), after enlarging every frame ``scale`` times (bicubic; 1: as stored); the truth at the last frame is
    the start points themselves."""
    if n_frames < 2 or start < 0 or stride < 1:
        raise InputError(f"a round trip needs at least 2 frames from a start >= 0 with a stride >= 1, got "
                         f"{n_frames} from {start} with stride {stride}")
    if not (1 <= scale <= 8):
        raise InputError(f"a round trip's scale must lie in [1, 8], got {scale}")
    needed = start + stride * (n_frames - 1) + 1
    frames, _ = read_frames(folder, limit=needed)  # the frames played, not the whole video
    if len(frames) < needed:
        raise InputError(f"{folder}: {len(frames)} frames, the round trip asks for {n_frames} from frame {start} "
                         f"with stride {stride}")
    frames = frames[start::stride]
    if scale != 1:
        frames = [cv2.resize(np.asarray(f, np.float32), None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
                  for f in frames]
    if condition.startswith(STRESS_PREFIX):
        frames = stress_frames(np.stack(frames), condition.removeprefix(STRESS_PREFIX), seed)
    elif condition != "none":
        rng = np.random.default_rng([seed, HOMOGRAPHY_CONDITIONS.index(condition)])
        angle = rng.uniform(0, np.pi)
        frames = [degrade(frame, condition, strength, rng, angle) for frame in frames]
    forward = np.stack(frames).round().clip(0, 255).astype(np.uint8)
    frames = np.concatenate([forward, forward[-2::-1]])
    points = detector(frames[0], n_points)
    return Dataset(frames, points, points.astype(np.float64), np.ones(len(points), dtype=bool))


def clock(device: str):
    """The timer for a run on ``device``: CPU time of this process on the CPU, the wall clock otherwise."""
    return time.process_time if device == "cpu" else time.perf_counter


def clock_name(device: str) -> str:
    """The name of :func:`clock`'s timer for ``device``, as the benchmarks' JSON gives it."""
    return "process_cpu_time" if device == "cpu" else "wall"


def run_klt(frames: np.ndarray, points: np.ndarray, device: str = "cpu") -> tuple[np.ndarray, np.ndarray, float]:
    """``cv2.calcOpticalFlowPyrLK`` (21x21, 3 levels) frame to frame; returns last positions, lost and seconds
    (by the clock of ``device``'s runs, see :func:`clock`)."""
    timer = clock(device)
    start = timer()
    tracks, lost = klt_track(list(frames), points)
    return tracks[-1], lost[-1], timer() - start


def dcf_tracker(method: str, device: str = "cpu", settings: dict | None = None) -> PointTracker:
    """``PointTracker(method, **settings)`` on ``device``, made once per (method, device, settings); an unknown
    or invalid setting is an ``InputError``."""
    settings = settings or {}
    key = (method, device, json.dumps(settings, sort_keys=True))
    if key not in _TRACKERS:
        try:
            _TRACKERS[key] = PointTracker(method, **settings).to(device)
        except TypeError as err:
            raise InputError(f"--tracker: {err}") from err
    return _TRACKERS[key]


def run_dcf(method: str, frames: np.ndarray, points: np.ndarray, device: str = "cpu", compile: bool = False,
            settings: dict | None = None):
    """Our tracker (:func:`dcf_tracker`); returns last positions, lost flags and seconds spent tracking (frames
    already in memory). ``compile``: the per-frame step through ``torch.compile`` (compiled in the warm-up run:
    one tracker per method, device and settings serves every run)."""
    tracker = dcf_tracker(method, device, settings)
    tensors = [torch.from_numpy(f.astype(np.float32)).to(device) for f in frames]
    pts = torch.from_numpy(points.astype(np.float32)).to(device)
    timer = clock(device)
    if device != "cpu":
        torch.cuda.synchronize()
    start = timer()
    tracks, lost, _ = tracker.track(tensors, pts, compile=compile)
    if device != "cpu":
        torch.cuda.synchronize()
    return tracks[-1].double().cpu().numpy(), lost[-1].cpu().numpy(), timer() - start


def run_ort(frames: np.ndarray, points: np.ndarray, bundle: str | Path | None = None, threads: int = 1,
            device: str = "cpu"):
    """The runtime's tracker (``runtime.tracking.OnnxPointTracker``, on the CPU) on ``bundle`` (default: a ccot bundle
    exported into a temporary folder once); returns last positions, lost flags and seconds spent tracking (by the
    clock of ``device``'s runs, as KLT's, see :func:`clock`)."""
    from runtime.tracking import OnnxPointTracker

    key = (None if bundle is None else str(bundle), threads)
    if key not in _ORT_TRACKERS:
        if bundle is None:
            from export.tracking_onnx import export_bundle

            bundle = export_bundle(Path(tempfile.mkdtemp(prefix="tracking_bundle_")) / "bundle", "ccot")
        _ORT_TRACKERS[key] = OnnxPointTracker(bundle, threads=threads)
    tracker = _ORT_TRACKERS[key]
    images = [f.astype(np.float32) for f in frames]
    timer = clock(device)
    start = timer()
    tracks, lost, _ = tracker.track(images, points)
    return tracks[-1].astype(np.float64), lost[-1], timer() - start


def metrics(pred: np.ndarray, lost: np.ndarray, data: Dataset, seconds: float) -> dict:
    """Statistics over the points with valid ground truth at the last frame."""
    epe = np.linalg.norm(pred[data.valid] - data.truth[data.valid], axis=1)
    tracked = ~lost[data.valid]
    inlier = tracked & (epe < 3)
    n_tracked = len(data.points) * (len(data.frames) - 1)
    return {
        "epe_median": float(np.median(epe)),
        "epe_mean": float(np.mean(epe)),
        "inlier_frac": float(inlier.mean()),
        "inlier_epe_mean": float(epe[inlier].mean()) if inlier.any() else float("nan"),
        "precision_at": {str(t): float((tracked & (epe < t)).mean()) for t in THRESHOLDS},
        "lost_frac": float((~tracked).mean()),
        "point_frames_per_s": n_tracked / seconds,
        **({"occluded_lost_frac": float(lost[data.occluded].mean())} if data.occluded is not None else {}),
        "epe": epe.tolist(),
        "tracked": tracked.tolist(),
    }


def run_method(method: str, frames: np.ndarray, points: np.ndarray, device: str = "cpu",
               bundle: str | Path | None = None, settings: dict | None = None):
    """One run of ``method`` (a DCF variant with ``settings``, ``ccot_compiled``, ``ccot_ort`` on ``bundle`` or
    ``klt``): last positions, lost, seconds."""
    if method == "klt":
        return run_klt(frames, points, device)
    if method == ORT:
        return run_ort(frames, points, bundle, torch.get_num_threads(), device)
    compiled = method == COMPILED
    return run_dcf("ccot" if compiled else method, frames, points, device, compiled, settings)


def evaluate(datasets: dict[str, Dataset], methods=METHODS, device: str = "cpu", repeats: int = 3,
             bundle: str | Path | None = None, settings: dict | None = None) -> dict:
    """Run every method on every dataset; one result dict per method (with per-point EPEs under ``epe``);
    ``settings``: keyword arguments of every DCF tracker (:class:`PointTracker`).

    Each method first runs once on the first two frames (warm-up: one-time start-up costs; its wall time,
    tracker construction and any compilation included, is ``first_call_s``, meaningful for the first dataset), then
    ``repeats`` times on the whole sequence, the methods taking turns; the time is the best of the repeats (the
    least disturbed by other jobs), the accuracy that of the last run (the trackers are deterministic)."""
    out = {}
    for name, data in datasets.items():
        first_call = {}
        for method in methods:
            start = time.perf_counter()
            run_method(method, data.frames[:2], data.points, device, bundle, settings)
            first_call[method] = time.perf_counter() - start
        seconds = {method: [] for method in methods}
        last = {}
        for _ in range(repeats):
            for method in methods:
                *last[method], elapsed = run_method(method, data.frames, data.points, device, bundle, settings)
                seconds[method].append(elapsed)
        results = {method: metrics(*last[method], data, min(seconds[method])) for method in methods}
        for method, m in results.items():
            m["first_call_s"] = first_call[method]
        if "klt" in results:
            for m in results.values():
                m["speed_vs_klt"] = m["point_frames_per_s"] / results["klt"]["point_frames_per_s"]
        out[name] = {
            "frames": len(data.frames),
            "points": len(data.points),
            "evaluated_points": int(data.valid.sum()),
            "methods": results,
        }
    return out


def beats_klt(row: dict, klt: dict) -> tuple[bool, bool]:
    """Whether a method's row has (inliers) at least KLT's inlier fraction and (precision) at most its mean
    inlier EPE; a KLT row without inliers (EPE NaN) is beaten on precision by any row, a row without inliers beats
    no KLT row that has some."""
    inliers = row["inlier_frac"] >= klt["inlier_frac"]
    precision = math.isnan(klt["inlier_epe_mean"]) or row["inlier_epe_mean"] <= klt["inlier_epe_mean"]
    return inliers, precision


def summary(result: dict, groups: dict[str, str]) -> dict:
    """Per group of rows (``groups``: dataset name -> group) and over ``all``: the number of rows; per method the
    mean inlier fraction, mean inlier EPE (over the rows with inliers; NaN if none) and mean lost fraction; with
    KLT in the run, per other method the rows where it beats KLT in both numbers, in inliers and in precision
    (:func:`beats_klt`) and the names of the rows it loses."""
    out = {}
    for group in [*dict.fromkeys(groups[name] for name in result), "all"]:
        names = [name for name in result if group in ("all", groups[name])]
        rows = [result[name]["methods"] for name in names]
        methods = {}
        for method in rows[0]:
            epes = [r[method]["inlier_epe_mean"] for r in rows if not math.isnan(r[method]["inlier_epe_mean"])]
            stats = {
                "inlier_frac_mean": float(np.mean([r[method]["inlier_frac"] for r in rows])),
                "inlier_epe_mean": float(np.mean(epes)) if epes else float("nan"),
                "lost_frac_mean": float(np.mean([r[method]["lost_frac"] for r in rows])),
            }
            if method != "klt" and "klt" in rows[0]:
                verdicts = [beats_klt(r[method], r["klt"]) for r in rows]
                stats.update(
                    rows_beating_klt=sum(a and b for a, b in verdicts),
                    rows_beating_klt_inliers=sum(a for a, _ in verdicts),
                    rows_beating_klt_precision=sum(b for _, b in verdicts),
                    rows_losing=[name for name, v in zip(names, verdicts, strict=True) if not all(v)],
                )
            methods[method] = stats
        out[group] = {"rows": len(names), "methods": methods}
    return out


def summary_lines(summaries: dict) -> list[str]:
    """The readable form of :func:`summary`: one line per group and method beside KLT."""
    lines = []
    for group, entry in summaries.items():
        means = ", ".join(f"{m} {s['inlier_frac_mean']:.3f} / {s['inlier_epe_mean']:.3f} px"
                          for m, s in entry["methods"].items())
        lines.append(f"summary {group} ({entry['rows']} rows), mean inliers / inlier EPE: {means}")
        for method, s in entry["methods"].items():
            if "rows_beating_klt" in s:
                lines.append(f"  {method} >= klt in both on {s['rows_beating_klt']} of {entry['rows']} rows "
                             f"(inliers {s['rows_beating_klt_inliers']}, precision "
                             f"{s['rows_beating_klt_precision']}); loses: {', '.join(s['rows_losing']) or '-'}")
    return lines


def table(result: dict) -> str:
    """Readable table of a result (without per-point EPEs)."""
    lines = []
    for name, ds in result.items():
        lines.append(
            f"{name}: {ds['points']} points, {ds['frames']} frames, {ds['evaluated_points']} evaluated"
        )
        lines.append(
            f"  {'method':13s} {'inliers':>8s} {'inl.EPE':>8s} {'EPE med':>8s} {'EPE mean':>9s} "
            f"{'P@1':>6s} {'P@2':>6s} {'lost':>6s} {'pt-fr/s':>9s} {'vs klt':>7s} {'1st call':>8s}"
        )
        for method, m in ds["methods"].items():
            lines.append(
                f"  {method:13s} {m['inlier_frac']:8.3f} {m['inlier_epe_mean']:8.3f} {m['epe_median']:8.3f} "
                f"{m['epe_mean']:9.2f} {m['precision_at']['1']:6.3f} {m['precision_at']['2']:6.3f} "
                f"{m['lost_frac']:6.3f} {m['point_frames_per_s']:9.0f} {m.get('speed_vs_klt', float('nan')):7.3f}"
                f" {m['first_call_s']:7.2f}s"
            )
    return "\n".join(lines)


def plot_conditions(result: dict, path: str | Path) -> None:
    """Inlier fraction and mean inlier EPE of every method per dataset (condition), as grouped bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result)
    methods = list(next(iter(result.values()))["methods"])
    fig, axes = plt.subplots(2, 1, figsize=(max(7.0, 0.9 * len(names) + 2), 6.5), sharex=True)
    width = 0.8 / len(methods)
    x = np.arange(len(names))
    for i, method in enumerate(methods):
        for ax, key in zip(axes, ("inlier_frac", "inlier_epe_mean"), strict=True):
            values = [result[n]["methods"][method][key] for n in names]
            ax.bar(x + (i - (len(methods) - 1) / 2) * width, values, width, label=method)
    axes[0].set(ylabel="inliers (not lost, EPE < 3 px)", ylim=(0, 1), title="per dataset and condition")
    axes[1].set(ylabel="mean inlier EPE (px)")
    labels = [n.replace("stress_", "").replace("homography_", "h_").replace("roundtrip_", "") for n in names]
    axes[1].set_xticks(x, labels, rotation=30, ha="right")
    axes[0].legend(fontsize=8, ncol=len(methods))
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _wrapped(name: str, width: int) -> str:
    """``name`` broken into lines of at most ``width`` characters after its underscores (dataset names have no
    spaces)."""
    return "\n".join(line.replace("_ ", "_") for line in textwrap.wrap(name.replace("_", "_ "), width))


def plot(result: dict, path: str | Path) -> None:
    """EPE distributions (log-spaced histogram, mean inlier EPE in the legend) and precision curves (value at 3 px
    in the legend) per dataset, like thesis figure 3.3, four datasets to a row (long dataset names wrapped in the
    titles); with several datasets also the per-condition bars (:func:`plot_conditions`) beside it, as
    ``<path stem>_conditions.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if len(result) > 1:
        path = Path(path)
        plot_conditions(result, path.with_name(f"{path.stem}_conditions{path.suffix}"))
    # two panels (EPE histogram, precision curve) per dataset, four datasets to a row
    columns = min(len(result), 4)
    rows = -(-len(result) // columns)
    fig, axes = plt.subplots(rows, 2 * columns, figsize=(5.2 * columns, 3.4 * rows), squeeze=False)
    for ax in axes.flat[2 * len(result):]:
        ax.set_axis_off()
    bins = np.logspace(-3, 2, 51)
    taus = np.linspace(0, 5, 101)
    for i, (name, ds) in enumerate(result.items()):
        hist, curve = axes[i // columns, 2 * (i % columns)], axes[i // columns, 2 * (i % columns) + 1]
        for method, m in ds["methods"].items():
            epe, tracked = np.maximum(np.asarray(m["epe"]), 1e-3), np.asarray(m["tracked"])
            hist.hist(epe, bins, histtype="step", density=False, label=f"{method} ({m['inlier_epe_mean']:.2f})")
            precision = [(tracked & (epe < t)).mean() for t in taus]
            curve.plot(taus, precision, label=f"{method} ({m['precision_at']['3']:.3f})")
        hist.set(xscale="log", xlabel="EPE (px)", ylabel="points")
        curve.set(xlabel="threshold (px)", ylabel="precision", ylim=(0, 1))
        for ax, quantity in ((hist, "EPE"), (curve, "precision")):
            ax.set_title(f"{_wrapped(name, 30)}: {quantity}", fontsize=9)
        hist.legend(fontsize=7)
        curve.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_tracks(data: Dataset, path: str | Path, methods: tuple[str, ...] = ("ccot", "klt"), trail: int = 6) -> None:
    """The last frame with each method's tracks of the points still in view (the last ``trail`` frames, green),
    those flagged lost (red x) and the ground truth (white dots), side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from models.tracking.run import track_points

    fig, axes = plt.subplots(1, len(methods), figsize=(6 * len(methods), 4.6), squeeze=False)
    last = len(data.frames) - 1
    for ax, method in zip(axes[0], methods, strict=True):
        result = track_points(list(data.frames), data.points, method=method)
        tracks, lost = result["tracks"], result["lost"]
        ax.imshow(data.frames[last], cmap="gray", vmin=0, vmax=255)
        ok = data.valid & ~lost[last]
        for p in np.flatnonzero(ok):
            ax.plot(tracks[last - trail : last + 1, p, 0], tracks[last - trail : last + 1, p, 1], color="lime", lw=0.8)
        ax.scatter(*data.truth[data.valid].T, s=4, c="white", label="ground truth")
        ax.scatter(*tracks[last, lost[last] & data.valid].T, s=14, c="red", marker="x", label="lost")
        inliers = ok & (np.linalg.norm(tracks[last] - data.truth, axis=-1) < 3)
        ax.set_title(f"{method}: {int(inliers.sum())} of the {int(data.valid.sum())} points still in view within "
                     f"3 px of the truth; {int((lost[last] & data.valid).sum())} of them flagged lost", fontsize=9)
        ax.set_axis_off()
        ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Small run (< 1 minute on 2 cores): synthetic sequence of 20 frames (10 quick), 150 points, all methods.
    With ``report_dir``, writes the EPE distributions and precision curves there; returns the figures."""
    data = synthetic_dataset(10 if quick else 20, 150, seed=1)
    retain_freed_memory()  # as infer.py track
    with cpu_threads(1):
        result = evaluate({"synthetic": data}, repeats=1)
        print(table(result))
        if report_dir is None:
            return []
        plot_tracks(data, report_dir / "point_tracks.png")
    plot(result, report_dir / "point_tracking.png")
    return [("point_tracks.png", "Tracks on the last frame of the synthetic sequence (large motion, blur, noise, "
             "brightness change): the continuous correlation filter (ccot) against KLT, lost points marked"),
            ("point_tracking.png", "End-point errors and precision curves of the correlation filters (ccot, mosse) "
             "and KLT on the same sequence")]


def build_parser() -> argparse.ArgumentParser:
    """The benchmark's arguments (``--sintel`` may be given several times; all folders count)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sintel", nargs="+", action="extend", default=[], metavar="DIR",
                        help="Sintel folders (frames plus gt/); repeat or list several")
    parser.add_argument("--sintel-conditions", nargs="+", choices=PHOTOMETRIC_CONDITIONS, default=[],
                        metavar="CONDITION", help="add the --sintel folders under these photometric stress "
                        "conditions, each a set of rows: " + ", ".join(PHOTOMETRIC_CONDITIONS))
    parser.add_argument("--synthetic", action="store_true", help="add the synthetic sequence")
    parser.add_argument("--stress", nargs="*", choices=STRESS_CONDITIONS, metavar="CONDITION",
                        help="add synthetic stress conditions (all without names): " + ", ".join(STRESS_CONDITIONS))
    parser.add_argument("--homography", nargs="+", action="extend", default=[], metavar="IMAGE",
                        help="real images to track through chained homographies; repeat or list several")
    parser.add_argument("--homography-conditions", nargs="+", choices=SEQUENCE_CONDITIONS,
                        default=["blur", "motion", "jpeg", "light"], metavar="CONDITION",
                        help="degradations of the homography sequences: " + ", ".join(SEQUENCE_CONDITIONS))
    parser.add_argument("--homography-cameras", nargs="+", choices=("moving", "fixed"), default=["moving"],
                        help="moving: the chained homographies; fixed: the same frames' degradation with a camera "
                        "that does not move (as in the Oxford sets), rows named homography_fixed_<condition>_...")
    parser.add_argument("--homography-geometry", type=float, default=1.0, metavar="G",
                        help="multiplier of each homography step's rotation (up to 2 degrees), scale change (3 %%) "
                        "and tilt (default 1; 3: up to 6 degrees and 9 %% a frame, a fast-turning or zooming camera)")
    parser.add_argument("--homography-step", type=float, default=6.0, metavar="PX",
                        help="largest translation of each homography step along each axis in px (default 6; 30: up "
                        "to about 42 px a frame, fast motion as in a handheld or vehicle camera)")
    parser.add_argument("--homography-folder", nargs="+", action="extend", default=[], metavar="DIR",
                        help="real sequences with known homographies from their first frame (Oxford layout "
                        "img1.ppm + H1to2p ..., or HPatches 1.ppm + H_1_2 ...); repeat or list several")
    parser.add_argument("--roundtrip", nargs="+", action="extend", default=[], metavar="DIR",
                        help="real video frame folders to track forward and back to the first frame")
    parser.add_argument("--roundtrip-frames", type=int, default=12,
                        help="frames of each round-trip video played forward (then back)")
    parser.add_argument("--roundtrip-start", type=int, default=0,
                        help="the round trips' first frame (index into each video's sorted frames)")
    parser.add_argument("--roundtrip-stride", type=int, default=1,
                        help="play every k-th frame of the round-trip videos (k times their motion per frame)")
    parser.add_argument("--roundtrip-scale", type=float, default=1.0,
                        help="enlarge the round-trip frames this many times (bicubic, 1-8; default 1), a stand-in for "
                        "the videos at a higher resolution, e.g. 3: 240p DAVIS frames at 720p")
    parser.add_argument("--roundtrip-conditions", nargs="+", choices=SEQUENCE_CONDITIONS, default=["none"],
                        metavar="CONDITION", help="degradations of the round-trip videos, each a set of rows: "
                        + ", ".join(SEQUENCE_CONDITIONS))
    parser.add_argument("--roundtrip-strength", type=float, default=1.0,
                        help="strength in [0, 1] of the round-trip degradations (1: the homography sets' last frame)")
    parser.add_argument("--frames", type=int, default=24, help="synthetic sequence length")
    parser.add_argument("--seed", type=int, default=0, help="synthetic sequence seed")
    parser.add_argument("--points", type=int, default=2000, help="start points to detect per dataset")
    parser.add_argument("--spacing", type=int, default=3,
                        help="least distance between detected points in px")
    parser.add_argument("--quality", type=float, default=0.003,
                        help="least corner response of a detected point, relative to the strongest (the defaults "
                             "give about 2900 points on a Sintel frame, --spacing 1 --quality 0.0003 give 10000)")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=(*METHODS, ORT))
    parser.add_argument("--bundle", metavar="DIR",
                        help=f"ccot tracking bundle for {ORT} (default: one exported into a temporary folder)")
    parser.add_argument(
        "--compile",
        action="store_true",
        help=f"also run ccot with its step through torch.compile ({COMPILED}; compiled in the warm-up)",
    )
    parser.add_argument("--tracker", nargs="+", metavar="KEY=JSON",
                        help="settings of the DCF trackers (PointTracker arguments), e.g. noise_reg=0 "
                             f"'patch_size=[31,15,15,15,15]'; not of {ORT}, which runs its bundle's")
    parser.add_argument("--device", default="cpu", help="torch device for the DCF trackers")
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="CPU threads for torch and OpenCV alike (1: fair on a shared CPU)",
    )
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per method; the best one counts")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--plot", help="write EPE distributions and precision curves to this PNG")
    return parser


def build_datasets(args: argparse.Namespace) -> tuple[dict[str, Dataset], dict[str, str]]:
    """The datasets the arguments ask for, by name, and the group of each (see :func:`summary`)."""
    datasets, groups = {}, {}
    detector = Detector(args.spacing, args.quality)
    for folder in args.sintel:
        path = Path(folder)
        name = f"{path.parent.name}_{path.name}"
        datasets[name], groups[name] = sintel_dataset(path, args.points, detector), "pairs"
        for condition in args.sintel_conditions:
            datasets[f"{name}_{condition}"] = sintel_dataset(path, args.points, detector, condition, args.seed)
            groups[f"{name}_{condition}"] = f"pairs_{condition}"
    for camera in args.homography_cameras if args.homography else []:
        for condition in args.homography_conditions:
            group = "_".join(["homography", *(["fixed"] if camera == "fixed" else []), condition])
            for image in args.homography:
                path = Path(image)
                name = f"{group}_{path.parent.name}_{path.stem}"
                datasets[name] = homography_dataset(path, condition, args.points, args.seed, detector,
                                                    moving=camera == "moving", geometry=args.homography_geometry,
                                                    step=args.homography_step)
                groups[name] = group
    for folder in args.homography_folder:
        path = Path(folder)
        name = f"homography_folder_{path.parent.name}_{path.name}"
        datasets[name], groups[name] = homography_folder_dataset(path, args.points, detector), "homography_folder"
    for condition in args.roundtrip_conditions if args.roundtrip else []:
        group = "_".join(["roundtrip", *([condition] if condition != "none" else [])])
        for folder in args.roundtrip:
            name = f"{group}_{Path(folder).name}"
            datasets[name] = roundtrip_dataset(folder, args.roundtrip_frames, args.points, detector, condition,
                                               args.roundtrip_strength, args.seed, args.roundtrip_start,
                                               args.roundtrip_stride, args.roundtrip_scale)
            groups[name] = group
    if args.synthetic or not (datasets or args.stress is not None):
        datasets["synthetic"] = synthetic_dataset(args.frames, args.points, args.seed, detector)
        groups["synthetic"] = "synthetic"
    for condition in STRESS_CONDITIONS if args.stress == [] else args.stress or []:
        datasets[f"stress_{condition}"] = stress_dataset(condition, args.frames, args.points, args.seed, detector)
        groups[f"stress_{condition}"] = "stress"
    return datasets, groups


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    retained = retain_freed_memory()
    try:
        settings = parse_tracker(args.tracker)
        check_device(args.device, "--device")
        with cpu_threads(args.threads):
            datasets, groups = build_datasets(args)
            methods = [*args.methods, *([COMPILED] if args.compile else [])]
            result = evaluate(datasets, methods, args.device, args.repeats, args.bundle, settings)
    except InputError as err:
        sys.stderr.write(f"bench/point_tracking.py: error: {err}\n")
        return 2
    if args.plot:
        plot(result, args.plot)
    for ds in result.values():
        for m in ds["methods"].values():
            del m["epe"], m["tracked"]
    if args.json:
        print(json.dumps({"datasets": result, "summary": summary(result, groups), "device": args.device,
                          "threads": args.threads, "clock": clock_name(args.device),
                          "timing": f"best of {args.repeats} runs", "tracker": settings,
                          "detector": {"spacing": args.spacing, "quality": args.quality},
                          **({"homography_geometry": args.homography_geometry,
                              "homography_step": args.homography_step} if args.homography else {}),
                          **({"roundtrip_scale": args.roundtrip_scale} if args.roundtrip else {}),
                          "retained_freed_memory": retained}))
    else:
        print("\n".join([table(result), *summary_lines(summary(result, groups))]))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""DCF point tracking from the exported graphs (thesis ch. 3), torch-free.

    python -m runtime.tracking --bundle DIR --frames DIR_OR_GLOB (--points FILE | --detect N) --out tracks.npz
                               [--threads N] [--provider cpu|cuda|tensorrt|coreml]

Start points come from a file or from OpenCV's good features to track (Shi-Tomasi) in the first frame; the
bundle's ``init`` graph trains every point's filters on it, then its ``step`` graph tracks all points into each
next frame (pyramid, coarse-to-fine correlation, lost flags and filter updates inside the graph; the filters are
numpy state between the calls). Blur matching as in ``PointTracker.step``: the ``profile`` and ``relative_blur``
graphs measure how much blurrier each frame is than the one the filters were last trained afresh on, and beyond
the bundle's ``blur_match_px2`` the sharper view is blurred (``cv2.GaussianBlur``) before the search; where the
``streak`` graph finds straight motion blur (``core.streak.streak_found`` with the bundle's ``streak_score``) that
changes by more than its ``streak_match_px2`` (``blur_match_px2`` where the streak reads the same in the frame's
four quarters), each view is blurred by the other's streak instead. Where the ``snr`` graph reads the first frame's
points (those inside it) with a median signal-to-noise ratio below the bundle's ``low_snr``, the whole sequence
runs on the ``init_low_snr`` and ``step_low_snr`` graphs (``PointTracker.init``'s low-SNR twin); where the first
step's PSRs are low and the ``first_step_noise`` graph reads its residuals as noise that the frame's estimate
under-read, that step runs again on them from the first frame, with the noise it read as the frame's least noise
(``PointTracker._low_snr_retry``). Frames of at least the bundle's ``large_min_side`` px a side run on the
``*_large`` graphs, with every pyramid level (the fifth searches only in such frames). Where the ``turn`` graph
reads the tracked points' steps as a camera turn beyond the bundle's ``turn_match``, the step runs again from the
previous frame warped by the similarity fitted to them (``cv2.warpAffine``; ``PointTracker._turn_matched_step``);
where a retried first step turns, the usual graphs track it again so, from the turn the low-SNR step gave, and the
retry decides again. The tracks file holds what ``infer.py track`` writes: ``tracks`` (T, P, 2), ``lost`` (T, P),
``psr`` (T, P), the start ``points``, ``method`` and ``frames``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from core.command import CommandParser, run_command
from core.errors import InputError
from core.files import writable_folder, write_npz
from core.frames import read_frames, read_points
from core.good_features import good_features
from core.progress import progress as progress_line
from core.streak import (
    Streak,
    quarter_slices,
    streak_blur,
    streak_change,
    streak_found,
    streak_uniform,
    streaks_matched,
)
from runtime.bundle import Bundle, add_runtime_arguments


@dataclass
class _Tracks:
    """The host loop's state after a frame: the step graph's outputs (positions, lost flags, PSRs, running PSR
    means, filters), the radial power profiles of the frame the filters were last trained afresh on
    (``reference``) and of the last frame (``last``; None: not measured yet), the last frame's streak and the
    filters' streaks (``template``)."""

    positions: np.ndarray
    flags: np.ndarray
    scores: np.ndarray
    means: np.ndarray
    filters: list
    reference: np.ndarray | None = None
    last: np.ndarray | None = None
    streak: Streak | None = None
    template: tuple[Streak, ...] = ()


class OnnxPointTracker:
    """The point tracker of a tracking bundle.

    Args:
        bundle: the bundle folder; threads, provider: as ``runtime.session.Graph``.
    """

    def __init__(self, bundle: str | Path, threads: int | None = None, provider: str = "cpu") -> None:
        self.bundle = Bundle(bundle, "tracking", threads, provider)
        self.method = self.bundle.section("settings")["method"]
        size = self.bundle.section("input")
        self.min_size, self.max_size = int(size["min_size"]), int(size["max_size"])
        # frames of at least large_min_side px a side run on the *_large graphs, whose deeper levels search there
        self.large_min_side = int(size["large_min_side"])
        self.large = False
        self.init_graph, self.step_graph = self.bundle.graph("init"), self.bundle.graph("step")
        thresholds = self.bundle.section("thresholds")
        self.low_snr = thresholds.get("low_snr")
        self.snr_graph = self.bundle.graph("snr") if self.low_snr is not None else None
        # (low SNR, large) -> (init, step); the other pairs are loaded when needed
        self._graph_pairs = {(False, False): (self.init_graph, self.step_graph)}
        self.low_snr_psr, self.low_snr_residual = thresholds.get("low_snr_psr"), thresholds.get("low_snr_residual")
        retry = self.low_snr is not None and self.low_snr_psr is not None
        self.noise_graph = self.bundle.graph("first_step_noise") if retry else None
        self.on_low_snr_graphs = False
        self.blur_match = thresholds.get("blur_match_px2")
        self.streak_score = thresholds.get("streak_score") if self.blur_match is not None else None
        self.streak_match = thresholds.get("streak_match_px2")
        self.streak_graph = self.bundle.graph("streak") if self.streak_score is not None else None
        self.profile_graph, self.relative_graph = self.bundle.graph("profile"), self.bundle.graph("relative_blur")
        self.turn_match = thresholds.get("turn_match")
        self.turn_graph = self.bundle.graph("turn") if self.turn_match is not None else None

    def _frame(self, frame: np.ndarray, index: int) -> np.ndarray:
        frame = np.asarray(frame, np.float32)
        if frame.ndim != 2 or not all(self.min_size <= n <= self.max_size for n in frame.shape):
            raise InputError(f"frame {index} is {frame.shape}: the bundle's tracker takes (H, W) gray frames of "
                             f"{self.min_size} to {self.max_size} px a side")
        return frame[None, None]

    def track(self, frames: Iterable[np.ndarray], points: np.ndarray,
              progress: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Track points (P, 2) given in the first frame through gray frames (H, W) of equal size (``progress``: a
        progress line on stderr, :func:`core.progress.progress`).

        Returns:
            tracks (T, P, 2) float32, lost (T, P) bool and PSR (T, P) float32 (inf in frame 0).
        """
        points = np.asarray(points, np.float32)
        if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
            raise InputError(f"points must be a non-empty (P, 2) array, got shape {points.shape}")
        single = len(points) == 1  # the graphs take at least 2 points; a copy leaves a lone point's result alone
        points = np.concatenate([points, points]) if single else points
        tracks, lost, psr, previous, state = [], [], [], None, None
        for t, frame in enumerate(progress_line(frames, f"track {self.method} (onnxruntime)", enabled=progress)):
            image = self._frame(frame, t)
            if previous is None:
                self.large = min(image.shape[2:]) >= self.large_min_side
                self._use_graphs(self._low_snr(image, points))
                state = self._start(image, points)
            else:
                if image.shape != previous.shape:
                    raise InputError(f"frame {t} has size {image.shape[2:]}, frame 0 has {previous.shape[2:]}")
                low_snr = self.on_low_snr_graphs  # the graphs of this state's filters
                new = self._retried_step(image, previous, state, first=t == 1)
                state = self._turn_matched(image, previous, state, new, low_snr, first=t == 1)
            previous = image
            tracks.append(state.positions)
            lost.append(state.flags)
            psr.append(state.scores)
        if previous is None:
            raise InputError("no frames to track")
        keep = slice(0, 1) if single else slice(None)
        return tuple(np.stack(a)[:, keep] for a in (tracks, lost, psr))  # type: ignore[return-value]

    def _use_graphs(self, low_snr: bool, noise_floor: np.ndarray | None = None) -> None:
        """Track on the tracker's pair of graphs or (``low_snr``) on the low-SNR twin's, whose step takes
        ``noise_floor`` (1,) (gray levels^2; None: 0, none)."""
        self.init_graph, step = self._graphs(low_snr)
        floor = np.zeros(1, np.float32) if noise_floor is None else noise_floor
        self.step_graph = _with_floor(step, floor) if low_snr else step
        self.on_low_snr_graphs = low_snr

    def _start(self, image: np.ndarray, points: np.ndarray) -> _Tracks:
        """The state after the first frame ``image`` (1, 1, H, W): the init graph's outputs at ``points``, the
        frame's radial power profile (with blur matching) and its streak."""
        positions, flags, scores, means, *filters = self.init_graph(image, points)
        reference = self.profile_graph(image) if self.blur_match is not None else None
        streak = self._streak(image)
        return _Tracks(positions, flags, scores, means, filters, reference, reference, streak,
                       (streak,) if streak else ())

    def _step(self, image: np.ndarray, previous: np.ndarray, state: _Tracks) -> _Tracks:
        """One frame ``image`` after ``previous`` (each (1, 1, H, W)) from ``state``: the step graph, with blur or
        streak matching where the bundle has them (``PointTracker.step``)."""
        args = (image, previous, state.positions, state.flags, state.means, state.filters)
        if self.blur_match is None:
            positions, flags, scores, means, *filters = self.step_graph(*args[:5], *state.filters)
            return _Tracks(positions, flags, scores, means, filters)
        if (streak := self._streak(image, state.streak)) is not None or state.template:
            outputs, template = self._streak_step(*args, state.streak, streak, state.template)
            reference = last = None  # the Gaussian matching restarts from this frame
        else:
            last = self.profile_graph(previous) if state.last is None else state.last
            profile = self.profile_graph(image)
            outputs, reference = self._matched_step(*args, last if state.reference is None else state.reference,
                                                    last, profile)
            last, template = profile, state.template
        positions, flags, scores, means, *filters = outputs
        return _Tracks(positions, flags, scores, means, filters, reference, last, streak, template)

    def _retried_step(self, image: np.ndarray, previous: np.ndarray, state: _Tracks, first: bool) -> _Tracks:
        """The step from ``state`` into ``image`` after ``previous``; in a ``first`` step whose PSRs are low and whose
        residuals read as noise that the frame's estimate under-read (:meth:`_retry_floor`), that step again on the
        low-SNR graphs, from ``previous`` at ``state``'s positions and with the noise it read as the frame's least
        noise, turn matched on them (``PointTracker._matched_step`` and ``_low_snr_retry``)."""
        new = self._step(image, previous, state)
        floor = self._retry_floor(image, state, new) if first else None
        if floor is None:
            return new
        self._use_graphs(True, floor)
        start = self._start(previous, state.positions)
        new = self._turn_matched(image, previous, start, self._step(image, previous, start), True, first=False)
        self._use_graphs(True)  # the floor holds for that step only
        return new

    def _turn_matched(self, image: np.ndarray, previous: np.ndarray, state: _Tracks, new: _Tracks, low_snr: bool,
                      first: bool) -> _Tracks:
        """``new``, the step from ``state`` (filters of the low-SNR graphs or not: ``low_snr``) into ``image`` after
        ``previous``, or, where the points tracked into and out of ``previous`` (at least 10) turn by more than the
        bundle's ``turn_match`` (the ``turn`` graph), the step again on ``state``'s graphs from ``previous`` warped by
        the similarity fitted to their steps, the points moved with it and their filters trained afresh there, in a
        ``first`` step retried as :meth:`_retried_step` does (``PointTracker._turn_matched_step``; ``new`` may come
        from the low-SNR graphs, whose step then gave the turn)."""
        if self.turn_graph is None:
            return new
        turn, similarity = self.turn_graph(state.positions, new.positions, ~(state.flags | new.flags))
        if not turn[0] > self.turn_match:
            return new
        if self.on_low_snr_graphs != low_snr:
            self._use_graphs(low_snr)
        height, width = previous.shape[2:]
        turned = cv2.warpAffine(previous[0, 0], similarity, (width, height), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REFLECT_101)[None, None]
        moved = (state.positions @ similarity[:, :2].T + similarity[:, 2]).astype(np.float32)
        flags, filters = self._retrained(turned, moved, state.flags, state.filters)
        return self._retried_step(image, turned, _Tracks(moved, flags, state.scores, state.means, filters), first)

    def _retry_floor(self, image: np.ndarray, state: _Tracks, new: _Tracks) -> np.ndarray | None:
        """The noise floor (1,) with which the first step into ``image`` is tracked again on the low-SNR graphs
        (``state``: the state the step was tracked from, ``new``: after this step), or None: where the step's
        geometric-mean PSR is below the bundle's ``low_snr_psr``, the ``first_step_noise`` graph's residual SNR
        below ``low_snr_residual`` and its residual noise above the frame's (``PointTracker._low_snr_retry``)."""
        if self.noise_graph is None or self.on_low_snr_graphs:
            return None
        if not _frame_psr(new.scores, new.flags) < self.low_snr_psr:
            return None
        snr, noise, estimate = self.noise_graph(image, state.filters[0], new.positions, new.flags)
        return noise[None] if snr < self.low_snr_residual and noise > estimate else None

    def _low_snr(self, image: np.ndarray, points: np.ndarray) -> bool:
        """Whether the median signal-to-noise ratio of the ``points`` (P >= 2) inside the (1, 1, H, W) first frame
        (the ``snr`` graph, ``PointTracker.signal_to_noise``: inf where none is inside) is below the bundle's
        ``low_snr`` (never where that is null)."""
        return self.low_snr is not None and float(self.snr_graph(image, points)[0]) < self.low_snr

    def _graphs(self, low_snr: bool) -> tuple:
        """The init and step graphs of the tracker (``low_snr`` False) or of its low-SNR twin, with every pyramid
        level where the sequence's frames are large enough for them (``large``), each loaded once."""
        key = (low_snr, self.large)
        if key not in self._graph_pairs:
            suffix = "_low_snr" * low_snr + "_large" * self.large
            self._graph_pairs[key] = (self.bundle.graph(f"init{suffix}"), self.bundle.graph(f"step{suffix}"))
        return self._graph_pairs[key]

    def _retrained(self, image: np.ndarray, positions: np.ndarray, flags: np.ndarray,
                   filters: list) -> tuple[np.ndarray, list]:
        """Lost flags and the tracked points' filters trained afresh on ``image`` at ``positions``; lost points stay
        lost and keep their ``filters`` (``PointTracker._retrained``)."""
        _, fresh_lost, _, _, *fresh = self.init_graph(image, positions)
        keep = flags[None, None, :, None]
        return flags | fresh_lost, [np.where(keep, old, new) for old, new in zip(filters, fresh, strict=True)]

    def _matched_step(self, image: np.ndarray, previous: np.ndarray, positions: np.ndarray, flags: np.ndarray,
                      means: np.ndarray, filters: list, reference: np.ndarray, last: np.ndarray, profile: np.ndarray):
        """One step with blur matching (``PointTracker._blur_matched_step``): the step graph's outputs and the
        reference profile after it (``means``: the points' running PSR means; ``reference``: the profile of the
        frame the filters were last trained afresh on, ``last``: of ``previous``, ``profile``: of ``image``)."""
        change = float(self.relative_graph(reference, profile)[0])
        if change > self.blur_match:  # blurrier: retrain on the previous frame blurred to this one
            matched = _blurred(previous, max(float(self.relative_graph(last, profile)[0]), 0.0))
            flags, filters = self._retrained(matched, positions, flags, filters)
            return self.step_graph(image, matched, positions, flags, means, *filters), profile
        if change < -self.blur_match:  # sharper: search a copy blurred to the filters' level, retrain on the frame
            positions, flags, scores, means, *filters = self.step_graph(_blurred(image, -change), previous, positions,
                                                                        flags, means, *filters)
            flags, filters = self._retrained(image, positions, flags, filters)
            return [positions, flags, scores, means, *filters], profile
        return self.step_graph(image, previous, positions, flags, means, *filters), reference

    def _streak(self, image: np.ndarray, previous: Streak | None = None) -> Streak | None:
        """The straight motion blur (length, angle) of a (1, 1, H, W) frame (``PointTracker._streak``); None where
        the ``streak`` graph's scores show none (``core.streak.streak_found`` with the bundle's ``streak_score``,
        continuing the ``previous`` frame's streak at half of it) and where streak matching is off (the bundle's
        smallest frame, 64 px, is large enough to measure)."""
        if self.streak_graph is None:
            return None
        length, angle, score, rival, *grid = (float(v) for v in self.streak_graph(image)[0])
        block_grid = grid[0] if grid else math.inf  # bundles before the block-grid column: assume a block grid
        found = streak_found(length, angle, score, rival, self.streak_score, block_grid, previous)
        return (length, angle) if found else None

    def _uniform(self, image: np.ndarray, streak: Streak | None, previous: np.ndarray | None = None) -> bool:
        """Whether ``streak``, found in the (1, 1, H, W) frame, reads the same in its four quarters and was not read
        already, with a score below the threshold, in the ``previous`` frame (the ``streak`` graph on each;
        ``PointTracker._uniform``)."""
        quarters = quarter_slices(*image.shape[2:])
        if streak is None or quarters is None:
            return False
        if previous is not None:
            length, angle, score = (float(v) for v in self.streak_graph(previous)[0][:3])
            if score < self.streak_score and streak_uniform(streak, [(length, angle)]):
                return False
        readings = [self.streak_graph(np.ascontiguousarray(image[..., rows, columns]))[0][:2] for rows, columns in
                    quarters]
        return streak_uniform(streak, [(float(length), float(angle)) for length, angle in readings])

    def _streak_step(self, image: np.ndarray, previous: np.ndarray, positions: np.ndarray, flags: np.ndarray,
                     means: np.ndarray, filters: list, streak: Streak | None, new_streak: Streak | None,
                     template: tuple[Streak, ...]):
        """One step with streak matching (``PointTracker._streak_matched_step``): the step graph's outputs and the
        streaks of the views the filters were last trained afresh on (``streak``: of ``previous``,
        ``new_streak``: of ``image``, ``template``: the filters' streaks before the step)."""
        change = streak_change([new_streak] if new_streak else [], template)
        first = None if template else previous  # a first streak: was it there already?
        if not streaks_matched(change, self.streak_match, self.blur_match,
                               lambda: self._uniform(image, new_streak, first)):
            return self.step_graph(image, previous, positions, flags, means, *filters), template
        matched = _streaked(previous, new_streak)
        flags, filters = self._retrained(matched, positions, flags, filters)
        outputs = self.step_graph(_streaked(image, streak), matched, positions, flags, means, *filters)
        return outputs, tuple(s for s in (streak, new_streak) if s is not None)


def _with_floor(step: Callable, noise_floor: np.ndarray) -> Callable:
    """The low-SNR step graph ``step`` called as the tracker's step graph: ``noise_floor`` (1,) goes in after the
    running PSR means."""
    return lambda image, previous, positions, flags, means, *filters: step(image, previous, positions, flags, means,
                                                                           noise_floor, *filters)


def _frame_psr(psr: np.ndarray, lost: np.ndarray) -> float:
    """Geometric mean of the finite PSRs (P,) of the points not ``lost`` (1 where there are none), as
    ``PointTracker._frame_psr``."""
    tracked = ~lost & np.isfinite(psr)
    return float(np.exp(np.log(np.maximum(psr[tracked], 1e-3)).mean())) if tracked.any() else 1.0


def _streaked(image: np.ndarray, streak: Streak | None) -> np.ndarray:
    """A (1, 1, H, W) frame blurred by a streak (``core.streak.streak_blur``; None: the frame)."""
    return image if streak is None else streak_blur(image[0, 0], *streak)[None, None]


def _blurred(image: np.ndarray, variance: float) -> np.ndarray:
    """A (1, 1, H, W) frame blurred by a Gaussian of ``variance`` px^2 with the kernel of
    ``models.tracking.blur.gaussian_blur`` (``2 round(4 sigma) + 1`` taps, reflected borders)."""
    if variance <= 0:
        return image
    sigma = float(np.sqrt(variance))
    size = min(int(round(sigma * 8 + 1)) | 1, 2 * min(image.shape[2:]) - 1)
    return cv2.GaussianBlur(image[0, 0], (size, size), sigma, borderType=cv2.BORDER_REFLECT_101)[None, None]


def track_files(bundle: str | Path, frames: str | Path, out: str | Path, points: str | Path | None = None,
                detect: int | None = None, threads: int | None = None, provider: str = "cpu",
                progress: bool = False) -> tuple[str, dict]:
    """Track the start ``points`` (a file) or ``detect`` good features through the frames ``frames`` (a folder or
    glob) with the bundle and write the tracks file ``out``; returns a one-line summary and the written arrays
    (the command ``runtime.tracking``, with a progress line on stderr where ``progress``)."""
    if (points is None) == (detect is None):
        raise InputError("give either start points (--points) or a number of points to detect (--detect)")
    tracker = OnnxPointTracker(bundle, threads, provider)
    images, paths = read_frames(frames)
    start = read_points(points) if points is not None else good_features(images[0], detect)
    writable_folder(Path(out).parent)
    begin = time.perf_counter()
    tracks, lost, psr = tracker.track(images, start, progress)
    seconds = time.perf_counter() - begin
    result = {"tracks": tracks.astype(np.float64), "lost": lost, "psr": psr.astype(np.float64), "points": start}
    write_npz(out, compress=False, method=np.array(tracker.method), frames=np.array([str(p) for p in paths]), **result)
    n_frames, n_points = lost.shape
    return (f"{tracker.method} (onnxruntime): {n_points} points through {n_frames} frames in {seconds:.1f} s "
            f"({n_points * max(n_frames - 1, 1) / seconds:.0f} point-frames/s), {int(lost[-1].sum())} lost at the "
            f"end; wrote {out}"), result


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="runtime.tracking", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_runtime_arguments(parser)
    parser.add_argument("--frames", required=True,
                        help="folder of frames (sorted by name), a glob like 'clip/*.png' or a video file "
                        "like clip.mp4 (decoded by OpenCV)")
    start = parser.add_mutually_exclusive_group(required=True)
    start.add_argument("--points", help="start points: .npy/.npz (P, 2) or text 'x y' lines")
    start.add_argument("--detect", type=int, help="detect this many good features to track in the first frame")
    parser.add_argument("--out", type=Path, required=True, help="output .npz (tracks, lost, psr, points)")
    args = parser.parse_args(argv)

    def run() -> None:
        print(track_files(args.bundle, args.frames, args.out, args.points, args.detect, args.threads, args.provider,
                          progress=True)[0])

    return run_command("runtime.tracking", run)


if __name__ == "__main__":
    raise SystemExit(main())

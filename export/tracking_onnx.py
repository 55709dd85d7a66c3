"""Export the DCF point tracker as a deployment bundle: its first-frame training and its per-frame step
(``runtime.tracking`` runs them).

    python -m export.tracking_onnx --out DIR [--method ccot] [--height 240 --width 320] [--workers N] [--check]

Graphs (frame height and width and the number of points P dynamic; the pyramid is built inside):

- ``init.onnx``: ``frame`` (1, 1, H, W) gray float32 in [0, 255], ``points`` (P, 2) (x, y) px -> ``positions`` (P,
  2), ``lost`` (P,) bool (outside the image), ``psr`` (P,) (inf), ``psr_mean`` (P,) (each point's running
  geometric-mean PSR, inf: none yet) and the filters of every pyramid level,
  ``filters_0`` .. ``filters_{L-1}`` (3, N_l, P, K_l) (real and imaginary parts of the numerators and the
  denominators, finest level first, point-interleaved): :meth:`PointTracker.init`.
- ``step.onnx``: ``frame``, ``previous`` (the frame before it, for the forward-backward test), ``positions``,
  ``lost``, ``psr_mean`` and the filters -> ``positions_out``, ``lost_out``, ``psr``, ``psr_mean_out`` and
  ``filters_l_out``: one :meth:`PointTracker.forward` (one GatherElements per level for the patches, matrix products
  for the small DFTs, a fixed number of Newton iterations).
- ``profile.onnx``: ``frame`` -> ``profile`` (1, 3, bins), its radial power profile, and ``relative_blur.onnx``:
  ``reference``, ``profile`` -> ``blur`` (1,) px^2 (:mod:`models.tracking.blur`): the blur matching of
  :meth:`PointTracker.step`, whose branches (retrain on a blurred previous frame, search a blurred copy) the
  runtime takes in numpy with ``cv2.GaussianBlur``; ``thresholds.blur_match_px2`` in the manifest (null: off).
- ``streak.onnx``: ``frame`` -> ``streak`` (1, 5): length (px), angle (rad), cepstral score and rival of the
  frame's straight motion blur (:mod:`models.tracking.motion_blur`) and its block-grid ratio
  (:mod:`models.tracking.compression`, for :func:`core.streak.streak_found`); with ``thresholds.streak_score``
  (null: off) and ``streak_match_px2`` the runtime matches streaks as :meth:`PointTracker._streak_matched_step`
  does, with ``core.streak.streak_blur``.
- ``snr.onnx``: ``frame``, ``points`` (P >= 2) -> ``snr`` (1,), the median signal-to-noise ratio of the points
  inside the frame, inf where none is (:meth:`PointTracker.signal_to_noise`); below ``thresholds.low_snr`` the
  runtime tracks the sequence with ``init_low_snr.onnx`` and ``step_low_snr.onnx``, the graphs of the tracker's
  low-SNR twin (Tukey windows, the level-0 patch size at every level; inputs and outputs as ``init`` and
  ``step``, and ``step_low_snr`` takes a ``noise_floor`` (1,) after ``psr_mean``: the least noise variance of the
  frame, 0 for none).
- ``first_step_noise.onnx``: ``frame``, ``template`` (the level-0 filters of the first frame), ``positions`` and
  ``lost`` after the first step -> ``noise`` (3,): the residual SNR and noise variance of that step
  (:meth:`PointTracker.first_step_noise`) and the frame's noise variance. Where the first step's geometric-mean
  PSR is below ``thresholds.low_snr_psr``, its residual SNR below ``thresholds.low_snr_residual`` and its residual
  noise above the frame's, the runtime tracks the sequence again from the first frame on the low-SNR graphs, that
  step with that noise as ``noise_floor`` (:meth:`PointTracker._low_snr_retry`).

- ``init_large.onnx``, ``step_large.onnx``, ``init_low_snr_large.onnx``, ``step_low_snr_large.onnx``: the same
  graphs with every pyramid level (:func:`bundle_tracker`; the others have the ``min_levels`` levels that search
  in every frame), for frames of at least ``input.large_min_side`` px a side (657 for the default fifth level), on
  which the deeper levels search; inside the graphs a gate computed from the frame's shape decides that, as
  :meth:`PointTracker._level_gate` does. ``input.levels`` and ``input.large_levels`` name the two depths.

- ``turn.onnx``: ``start``, ``moved`` (P, 2) and ``tracked`` (P,) bool -> ``turn`` (1,) and ``similarity`` (2, 3):
  the turn of the tracked points' steps (0 where fewer than ``TURN_POINTS``, 10, are tracked) and the similarity
  fitted to them (:mod:`models.tracking.turn`). Beyond
  ``thresholds.turn_match`` (null: off) the runtime tracks the step again from the previous frame warped by that
  similarity (``cv2.warpAffine``), as :meth:`PointTracker._turn_matched_step` does.

``--check`` tracks the synthetic sequence with the bundle and with PyTorch and prints the largest position
difference and the lost flags that differ.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from core.command import CommandParser, run_command
from core.errors import InputError
from core.streak import streak_blur
from export.bundle import staged_bundle
from export.onnx import OPSET, export_onnx
from export.pool import GraphJob, export_jobs
from models.tracking import PointTracker
from models.tracking.blur import RadialPowerProfile, gaussian_blur, relative_blur
from models.tracking.compression import BlockGridRatio
from models.tracking.motion_blur import MotionBlurStreak
from models.tracking.point_tracker import METHODS
from models.tracking.turn import TURN_POINTS, camera_turn, fit_similarity
from runtime.bundle import write_manifest
from runtime.tracking import OnnxPointTracker

#: Frame sizes and point counts the graphs accept (``torch.export`` dimension bounds).
MIN_SIZE, MAX_SIZE, MAX_POINTS = 64, 4096, 100_000


def io_names(levels: int, floor: bool = False) -> tuple[list[str], list[str]]:
    """Input and output names of the exported step for a ``levels``-level tracker (``floor``: with the
    ``noise_floor`` input of :class:`FlooredStep`)."""
    filters = [f"filters_{level}" for level in range(levels)]
    inputs = ["frame", "previous", "positions", "lost", "psr_mean", *(["noise_floor"] if floor else []), *filters]
    return inputs, ["positions_out", "lost_out", "psr", "psr_mean_out", *[f"{name}_out" for name in filters]]


class FlooredStep(nn.Module):
    """:meth:`PointTracker.forward` with its ``noise_floor`` (1,) as an input after ``psr_mean`` (0: none): the
    low-SNR twin's step, which a retried first step hands the noise it measured (:meth:`PointTracker.step`)."""

    def __init__(self, tracker: PointTracker) -> None:
        super().__init__()
        self.tracker = tracker

    def forward(self, frame: Tensor, previous: Tensor, positions: Tensor, lost: Tensor, psr_mean: Tensor,
                noise_floor: Tensor, *filters: Tensor) -> tuple[Tensor, ...]:
        return self.tracker(frame, previous, positions, lost, psr_mean, *filters, noise_floor=noise_floor)


class FirstStepNoiseGraph(nn.Module):
    """:meth:`PointTracker.first_step_noise` and the frame's noise estimate: frame (1, 1, H, W), the level-0
    filters of the first frame (3, N, P, K), positions (P, 2) and lost (P,) after the first step -> (3,): residual
    SNR, residual noise variance and the frame's noise variance (gray levels^2)."""

    def __init__(self, tracker: PointTracker) -> None:
        super().__init__()
        self.tracker = tracker

    def forward(self, frame: Tensor, template: Tensor, positions: Tensor, lost: Tensor) -> Tensor:
        return torch.cat(self.tracker.first_step_noise(frame, template, positions, lost))


class InitGraph(nn.Module):
    """:meth:`PointTracker.init` with tensors out: frame (1, 1, H, W), points (P, 2) -> positions, lost, psr,
    psr_mean, filters of every level."""

    def __init__(self, tracker: PointTracker) -> None:
        super().__init__()
        self.tracker = tracker

    def forward(self, frame: Tensor, points: Tensor) -> tuple[Tensor, ...]:
        state = self.tracker.init(frame, points, switch=False)
        return state.positions, state.lost, state.psr, state.psr_mean, *state.filters


class SnrGraph(nn.Module):
    """:meth:`PointTracker.signal_to_noise`: frame (1, 1, H, W), points (P, 2) -> (1,)."""

    def __init__(self, tracker: PointTracker) -> None:
        super().__init__()
        self.tracker = tracker

    def forward(self, frame: Tensor, points: Tensor) -> Tensor:
        return self.tracker.signal_to_noise(frame, points)


class StreakGraph(nn.Module):
    """The streak reading of a frame (:func:`~models.tracking.motion_blur.motion_blur_streak`) and its block-grid
    ratio (:func:`~models.tracking.compression.block_grid_ratio`): frame (1, 1, H, W) -> (1, 5)."""

    def __init__(self) -> None:
        super().__init__()
        self.streak, self.block_grid = MotionBlurStreak(), BlockGridRatio()

    def forward(self, frame: Tensor) -> Tensor:
        return torch.cat([self.streak(frame), self.block_grid(frame)[:, None]], 1)


class RelativeBlurGraph(nn.Module):
    """:func:`~models.tracking.blur.relative_blur`: reference, profile (1, 3, bins) -> blur (1,) px^2."""

    def forward(self, reference: Tensor, profile: Tensor) -> Tensor:
        return relative_blur(reference, profile)


class TurnGraph(nn.Module):
    """:func:`~models.tracking.turn.camera_turn` and :func:`~models.tracking.turn.fit_similarity` of the tracked
    points' steps: start, moved (P, 2), tracked (P,) bool -> turn (1,; 0 with fewer than ``TURN_POINTS`` tracked, as
    :class:`PointTracker` reads it), similarity (2, 3)."""

    def forward(self, start: Tensor, moved: Tensor, tracked: Tensor) -> tuple[Tensor, Tensor]:
        weight = tracked.to(start.dtype)
        return camera_turn(start, moved, weight, TURN_POINTS).reshape(1), fit_similarity(start, moved, weight)


def export_turn_graph(path: str | Path) -> None:
    """Export ``turn.onnx`` (P dynamic) to ``path``."""
    gen = torch.Generator().manual_seed(0)
    start = torch.rand(20, 2, generator=gen) * 100
    moved = start @ torch.tensor([[0.99, 0.1], [-0.1, 0.99]]) + 3
    tracked = torch.rand(20, generator=gen) > 0.2
    p = torch.export.Dim("points", min=2, max=MAX_POINTS)
    with torch.no_grad():
        export_onnx(TurnGraph(), (start, moved, tracked), path, ["start", "moved", "tracked"], ["turn", "similarity"],
                    dynamic_shapes=({0: p}, {0: p}, {0: p}))


def example_inputs(tracker: PointTracker, height: int, width: int, points: int, seed: int = 0):
    """Real inputs for one step: a textured frame, its filters at random points, and a shifted next frame (the
    points' PSR history seeded, so that both branches of the lost test are exercised)."""
    gen = torch.Generator().manual_seed(seed)
    base = torch.rand(1, 1, height // 8 + 2, width // 8 + 2, generator=gen) * 255
    frame = torch.nn.functional.interpolate(base, size=(height, width), mode="bicubic", align_corners=False)
    frame = frame + 10 * torch.rand(1, 1, height, width, generator=gen)
    pts = torch.rand(points, 2, generator=gen) * torch.tensor([width - 1.0, height - 1.0])
    state = tracker.init(frame[0, 0], pts, switch=False)
    nxt = torch.roll(frame, (2, -3), (2, 3))
    psr_mean = 1 + 30 * torch.rand(points, generator=gen)
    return nxt, frame, state.positions, state.lost, psr_mean, *state.filters


def export_tracking_step(path: str | Path, tracker: PointTracker, height: int = 240, width: int = 320,
                         points: int = 64, floor: bool = False) -> Path:
    """Export :meth:`PointTracker.forward` of ``tracker`` with dynamic H, W and P (``floor``: as
    :class:`FlooredStep`, with a ``noise_floor`` input); returns the path."""
    args = example_inputs(tracker, height, width, points)
    p = torch.export.Dim("points", min=2, max=MAX_POINTS)
    h, w = torch.export.Dim("height", min=MIN_SIZE, max=MAX_SIZE), torch.export.Dim("width", min=MIN_SIZE, max=MAX_SIZE)
    inputs, outputs = io_names(tracker.levels, floor)
    dynamic = {"frame": {2: h, 3: w}, "previous": {2: h, 3: w}, "positions": {0: p}, "lost": {0: p}, "psr_mean": {0: p}}
    if floor:
        args = (*args[:5], torch.full((1,), 4.0), *args[5:])
        dynamic["noise_floor"] = None
    dynamic["filters"] = tuple({2: p} for _ in range(tracker.levels))  # forward's *filters
    module = FlooredStep(tracker) if floor else tracker
    with torch.no_grad():
        return export_onnx(module, args, path, inputs, outputs, dynamic_shapes=dynamic)


def export_tracking_init(path: str | Path, tracker: PointTracker, height: int = 240, width: int = 320,
                         points: int = 64) -> Path:
    """Export :meth:`PointTracker.init` of ``tracker`` (``InitGraph``) with dynamic H, W and P."""
    frame, _, positions, *_ = example_inputs(tracker, height, width, points)
    p = torch.export.Dim("points", min=2, max=MAX_POINTS)
    h, w = torch.export.Dim("height", min=MIN_SIZE, max=MAX_SIZE), torch.export.Dim("width", min=MIN_SIZE, max=MAX_SIZE)
    outputs = ["positions", "lost", "psr", "psr_mean", *[f"filters_{level}" for level in range(tracker.levels)]]
    with torch.no_grad():
        return export_onnx(InitGraph(tracker), (frame, positions), path, ["frame", "points"], outputs,
                           dynamic_shapes=({2: h, 3: w}, {0: p}))


def export_snr_graph(path: str | Path, tracker: PointTracker, height: int = 240, width: int = 320,
                     points: int = 64) -> Path:
    """Export :meth:`PointTracker.signal_to_noise` of ``tracker`` (``SnrGraph``) with dynamic H, W and P."""
    frame, _, positions, *_ = example_inputs(tracker, height, width, points)
    p = torch.export.Dim("points", min=2, max=MAX_POINTS)
    h, w = torch.export.Dim("height", min=MIN_SIZE, max=MAX_SIZE), torch.export.Dim("width", min=MIN_SIZE, max=MAX_SIZE)
    with torch.no_grad():
        return export_onnx(SnrGraph(tracker), (frame, positions), path, ["frame", "points"], ["snr"],
                           dynamic_shapes=({2: h, 3: w}, {0: p}))


def export_first_step_noise_graph(path: str | Path, tracker: PointTracker, height: int = 240, width: int = 320,
                                  points: int = 64) -> Path:
    """Export :class:`FirstStepNoiseGraph` of ``tracker`` with dynamic H, W and P."""
    frame, _, positions, lost, _, template, *_ = example_inputs(tracker, height, width, points)
    p = torch.export.Dim("points", min=2, max=MAX_POINTS)
    h, w = torch.export.Dim("height", min=MIN_SIZE, max=MAX_SIZE), torch.export.Dim("width", min=MIN_SIZE, max=MAX_SIZE)
    with torch.no_grad():
        return export_onnx(FirstStepNoiseGraph(tracker), (frame, template, positions + 0.5, lost), path,
                           ["frame", "template", "positions", "lost"], ["noise"],
                           dynamic_shapes=({2: h, 3: w}, {2: p}, {0: p}, {0: p}))


def export_blur_graphs(folder: Path, tracker: PointTracker, height: int = 240, width: int = 320) -> None:
    """Export ``profile.onnx``, ``streak.onnx`` (both dynamic H, W) and ``relative_blur.onnx`` into ``folder``
    (example frames of ``tracker``'s :func:`example_inputs`)."""
    frame = example_inputs(tracker, height, width, 2)[0]
    h, w = torch.export.Dim("height", min=MIN_SIZE, max=MAX_SIZE), torch.export.Dim("width", min=MIN_SIZE, max=MAX_SIZE)
    profiler = RadialPowerProfile()
    with torch.no_grad():
        export_onnx(profiler, (frame,), folder / "profile.onnx", ["frame"], ["profile"], dynamic_shapes=({2: h, 3: w},))
        # two distinct example tensors: the exporter would merge one tensor passed twice into one input
        reference, profile = profiler(frame), profiler(gaussian_blur(frame, 2.0))
        export_onnx(RelativeBlurGraph(), (reference, profile), folder / "relative_blur.onnx", ["reference", "profile"],
                    ["blur"])
        streaked = torch.from_numpy(streak_blur(frame[0, 0].numpy(), 9.0, 0.5))[None, None]
        export_onnx(StreakGraph(), (streaked,), folder / "streak.onnx", ["frame"], ["streak"],
                    dynamic_shapes=({2: h, 3: w},))


#: The bundle's graph exports, heaviest first (about 60 s for each step, 18, 9 for each init, 9 and 4 s at 96 x 128
#: in one process), so that a pool of workers ends together: name -> (exporter, on the low-SNR twin, with every
#: pyramid level: the ``*_large`` graphs for frames large enough for the levels beyond ``min_levels``).
GRAPH_JOBS = {
    "step_low_snr_large.onnx": ("step", True, True),
    "step_large.onnx": ("step", False, True),
    "step_low_snr.onnx": ("step", True, False),
    "step.onnx": ("step", False, False),
    "profile.onnx, relative_blur.onnx, streak.onnx": ("blur", False, False),
    "init_large.onnx": ("init", False, True),
    "init_low_snr_large.onnx": ("init", True, True),
    "init.onnx": ("init", False, False),
    "init_low_snr.onnx": ("init", True, False),
    "snr.onnx": ("snr", False, False),
    "first_step_noise.onnx": ("noise", False, False),
    "turn.onnx": ("turn", False, False),
}


def bundle_tracker(method: str, large: bool = False) -> PointTracker:
    """The tracker whose graphs the bundle holds: ``PointTracker(method)`` with only its ``min_levels`` levels, those
    every frame searches, or (``large``) with all of them. On a frame smaller than its ``full_depth_side`` the two
    track alike (the deeper levels do not search there), and the smaller graphs spare the runtime the deeper
    levels' work, which an exported graph, gated by the frame's shape, would do in every frame."""
    tracker = PointTracker(method)
    if not large:
        tracker = PointTracker(method, levels=min(tracker.levels, tracker.min_levels))
    return tracker.eval()


def export_graph(name: str, folder: Path, method: str, height: int, width: int) -> None:
    """Export the bundle graph ``name`` (a key of :data:`GRAPH_JOBS`) of :func:`bundle_tracker` into ``folder``.
    A module-level function, so that a pool's worker process can run it."""
    kind, twin, large = GRAPH_JOBS[name]
    tracker = bundle_tracker(method, large)
    tracker = tracker.low_snr_tracker if twin else tracker
    if kind == "step":
        export_tracking_step(folder / name, tracker, height, width, floor=twin)
    elif kind == "init":
        export_tracking_init(folder / name, tracker, height, width)
    elif kind == "blur":
        export_blur_graphs(folder, tracker, height, width)
    elif kind == "noise":
        export_first_step_noise_graph(folder / name, tracker, height, width)
    elif kind == "turn":
        export_turn_graph(folder / name)
    else:
        export_snr_graph(folder / name, tracker, height, width)


def export_graphs(folder: Path, method: str, height: int, width: int, workers: int | None = None) -> None:
    """Export every graph of :data:`GRAPH_JOBS` into ``folder``, by ``workers`` processes at once
    (:func:`export.pool.export_jobs`: default one per core; 1: in this process). On two cores the graphs export
    in 0.55-0.6 of the time."""
    jobs = [GraphJob(name, export_graph, (name, folder, method, height, width)) for name in GRAPH_JOBS]
    export_jobs("export.tracking_onnx", jobs, workers)


def export_bundle(out: str | Path, method: str = "ccot", height: int = 240, width: int = 320,
                  workers: int | None = None) -> Path:
    """Write the tracking bundle of ``PointTracker(method)`` (``init.onnx``, ``step.onnx``, ``profile.onnx``,
    ``relative_blur.onnx``, ``streak.onnx``, ``snr.onnx``, ``init_low_snr.onnx``, ``step_low_snr.onnx``,
    ``first_step_noise.onnx``, ``turn.onnx``, the four ``*_large.onnx``, ``bundle.json``), its graphs exported by
    ``workers`` processes (:func:`export_graphs`)."""
    if method not in METHODS:
        raise InputError(f"unknown tracking method {method!r}; choose one of {', '.join(METHODS)}")
    if not (MIN_SIZE <= height <= MAX_SIZE and MIN_SIZE <= width <= MAX_SIZE):
        raise InputError(f"--height and --width must lie in [{MIN_SIZE}, {MAX_SIZE}], got {height} x {width}")
    tracker, large = bundle_tracker(method), bundle_tracker(method, large=True)
    with staged_bundle(out) as folder:
        export_graphs(folder, method, height, width, workers)
        write_manifest(
            folder, "tracking", OPSET,
            input={"frame": "(1, 1, H, W) gray float32 in [0, 255]", "min_size": MIN_SIZE, "max_size": MAX_SIZE,
                   "max_points": MAX_POINTS, "levels": tracker.levels, "large_levels": large.levels,
                   "large_min_side": large.full_depth_side},
            normalisation={"gray": "cv2.IMREAD_GRAYSCALE", "scale": 1.0},
            thresholds={"psr_threshold": tracker.psr_threshold, "floor_relative": tracker.floor_relative,
                        "psr_relative": tracker.psr_relative,
                        "psr_rate": tracker.psr_rate, "psr_recover": tracker.psr_recover,
                        "fb_threshold_px": tracker.fb_threshold, "eta": tracker.eta,
                        "noise_reg": tracker.noise_reg, "blur_match_px2": tracker.blur_match,
                        "streak_score": tracker.streak_score, "streak_match_px2": tracker.streak_match,
                        "block_limit": tracker.block_limit, "block_psr_threshold": tracker.block_psr_threshold,
                        "compression_reg": tracker.compression_reg, "low_snr": tracker.low_snr,
                        "low_snr_psr": tracker.low_snr_psr, "low_snr_residual": tracker.low_snr_residual,
                        "turn_match": tracker.turn_match},
            settings={"method": method, "patch_sizes": list(tracker.sizes), "bands": list(tracker.bands),
                      "search_sigmas": list(tracker.search_sigmas), "window": tracker.window,
                      "low_snr_patch_sizes": list(tracker.low_snr_tracker.sizes),
                      "low_snr_bands": list(tracker.low_snr_tracker.bands),
                      "low_snr_window": tracker.low_snr_tracker.window,
                      "low_snr_first_step_sigmas": list(tracker.low_snr_tracker.first_step_sigmas),
                      "good_features": {"quality": 0.01, "min_distance": 5}})
    return Path(out)


def parity(out: str | Path, frames: int = 8, points: int = 300) -> tuple[float, int]:
    """(largest |onnxruntime - PyTorch| position over tracked points in px, number of lost flags that differ) of
    the bundle on the synthetic sequence."""
    from data.flow import synthetic_sequence

    runtime = OnnxPointTracker(out)
    seq = synthetic_sequence(frames=frames, seed=3)
    images = list(seq.frames.astype(np.float32))
    start = np.random.default_rng(0).uniform(8, [images[0].shape[1] - 8, images[0].shape[0] - 8], (points, 2))
    tracks, lost, _ = runtime.track(images, start)
    ref_tracks, ref_lost, _ = PointTracker(runtime.method).track([torch.from_numpy(f) for f in images],
                                                                 torch.from_numpy(start).float())
    both = ~lost & ~ref_lost.numpy()
    return float(np.abs(tracks - ref_tracks.numpy())[both].max()), int((lost != ref_lost.numpy()).sum())


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.tracking_onnx", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="bundle folder to write")
    parser.add_argument("--method", default="ccot", choices=METHODS)
    parser.add_argument("--height", type=int, default=240, help="example frame height (the graphs are dynamic)")
    parser.add_argument("--width", type=int, default=320, help="example frame width (the graphs are dynamic)")
    parser.add_argument("--workers", type=int, default=None,
                        help="graphs exported at once, one process each (default: one per core)")
    parser.add_argument("--check", action="store_true", help="compare onnxruntime with PyTorch on synthetic frames")
    args = parser.parse_args(argv)

    def run() -> None:
        print(f"wrote {export_bundle(args.out, args.method, args.height, args.width, args.workers)}")
        if args.check:
            error, flags = parity(args.out)
            print(f"onnxruntime vs PyTorch on the synthetic sequence: max position difference {error:.2e} px, "
                  f"{flags} lost flags differ")

    return run_command("export.tracking_onnx", run)


if __name__ == "__main__":
    raise SystemExit(main())

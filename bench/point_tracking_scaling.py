"""Speed of the point trackers against the number of points: the default ``ccot`` (eager) and OpenCV's KLT, side by
side in one run on one sequence, at several point counts.

Per method and count the CPU time per frame (a whole run, the first frame's training included, over its ``T - 1``
steps, as :mod:`bench.point_tracking` counts it; best of ``--repeats`` runs, the methods taking turns; the warm-up
run on the first two frames is not counted) and the point-frames per second, with KLT in the run their ratio
``speed_vs_klt``. Per method a least-squares line through the times, ``ms per frame = per_frame_ms + per_point_us
points / 1000``, splits each step into what every frame costs whatever the point count (image pyramids and, for
``ccot``, the frame's noise, compression, blur and streak analyses) and what each point adds. Two numbers follow
from the lines: ``asymptotic_speed_vs_klt``, the speed ratio that more and more points tend to (KLT's per-point
cost over the method's), and ``fixed_share``, the fraction of the method's time per frame that the per-frame part
takes at each count. The start points are the strongest ``N`` corners of the first frame (one detection at the
largest count, spacing 1 px and quality 0.0003 by default, so that a Sintel frame yields 10000), so every count
tracks a subset of the next. A detection stops at about 13000 corners on a Sintel frame; ``--grid STEP`` starts from
a regular grid instead (every ``STEP`` px, taken in a seeded random order so that every count covers the whole
frame), for counts such as 1e5. ``--device cuda`` runs the DCF trackers on a GPU; every method is then timed by
the wall clock after a synchronisation (KLT and the ONNX runtime stay on the CPU).

    python -m bench.point_tracking_scaling --frames-dir ../shared/data/sintel/alley_1/clean \\
        --points 20 200 1000 2000 5000 10000 --json --plot speed_vs_points.png
    python -m bench.point_tracking_scaling --synthetic --points 100 2000 6000
    python -m bench.point_tracking_scaling --synthetic --grid 1 --points 1000 10000 100000 --device cuda
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from bench.point_tracking import METHODS, ORT, Detector, clock_name, run_method
from core.allocator import retain_freed_memory
from core.checks import check_device
from core.errors import InputError
from core.files import atomic_path
from core.frames import read_frames
from core.settings import parse_tracker
from core.threads import cpu_threads
from data.flow import synthetic_sequence

# start points: dense enough that a 1024 x 436 Sintel frame yields 10000
DETECTOR = Detector(spacing=1, quality=0.0003)


def fit_line(points: np.ndarray, ms_per_frame: np.ndarray) -> dict:
    """Least-squares line through ``(points, ms_per_frame)`` ``(K,)`` (at least two distinct counts):
    ``per_frame_ms`` (the intercept), ``per_point_us`` (the slope in µs) and ``r2``, the fraction of the times'
    variance the line explains (1 for times on a line)."""
    points, ms = np.asarray(points, dtype=np.float64), np.asarray(ms_per_frame, dtype=np.float64)
    if points.shape != ms.shape or points.ndim != 1 or len(np.unique(points)) < 2:
        raise InputError(f"a line needs times at two or more distinct point counts, got counts {points.tolist()}")
    slope, intercept = np.polyfit(points, ms, 1)
    residual = ms - (intercept + slope * points)
    spread = np.square(ms - ms.mean()).sum()
    r2 = 1.0 - np.square(residual).sum() / spread if spread > 0 else 1.0
    return {"per_frame_ms": float(intercept), "per_point_us": float(slope * 1e3), "r2": float(r2)}


def grid_points(shape: tuple[int, int], step: int, seed: int = 0) -> np.ndarray:
    """Start points ``(N, 2)`` (x, y) float64 on a regular grid every ``step`` px of a frame of ``shape`` (H, W), the
    first at ``step // 2`` px from the top left, in an order drawn from ``seed``: the first ``n`` of them spread over
    the whole frame for any ``n``."""
    if step < 1:
        raise InputError(f"the grid step (--grid) must be at least 1 px, got {step}")
    ys, xs = np.mgrid[step // 2 : shape[0] : step, step // 2 : shape[1] : step]
    points = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    return points[np.random.default_rng(seed).permutation(len(points))]


def time_counts(frames: np.ndarray, points: np.ndarray, counts: list[int], methods: list[str], repeats: int,
                settings: dict | None = None, bundle: str | None = None, device: str = "cpu") -> list[dict]:
    """Per point count ``N`` of ``counts``, each method's best time over ``repeats`` runs tracking the first ``N`` of
    ``points`` ``(P, 2)`` through uint8 ``frames`` ``(T, H, W)`` (the DCF trackers on ``device``; process CPU time
    on the CPU, the wall clock otherwise, :func:`bench.point_tracking.clock`): ``ms_per_frame``,
    ``point_frames_per_s``, ``first_call_s`` (the warm-up on the first two frames, wall clock as in
    :func:`bench.point_tracking.evaluate`) and, with ``klt`` among the methods, ``speed_vs_klt``."""
    steps = len(frames) - 1
    rows = []
    for n in counts:
        subset = points[:n]
        first_call = {m: _seconds(m, frames[:2], subset, settings, bundle, device, wall=True) for m in methods}
        seconds = {m: [] for m in methods}
        for _ in range(repeats):
            for method in methods:
                seconds[method].append(_seconds(method, frames, subset, settings, bundle, device))
        result = {}
        for method in methods:
            best = min(seconds[method])
            result[method] = {"ms_per_frame": 1e3 * best / steps, "point_frames_per_s": n * steps / best,
                              "first_call_s": first_call[method]}
        if "klt" in result:
            for m in result.values():
                m["speed_vs_klt"] = m["point_frames_per_s"] / result["klt"]["point_frames_per_s"]
        rows.append({"points": n, "methods": result})
    return rows


def _seconds(method: str, frames: np.ndarray, points: np.ndarray, settings: dict | None, bundle: str | None,
             device: str = "cpu", wall: bool = False) -> float:
    """One run's seconds by ``device``'s clock (:func:`bench.point_tracking.run_method`), or its wall seconds from
    the call on."""
    start = time.perf_counter()
    elapsed = run_method(method, frames, points, device, bundle, settings)[-1]
    return time.perf_counter() - start if wall else elapsed


def scaling(rows: list[dict], methods: list[str]) -> dict:
    """Per method the line through its times (:func:`fit_line`), its ``fixed_share`` per count (the intercept over
    the time; slightly negative where noise puts the intercept below 0) and, with KLT among the methods,
    ``asymptotic_speed_vs_klt``."""
    counts = np.array([row["points"] for row in rows])
    out = {}
    for method in methods:
        ms = np.array([row["methods"][method]["ms_per_frame"] for row in rows])
        line = fit_line(counts, ms)
        line["fixed_share"] = {str(n): float(line["per_frame_ms"] / t) for n, t in zip(counts, ms, strict=True)}
        out[method] = line
    if "klt" in out:
        for line in out.values():
            line["asymptotic_speed_vs_klt"] = out["klt"]["per_point_us"] / line["per_point_us"]
    return out


def plot(rows: list[dict], fits: dict, path: str | Path, clock: str = "process_cpu_time") -> None:
    """Two panels: ms per frame (by the ``clock`` named, :func:`bench.point_tracking.clock_name`) against the point
    count (log-log, the fitted lines dashed) and, with KLT in the run, each method's speed relative to KLT's (1: as
    fast; dotted: the ratio more points tend to)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    counts = np.array([row["points"] for row in rows])
    dense = np.geomspace(counts.min(), counts.max(), 50)
    fig, (times, ratio) = plt.subplots(1, 2, figsize=(10.5, 3.8))
    for method, line in fits.items():
        ms = [row["methods"][method]["ms_per_frame"] for row in rows]
        (marks,) = times.plot(counts, ms, "o", label=f"{method}: {line['per_frame_ms']:.1f} ms + "
                              f"{line['per_point_us']:.1f} µs/point")
        times.plot(dense, line["per_frame_ms"] + line["per_point_us"] * dense / 1e3, "--", color=marks.get_color())
        if method != "klt" and "klt" in fits:
            ratio.plot(counts, [row["methods"][method]["speed_vs_klt"] for row in rows], "o-",
                       color=marks.get_color(), label=f"{method} (limit {line['asymptotic_speed_vs_klt']:.2f}x)")
            ratio.axhline(line["asymptotic_speed_vs_klt"], color=marks.get_color(), ls=":", lw=1)
    times.set(xscale="log", yscale="log", xlabel="points", ylabel=f"ms per frame ({clock})", title="time per frame")
    ratio.axhline(1.0, color="gray", lw=0.8)
    ratio.set(xscale="log", xlabel="points", ylabel="point-frames/s over KLT's", title="speed relative to KLT",
              ylim=(0, None))
    times.legend(fontsize=8)
    if ratio.get_legend_handles_labels()[0]:  # a method beside KLT
        ratio.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=Path(path).suffix.lstrip(".") or "png")
    plt.close(fig)


def load_frames(frames_dir: str | None, length: int, seed: int = 0) -> tuple[str, np.ndarray]:
    """The sequence's name and uint8 frames ``(T, H, W)``: the first ``length`` frames of ``frames_dir`` or, without
    one, the synthetic sequence of ``length`` frames (``seed``)."""
    if frames_dir:
        frames, _ = read_frames(frames_dir, length)
        name = str(frames_dir)
    else:
        frames = synthetic_sequence(frames=length, seed=seed).frames
        name = f"synthetic (seed {seed})"
    if len(frames) < 2:
        raise InputError(f"{name}: timing needs at least two frames, got {len(frames)}")
    return name, np.round(np.stack(frames)).clip(0, 255).astype(np.uint8)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Small run (about 10 s on 2 cores): ``ccot`` and KLT on 6 frames (4 quick) of the synthetic sequence at 20 to
    3000 points (1000 quick), one thread. With ``report_dir``, writes the plot there; returns the figures."""
    frames = load_frames(None, 4 if quick else 6, seed=1)[1]
    counts = [20, 200, 1000] if quick else [20, 200, 1000, 3000]
    retain_freed_memory()  # as infer.py track
    with cpu_threads(1):
        points = DETECTOR(frames[0], counts[-1])
        rows = time_counts(frames, points, counts, ["ccot", "klt"], repeats=1)
    fits = scaling(rows, ["ccot", "klt"])
    print(table(rows, fits))
    if report_dir is None:
        return []
    plot(rows, fits, report_dir / "point_tracking_speed.png")
    return [("point_tracking_speed.png", "CPU time per frame of ccot and KLT against the number of points (one "
             "thread, the synthetic sequence), with a line through each: a per-frame part plus a per-point part")]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--frames-dir", metavar="DIR", help="a folder (or glob) of frames of one size")
    source.add_argument("--synthetic", action="store_true", help="the synthetic sequence (the default)")
    parser.add_argument("--length", type=int, default=8, help="frames to track (the first of --frames-dir)")
    parser.add_argument("--seed", type=int, default=0, help="synthetic sequence seed")
    parser.add_argument("--points", nargs="+", type=int, default=[20, 200, 1000, 2000, 5000, 10000],
                        help="point counts (each the strongest of one detection)")
    parser.add_argument("--spacing", type=int, default=DETECTOR.spacing,
                        help="least distance between detected points in px")
    parser.add_argument("--quality", type=float, default=DETECTOR.quality,
                        help="least corner response of a detected point, relative to the strongest")
    parser.add_argument("--grid", type=int, metavar="STEP",
                        help="start from a grid every STEP px (seeded order) instead of detected corners")
    parser.add_argument("--device", default="cpu", help="torch device of the DCF trackers (cuda: wall clock)")
    parser.add_argument("--methods", nargs="+", default=["ccot", "klt"], choices=(*METHODS, ORT))
    parser.add_argument("--bundle", metavar="DIR", help=f"ccot tracking bundle for {ORT}")
    parser.add_argument("--tracker", nargs="+", metavar="KEY=JSON", help="settings of the DCF trackers")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for torch and OpenCV alike")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per method and count; the best counts")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--plot", help="write time per frame and speed relative to KLT against points to this PNG")
    return parser


def table(rows: list[dict], fits: dict) -> str:
    """The run as text: ms per frame (and speed relative to KLT) per count, then each method's line."""
    methods = list(fits)
    lines = ["points  " + "  ".join(f"{m + ' ms/frame':>18s}" for m in methods)]
    for row in rows:
        cells = []
        for m in methods:
            r = row["methods"][m]
            ratio = f" ({r['speed_vs_klt']:.2f}x)" if "speed_vs_klt" in r and m != "klt" else ""
            cells.append(f"{r['ms_per_frame']:>9.2f}{ratio:>9s}")
        lines.append(f"{row['points']:>6d}  " + "  ".join(cells))
    for m, line in fits.items():
        limit = f", limit {line['asymptotic_speed_vs_klt']:.2f}x KLT" if "asymptotic_speed_vs_klt" in line else ""
        lines.append(f"{m}: {line['per_frame_ms']:.2f} ms per frame + {line['per_point_us']:.2f} µs per point "
                     f"(r2 {line['r2']:.3f}){limit}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    counts = sorted(set(args.points))
    if args.repeats < 1 or args.length < 2 or args.threads < 1 or counts[0] < 1 or len(counts) < 2:
        parser.error("--repeats and --threads must be at least 1, --length at least 2, and --points two or more "
                     "distinct positive counts")
    retained = retain_freed_memory()
    try:
        settings = parse_tracker(args.tracker)
        check_device(args.device, "--device")
        with cpu_threads(args.threads):
            name, frames = load_frames(args.frames_dir, args.length, args.seed)
            if args.grid is None:
                points = Detector(args.spacing, args.quality)(frames[0], counts[-1])
            else:
                points = grid_points(frames.shape[1:], args.grid, args.seed)[: counts[-1]]
            counts = [n for n in counts if n < len(points)] + [len(points)]
            if len(counts) < 2:
                raise InputError(f"{name}: only {len(points)} start points, fewer than two of the counts asked")
            rows = time_counts(frames, points, counts, args.methods, args.repeats, settings, args.bundle, args.device)
        fits = scaling(rows, args.methods)
        if args.plot:
            plot(rows, fits, args.plot, clock_name(args.device))
    except InputError as err:
        sys.stderr.write(f"bench/point_tracking_scaling.py: error: {err}\n")
        return 2
    if args.json:
        print(json.dumps({"sequence": name, "frames": len(frames), "size": list(frames.shape[1:]),
                          "counts": rows, "fits": fits, "threads": args.threads, "clock": clock_name(args.device),
                          "device": args.device, "timing": f"best of {args.repeats} runs", "tracker": settings,
                          "start_points": {"grid": args.grid, "seed": args.seed} if args.grid else
                          {"detector": {"spacing": args.spacing, "quality": args.quality}},
                          "retained_freed_memory": retained}))
    else:
        print(table(rows, fits))
    return 0


if __name__ == "__main__":
    sys.exit(main())

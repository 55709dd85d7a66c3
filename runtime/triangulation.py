"""Optimal N-view triangulation from the exported dogleg graphs (thesis ch. 2), torch-free.

    python -m runtime.triangulation --bundle DIR (--bundler FILE.out | --bal FILE) [--views K] [--out points.ply]
                                    [--json] [--threads N] [--provider cpu|cuda|tensorrt|coreml]

Reads a reconstruction (``runtime.sfm``), triangulates every track with at least K views from its first K views
with the bundle's ``dogleg`` graph and compares the points with the file's (bundle-adjusted) points: the report of
``infer.py triangulate`` (``count``, ``valid``, ``err3d_median_rel`` / ``err3d_mean_rel`` = 3D distance over the
scene radius, ``reproj_rms`` px, ``points_per_s``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from core.command import CommandParser, print_report, run_command
from core.errors import InputError
from core.files import atomic_path
from runtime.bundle import Bundle, add_runtime_arguments
from runtime.sfm import Reconstruction, read_reconstruction


class Triangulation(NamedTuple):
    """points (B, 3), cost (B,) px^2, valid (B,) bool, converged (B,) bool."""

    points: np.ndarray
    cost: np.ndarray
    valid: np.ndarray
    converged: np.ndarray


class Triangulator:
    """The dogleg solver of a triangulation bundle: cameras (B|1, N, 3, 4) and observations (B, N, 2) px ->
    ``Triangulation``, ``chunk`` points per graph call (keeps the working set in cache). Each chunk runs the start
    graph, then the step graph until none of its points is active or the bundle's iteration budget is spent.

    Args:
        bundle: the bundle folder; threads, provider: as ``runtime.session.Graph``; chunk: points per call.
    """

    def __init__(self, bundle: str | Path, threads: int | None = None, provider: str = "cpu",
                 chunk: int = 16384) -> None:
        self.bundle = Bundle(bundle, "triangulation", threads, provider)
        self.views = int(self.bundle.section("input")["views"])
        thresholds = self.bundle.section("thresholds")
        self.iterations, self.min_parallax = int(thresholds["iterations"]), float(thresholds["min_parallax_rad"])
        self.start_per_point = self.bundle.graph("dogleg_start")
        self.start_shared = self.bundle.graph("dogleg_start_shared")
        self.step = self.bundle.graph("dogleg_step")
        self.chunk = max(2, chunk)

    def __call__(self, cameras: np.ndarray, observations: np.ndarray) -> Triangulation:
        cameras = np.ascontiguousarray(cameras, np.float32)
        observations = np.ascontiguousarray(observations, np.float32)
        if observations.ndim != 3 or observations.shape[1:] != (self.views, 2):
            raise InputError(f"observations must be (B, {self.views}, 2) for this bundle (exported for "
                             f"{self.views} views), got {observations.shape}")
        n = observations.shape[0]
        if cameras.shape[1:] != (self.views, 3, 4) or cameras.shape[0] not in (1, n):
            raise InputError(f"cameras must be (1 or {n}, {self.views}, 3, 4), got {cameras.shape}")
        if n == 0:
            raise InputError("no points to triangulate")
        shared = cameras.shape[0] == 1
        parts = []
        for start in range(0, n, self.chunk):
            obs = observations[start : start + self.chunk]
            single = len(obs) == 1  # the graphs take at least 2 points: solve a lone point twice
            obs = np.concatenate([obs, obs]) if single else obs
            cams = cameras if shared else cameras[start : start + len(obs)]
            cams = np.concatenate([cams, cams]) if single and not shared else cams
            result = self._solve(cams, obs)
            parts.append([a[:1] for a in result] if single else result)
        return Triangulation(*(np.concatenate(field) for field in zip(*parts, strict=True)))

    def _solve(self, cameras: np.ndarray, observations: np.ndarray) -> Triangulation:
        """One chunk: start graph, step graph while any point is active (at most ``iterations`` times)."""
        start_graph = self.start_shared if cameras.shape[0] == 1 else self.start_per_point
        X0, usable, rows, state, active = start_graph(cameras, observations)
        for _ in range(self.iterations):
            if not active.any():
                break
            state, active = self.step(rows, state, active)
        cost = 2 * state[3]
        valid = usable & (state[4] > 0) & np.isfinite(cost)
        return Triangulation(np.ascontiguousarray((X0 + state[0:3]).T), cost, valid, ~active & valid)


def lower_median(values: np.ndarray, axis: int | None = None) -> np.ndarray:
    """The lower of the two middle values for an even count (``torch.median``'s convention)."""
    return np.quantile(values, 0.5, axis=axis, method="lower")


def evaluate(recon: Reconstruction, triangulator: Triangulator, views: int) -> tuple[dict, Triangulation, np.ndarray]:
    """Triangulate the tracks of ``recon`` with at least ``views`` views; returns the report (see the module
    docstring), the result and the (B,) file indices of the points."""
    if views != triangulator.views:
        raise InputError(f"--views {views}: the bundle's graphs were exported for {triangulator.views} views "
                         f"(export another with python -m export.triangulation --views {views})")
    cameras, observations, reference, index = recon.tracks(views)
    if len(index) == 0:
        raise InputError(f"no track of the reconstruction has {views} registered views")
    triangulator(cameras[:2], observations[:2])  # warm-up
    start = time.perf_counter()
    result = triangulator(cameras, observations)
    seconds = time.perf_counter() - start
    valid, n_valid = result.valid, int(result.valid.sum())
    centre = lower_median(recon.points, axis=0)
    radius = lower_median(np.linalg.norm(recon.points - centre, axis=-1))
    err = np.linalg.norm(result.points.astype(np.float64) - reference, axis=-1)[valid] / radius
    report = {
        "method": "dogleg_onnx", "views": views, "count": int(len(index)), "valid": n_valid,
        "err3d_median_rel": float(lower_median(err)) if n_valid else float("nan"),
        "err3d_mean_rel": float(err.mean()) if n_valid else float("nan"),
        "reproj_rms": float(np.sqrt(result.cost[valid].astype(np.float64).sum() / (views * max(n_valid, 1)))),
        "points_per_s": len(index) / seconds,
    }
    return report, result, index


def write_ply(path: str | Path, points: np.ndarray, colors: np.ndarray) -> None:
    """Points (M, 3) and uint8 colours (M, 3) as an ASCII PLY file, written atomically."""
    header = ["ply", "format ascii 1.0", f"element vertex {len(points)}", "property double x", "property double y",
              "property double z", "property uchar red", "property uchar green", "property uchar blue", "end_header"]
    rows = np.concatenate([points.astype(np.float64), colors.astype(np.float64)], 1)
    with atomic_path(path) as tmp, tmp.open("w") as handle:
        handle.write("\n".join(header) + "\n")
        np.savetxt(handle, rows, fmt="%.9g %.9g %.9g %d %d %d")


def triangulate_file(bundle: str | Path, path: str | Path, bal: bool = False, views: int = 3,
                     out: str | Path | None = None, threads: int | None = None, provider: str = "cpu") -> dict:
    """Triangulate the reconstruction ``path`` (Bundler, or BAL with ``bal``) with the bundle, optionally write the
    valid points as PLY to ``out``; returns the report (the command ``runtime.triangulation``)."""
    triangulator = Triangulator(bundle, threads, provider)
    recon = read_reconstruction(path, bal=bal)
    report, result, index = evaluate(recon, triangulator, views)
    if out:
        write_ply(out, result.points[result.valid], recon.colors[index][result.valid])
    return report


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="runtime.triangulation", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_runtime_arguments(parser)
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--bundler", type=Path, metavar="FILE", help="Bundler v0.3 .out reconstruction")
    source.add_argument("--bal", type=Path, metavar="FILE", help="BAL problem file")
    parser.add_argument("--views", type=int, default=3, metavar="K", help="tracks with at least K views (default 3)")
    parser.add_argument("--out", type=Path, metavar="points.ply", help="write the valid points as PLY")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    def run() -> None:
        report = triangulate_file(args.bundle, args.bundler or args.bal, args.bal is not None, args.views, args.out,
                                  args.threads, args.provider)
        print_report(report, args.json)

    return run_command("runtime.triangulation", run)


if __name__ == "__main__":
    raise SystemExit(main())

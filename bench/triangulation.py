"""Triangulation benchmark: every method side by side on the same synthetic cube (thesis 2.5, figure 2.2).

    python -m bench.triangulation [--points N] [--noise SIGMA] [--device cpu|cuda] [--methods ...]
                                  [--bundle DIR] [--json] [--plot FILE.png]

Points in the cube [-1, 1]^3, three cameras on a radius-5 circle at -0.3/0/+0.3 rad (f = 1000 px), N(0, sigma)
pixel noise. Two-view methods use the first two views. ``ort_dogleg`` is the deployment runtime's dogleg
(``runtime.triangulation``: the exported graph in onnxruntime, float32, cameras shared, ``--threads`` threads) on
``--bundle DIR`` or a bundle exported into a temporary folder; it is not among the default methods. Prints one JSON
object ``{"config": {...}, "methods": {NAME: {views, points, points_per_s, err3d_median, err3d_mean, err3d_p95,
reproj_rms, valid_frac}}}``; ``reproj_rms`` is the RMS over observations of the reprojection distance (px).
Speeds are best-of-``--repeats`` wall clock including everything from input arrays to 3D points.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import torch

from core.checks import check_device
from core.errors import InputError
from core.threads import set_cpu_threads
from data.sfm.bundler import read_bundler
from data.sfm.synthetic import SyntheticScene, synthetic_cube_scene
from models.geometry import (
    fundamental_from_cameras,
    reprojection_cost,
    triangulate_dogleg,
    triangulate_midpoint,
    triangulate_polynomial,
)
from models.geometry.evaluation import evaluate_reconstruction

ALL_METHODS = (
    "dogleg", "dogleg_compiled", "ort_dogleg", "midpoint3", "midpoint2", "polynomial", "kornia_dlt", "opencv_dlt",
    "opencv_optimal", "pycolmap",
)
DEFAULT_METHODS = tuple(m for m in ALL_METHODS if m not in ("dogleg_compiled", "ort_dogleg"))


def _best_time(fn: Callable[[], np.ndarray | torch.Tensor], repeats: int, sync: Callable[[], None]) -> tuple:
    fn()  # warm-up (allocations, lazy initialisation)
    best, out = math.inf, None
    for _ in range(repeats):
        sync()
        start = time.perf_counter()
        out = fn()
        sync()
        best = min(best, time.perf_counter() - start)
    return best, out


def _compiled_dogleg(P: torch.Tensor, x: torch.Tensor) -> tuple[Callable[[], torch.Tensor], float]:
    """``torch.compile``d dogleg (dynamic point count, fixed 5 iterations) and its compile time in seconds."""
    solver = torch.compile(triangulate_dogleg, dynamic=True)
    start = time.perf_counter()
    solver(P, x[:1000])
    return (lambda: solver(P, x, chunk_size=262_144).points), time.perf_counter() - start


def _ort_dogleg(P: torch.Tensor, x: torch.Tensor, bundle: Path | None, threads: int) -> Callable[[], np.ndarray]:
    """The runtime's dogleg on a bundle (exported into a temporary folder without ``bundle``) with ``threads``
    onnxruntime threads."""
    from runtime.triangulation import Triangulator

    if bundle is None:
        from export.triangulation import export_bundle

        bundle = export_bundle(Path(tempfile.mkdtemp(prefix="tri_bundle_")) / "bundle", views=x.shape[1])
    solver = Triangulator(bundle, threads=threads)
    cameras, observations = P.float().cpu().numpy(), x.float().cpu().numpy()
    return lambda: solver(cameras, observations).points


def _method_table(
    scene: SyntheticScene, device: str, dtype: torch.dtype, pycolmap_points: int, methods: tuple[str, ...],
    bundle: Path | None = None, threads: int = 1,
) -> tuple[dict, dict]:
    """name -> (views, number of points, callable returning (B, 3) points), and notes for the config."""
    P = scene.cameras.to(device, dtype)
    x = scene.observations.to(device, dtype)
    P_np = scene.cameras[0].numpy()
    x_np = scene.observations.numpy()
    p1, p2 = np.ascontiguousarray(x_np[:, 0].T), np.ascontiguousarray(x_np[:, 1].T)
    F = fundamental_from_cameras(scene.cameras[:, 0], scene.cameras[:, 1])[0].numpy()
    n = x.shape[0]

    def opencv_dlt() -> np.ndarray:
        X = cv2.triangulatePoints(P_np[0], P_np[1], p1, p2)
        return (X[:3] / X[3:]).T

    def opencv_optimal() -> np.ndarray:
        c1, c2 = cv2.correctMatches(F, p1.T[None], p2.T[None])
        X = cv2.triangulatePoints(P_np[0], P_np[1], c1[0].T, c2[0].T)
        return (X[:3] / X[3:]).T

    def kornia_dlt() -> torch.Tensor:
        from kornia.geometry.epipolar import triangulate_points

        return triangulate_points(P[0, 0], P[0, 1], x[:, 0], x[:, 1])

    notes = {}
    table = {
        "dogleg": (3, n, lambda: triangulate_dogleg(P, x, chunk_size=262_144).points),
        "midpoint3": (3, n, lambda: triangulate_midpoint(P, x).points),
        "midpoint2": (2, n, lambda: triangulate_midpoint(P[:, :2], x[:, :2]).points),
        "polynomial": (2, n, lambda: triangulate_polynomial(P[:, :2], x[:, :2]).points),
        "kornia_dlt": (2, n, kornia_dlt),
        "opencv_dlt": (2, n, opencv_dlt),
        "opencv_optimal": (2, n, opencv_optimal),
    }
    if "dogleg_compiled" in methods:
        solver, notes["compile_s"] = _compiled_dogleg(P, x)
        table["dogleg_compiled"] = (3, n, solver)
    if "ort_dogleg" in methods:
        table["ort_dogleg"] = (3, n, _ort_dogleg(P, x, bundle, threads))
    try:
        import pycolmap
    except ImportError:
        return table, notes
    m = min(pycolmap_points, n)
    K_inv = np.linalg.inv(scene.intrinsics.numpy())
    poses = [K_inv @ Pi for Pi in P_np]
    rays = np.einsum("ij,bnj->bni", K_inv, np.concatenate((x_np[:m], np.ones((m, 3, 1))), -1))
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)

    def colmap() -> np.ndarray:
        out = np.full((m, 3), np.nan)
        for i in range(m):
            X = pycolmap.triangulate_multi_view_point(poses, rays[i])
            if X is not None:
                out[i] = X.ravel()
        return out

    table["pycolmap"] = (3, m, colmap)
    return table, notes


def run(
    points: int = 100_000,
    noise: float = 1.0,
    device: str = "cpu",
    dtype: str = "float32",
    seed: int = 0,
    repeats: int = 3,
    pycolmap_points: int = 10_000,
    methods: tuple[str, ...] = DEFAULT_METHODS,
    bundle: Path | None = None,
) -> tuple[dict, dict[str, np.ndarray]]:
    """Run the benchmark; returns the JSON-ready report and per-method arrays of 3D and reprojection errors
    (``bundle``: the triangulation bundle of ``ort_dogleg``, see the module docstring)."""
    scene = synthetic_cube_scene(points, num_views=3, noise_px=noise, seed=seed)
    table, notes = _method_table(scene, device, getattr(torch, dtype), pycolmap_points, methods, bundle,
                                 torch.get_num_threads())
    sync = torch.cuda.synchronize if device.startswith("cuda") else (lambda: None)
    report: dict = {"config": {"points": points, "noise_px": noise, "device": device, "dtype": dtype,
                               "torch_threads": torch.get_num_threads(), "repeats": repeats, **notes}, "methods": {}}
    errors: dict[str, np.ndarray] = {}
    for name in methods:
        if name not in table:
            continue
        views, count, fn = table[name]
        seconds, X = _best_time(fn, repeats if count >= 1000 else 1, sync)
        X = torch.as_tensor(X).detach().cpu().double()
        truth = scene.points[:count]
        valid = torch.isfinite(X).all(-1)
        X = torch.where(valid.unsqueeze(-1), X, torch.zeros_like(X))
        err3d = (X - truth).norm(dim=-1)[valid].numpy()
        cost = reprojection_cost(scene.cameras[:, :views], X, scene.observations[:count, :views])[valid]
        per_obs = (cost / views).sqrt().numpy()
        report["methods"][name] = {
            "views": views,
            "points": count,
            "points_per_s": count / seconds,
            "err3d_median": float(np.median(err3d)),
            "err3d_mean": float(err3d.mean()),
            "err3d_p95": float(np.quantile(err3d, 0.95)),
            "reproj_rms": float(math.sqrt(cost.sum() / (len(cost) * views))),
            "valid_frac": float(valid.double().mean()),
        }
        errors[name] = np.stack((err3d, per_obs))
    if "opencv_dlt" in report["methods"]:
        base = report["methods"]["opencv_dlt"]["points_per_s"]
        for entry in report["methods"].values():
            entry["speed_vs_opencv_dlt"] = entry["points_per_s"] / base
    return report, errors


def plot(errors: dict[str, np.ndarray], path: str | Path, title: str) -> None:
    """Distributions of 3D error and per-point RMS reprojection error per method (like thesis figure 2.2)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for column, (ax, label) in enumerate(
        zip(axes, ("3D error (world units)", "RMS reprojection error per point (px)"), strict=True)
    ):
        values = {name: e[column][e[column] > 0] for name, e in errors.items()}
        low = min(v.min() for v in values.values())
        high = max(v.max() for v in values.values())
        bins = np.logspace(np.log10(low), np.log10(high), 60)
        for name, v in values.items():
            ax.hist(v, bins=bins, weights=np.full(len(v), 1 / len(v)), histtype="step", label=name, linewidth=1.3)
        ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("fraction of points")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def format_table(report: dict) -> str:
    """The report as an aligned text table."""
    head = f"{'method':<15}{'views':>6}{'points/s':>12}{'x cv DLT':>9}{'3D med':>10}{'3D mean':>10}{'3D p95':>10}"
    lines = [head + f"{'reproj':>9}", "-" * (len(head) + 9)]
    for name, m in report["methods"].items():
        lines.append(
            f"{name:<15}{m['views']:>6}{m['points_per_s']:>12.3g}{m.get('speed_vs_opencv_dlt', float('nan')):>9.2f}"
            f"{m['err3d_median']:>10.5f}{m['err3d_mean']:>10.5f}{m['err3d_p95']:>10.5f}{m['reproj_rms']:>9.3f}"
        )
    return "\n".join(lines)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Small side-by-side run for ``make demo``: the synthetic cube, then the real reconstruction when present.
    With ``report_dir``, writes the error distributions there; returns the figures as (file name, caption)."""
    set_cpu_threads(1)
    report, errors = run(points=5_000 if quick else 20_000, repeats=1 if quick else 2,
                         pycolmap_points=500 if quick else 2000, methods=DEFAULT_METHODS)
    print(f"Triangulation, synthetic cube: {report['config']['points']} points, sigma = 1 px")
    print(format_table(report))
    figures = []
    if report_dir is not None:
        plot(errors, report_dir / "triangulation.png", f"synthetic cube, {report['config']['points']} points")
        figures.append(("triangulation.png", "3D error and reprojection error of every method on the synthetic "
                        "cube (sigma = 1 px): the dogleg's errors are the smallest"))
    path = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "sfm" / "Balbianello.out"
    if not path.is_file():
        print("(../shared/data/sfm/Balbianello.out not found: real-data part skipped)")
        return figures
    recon = read_bundler(path)
    print(f"\nTriangulation, {path.name} (bundle-adjusted points as reference), first 3 views of each track")
    print(f"{'method':<12}{'points':>8}{'3D err/radius med':>19}{'mean':>10}{'reproj RMS px':>15}")
    for method in ("dogleg", "midpoint", "dlt"):
        r, _, _ = evaluate_reconstruction(recon, 3, method)
        print(f"{method:<12}{r['count']:>8}{r['err3d_median_rel']:>19.2e}{r['err3d_mean_rel']:>10.2e}"
              f"{r['reproj_rms']:>15.3f}")
    return figures


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--noise", type=float, default=1.0, help="pixel noise sigma")
    parser.add_argument("--device", default="cpu", help="cpu or cuda")
    parser.add_argument("--dtype", choices=("float32", "float64"), default="float32", help="dtype of torch methods")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pycolmap-points", type=int, default=10_000, help="pycolmap runs per point in Python")
    parser.add_argument("--methods", nargs="+", choices=ALL_METHODS, default=list(DEFAULT_METHODS))
    parser.add_argument("--compile", action="store_true", help="also time torch.compile'd dogleg (dogleg_compiled)")
    parser.add_argument("--bundle", type=Path, metavar="DIR",
                        help="triangulation bundle for ort_dogleg (default: one exported into a temporary folder)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1,
                        help="CPU threads for torch and OpenCV (default 1: OpenCV's DLT is single-threaded)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", type=Path, help="write error distributions to this PNG")
    args = parser.parse_args(argv)
    if args.points < 1:
        parser.error("--points must be positive")
    try:
        check_device(args.device, "--device")
    except InputError as err:
        parser.error(str(err))
    set_cpu_threads(args.threads)
    methods = tuple(args.methods) + (("dogleg_compiled",) if args.compile else ())
    report, errors = run(args.points, args.noise, args.device, args.dtype, args.seed, args.repeats,
                         args.pycolmap_points, methods, args.bundle)
    if args.plot:
        plot(errors, args.plot, f"{args.points} points, sigma = {args.noise} px")
    print(json.dumps(report, indent=None) if args.json else format_table(report))


if __name__ == "__main__":
    main()

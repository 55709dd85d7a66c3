"""Export the dogleg triangulation solver as a deployment bundle (``runtime.triangulation`` runs it).

    python -m export.triangulation --out DIR [--views 3] [--iterations 5] [--check]

Graphs (float32; the number of points B dynamic; closed-form 3x3 solves; packing of the tensors between them in
``models.geometry.dogleg_stages``):

- ``dogleg_start.onnx``: ``cameras`` (B, N, 3, 4) per point (a reconstruction's tracks), ``observations`` (B, N, 2)
  px -> ``start`` (3, B), ``usable`` (B,), ``rows`` (8, 2N, B), ``state`` (16, B), ``active`` (B,).
- ``dogleg_start_shared.onnx``: the same with ``cameras`` (1, N, 3, 4) shared by all points (a calibrated rig).
- ``dogleg_step.onnx``: one iteration, ``rows``, ``state``, ``active`` -> ``state``, ``active``. The runtime runs
  at most ``iterations`` of them and stops when no point is active, as the eager solver does.

``--check`` compares onnxruntime with PyTorch on the synthetic cube (largest difference relative to the scene).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from core.command import CommandParser, run_command
from core.errors import InputError
from data.sfm.synthetic import synthetic_cube_scene
from export.bundle import staged_bundle
from export.onnx import OPSET, export_onnx
from models.geometry.dogleg import TriangulateDogleg
from models.geometry.dogleg_stages import DoglegStart, DoglegStep
from runtime.bundle import write_manifest
from runtime.triangulation import Triangulator

START_OUTPUTS = ("start", "usable", "rows", "state", "active")
STEP_INPUTS = ("rows", "state", "active")


def export_start(path: str | Path, views: int = 3, shared: bool = True, min_parallax: float = 1e-3) -> Path:
    """Export :class:`DoglegStart` (float32, ``views`` views) to ``path``, with cameras shared by all points
    (``shared``) or one set per point."""
    scene = synthetic_cube_scene(64, num_views=views, dtype=torch.float32)
    points = torch.export.Dim("points", min=2)
    cameras = scene.cameras if shared else scene.cameras.expand(64, -1, -1, -1).contiguous()
    return export_onnx(DoglegStart(min_parallax=min_parallax), (cameras, scene.observations), path,
                       ("cameras", "observations"), START_OUTPUTS,
                       dynamic_shapes={"P": None if shared else {0: points}, "x": {0: points}})


def export_step(path: str | Path, views: int = 3) -> Path:
    """Export :class:`DoglegStep` (float32, ``views`` views) to ``path``."""
    scene = synthetic_cube_scene(64, num_views=views, dtype=torch.float32)
    _, _, rows, state, active = DoglegStart()(scene.cameras, scene.observations)
    points = torch.export.Dim("points", min=2)
    return export_onnx(DoglegStep(), (rows, state, active), path, STEP_INPUTS, ("next_state", "next_active"),
                       dynamic_shapes={"rows": {2: points}, "state": {1: points}, "active": {0: points}})


def export_bundle(out: str | Path, views: int = 3, iterations: int = 5, min_parallax: float = 1e-3) -> Path:
    """Write the triangulation bundle (its three graphs and ``bundle.json``) to the folder ``out``."""
    if views < 2:
        raise InputError(f"--views must be at least 2, got {views}")
    if iterations < 1:
        raise InputError(f"--iterations must be at least 1, got {iterations}")
    with staged_bundle(out) as folder:
        export_start(folder / "dogleg_start.onnx", views, shared=False, min_parallax=min_parallax)
        export_start(folder / "dogleg_start_shared.onnx", views, shared=True, min_parallax=min_parallax)
        export_step(folder / "dogleg_step.onnx", views)
        write_manifest(folder, "triangulation", OPSET,
                       input={"views": views, "dtype": "float32", "cameras": "(B|1, N, 3, 4) P = K [R | t], w > 0 "
                              "in front", "observations": "(B, N, 2) px"},
                       thresholds={"iterations": iterations, "min_parallax_rad": min_parallax})
    return Path(out)


def parity(out: str | Path, points: int = 20_000, seed: int = 1) -> float:
    """Largest |onnxruntime - PyTorch| point difference of the bundle on the synthetic cube (cameras shared and per
    point), relative to the cube's half size (1)."""
    runtime = Triangulator(out)
    scene = synthetic_cube_scene(points, num_views=runtime.views, noise_px=1.0, seed=seed, dtype=torch.float32)
    model = TriangulateDogleg(runtime.iterations, min_parallax=runtime.min_parallax)
    per_point = scene.cameras.expand(points, -1, -1, -1)
    error = 0.0
    for cameras in (scene.cameras, per_point):
        expected = model(cameras, scene.observations).points.numpy()
        got = runtime(cameras.numpy(), scene.observations.numpy()).points
        error = max(error, float(np.abs(got - expected).max()))
    return error


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.triangulation", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="bundle folder to write")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--check", action="store_true", help="compare onnxruntime with PyTorch on the synthetic cube")
    args = parser.parse_args(argv)

    def run() -> None:
        print(f"wrote {export_bundle(args.out, args.views, args.iterations)}")
        if args.check:
            print(f"onnxruntime vs PyTorch on the synthetic cube: max point difference {parity(args.out):.2e}")

    return run_command("export.triangulation", run)


if __name__ == "__main__":
    raise SystemExit(main())

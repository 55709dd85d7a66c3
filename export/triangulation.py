"""Export the dogleg triangulation solver to ONNX.

    python -m export.triangulation --out dogleg.onnx [--views 3] [--iterations 5] [--dtype float32]

The graph takes ``cameras`` (1, N, 3, 4) shared by all points and ``observations`` (B, N, 2) in px with a
dynamic number of points B, and returns ``points`` (B, 3), ``cost`` (B,), ``valid`` (B,) and ``converged`` (B,).
It runs a fixed number of iterations (no data-dependent loop) with closed-form 3x3 solves.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from core.command import CommandParser, run_command
from data.sfm.synthetic import synthetic_cube_scene
from export.onnx import export_onnx
from models.geometry.dogleg import TriangulateDogleg

INPUTS = ("cameras", "observations")
OUTPUTS = ("points", "cost", "valid", "converged")


def export_dogleg(path: str | Path, views: int = 3, iterations: int = 5, dtype: torch.dtype = torch.float32) -> Path:
    """Export :class:`TriangulateDogleg` with ``iterations`` fixed iterations for ``views`` views to ``path``."""
    scene = synthetic_cube_scene(64, num_views=views, dtype=dtype)
    points = torch.export.Dim("points", min=2)
    return export_onnx(
        TriangulateDogleg(iterations=iterations),
        (scene.cameras, scene.observations),
        path,
        INPUTS,
        OUTPUTS,
        dynamic_shapes={"P": None, "x": {0: points}},
    )


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.triangulation", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    args = parser.parse_args(argv)

    def run() -> None:
        print(f"wrote {export_dogleg(args.out, args.views, args.iterations, getattr(torch, args.dtype))}")

    return run_command("export.triangulation", run)


if __name__ == "__main__":
    raise SystemExit(main())

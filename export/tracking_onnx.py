"""Export one step of the DCF point tracker to ONNX (filters as state in and out).

    python -m export.tracking_onnx --out track_step.onnx [--method ccot] [--height 240 --width 320]

Inputs: ``frame`` (1, 1, H, W) gray float32 (H, W dynamic), ``previous`` (the frame before it, for the
forward-backward test), ``positions`` (P, 2), ``lost`` (P,) bool and the
filter state of every pyramid level, ``filters_0`` .. ``filters_{L-1}`` (3, N_l, P, K_l) (real and imaginary
parts of the numerators and the denominators, finest level first, point-interleaved), with a dynamic number of
points P. Outputs: ``positions_out``, ``lost_out``, ``psr`` (P,) and the updated ``filters_l_out``. The graph
uses one Gather per level for the patches, matrix products for the small DFTs and a fixed number of Newton
iterations; the first frame's state comes from :meth:`PointTracker.init`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from core.command import CommandParser, run_command
from export.onnx import export_onnx
from models.tracking import PointTracker


def io_names(levels: int) -> tuple[list[str], list[str]]:
    """Input and output names of the exported step for a ``levels``-level tracker."""
    filters = [f"filters_{level}" for level in range(levels)]
    inputs = ["frame", "previous", "positions", "lost", *filters]
    return inputs, ["positions_out", "lost_out", "psr", *[f"{name}_out" for name in filters]]


def example_inputs(tracker: PointTracker, height: int, width: int, points: int, seed: int = 0):
    """Real inputs for one step: a textured frame, its filters at random points, and a shifted next frame."""
    gen = torch.Generator().manual_seed(seed)
    base = torch.rand(1, 1, height // 8 + 2, width // 8 + 2, generator=gen) * 255
    frame = torch.nn.functional.interpolate(base, size=(height, width), mode="bicubic", align_corners=False)
    frame = frame + 10 * torch.rand(1, 1, height, width, generator=gen)
    pts = torch.rand(points, 2, generator=gen) * torch.tensor([width - 1.0, height - 1.0])
    state = tracker.init(frame[0, 0], pts)
    nxt = torch.roll(frame, (2, -3), (2, 3))
    return nxt, frame, state.positions, state.lost, *state.filters


def export_tracking_step(
    path: str | Path, method: str = "ccot", height: int = 240, width: int = 320, points: int = 64
) -> Path:
    """Export :meth:`PointTracker.forward` for ``method`` with dynamic H, W and P; returns the path."""
    tracker = PointTracker(method).eval()
    args = example_inputs(tracker, height, width, points)
    p = torch.export.Dim("points", min=2, max=100_000)
    h = torch.export.Dim("height", min=64, max=4096)
    w = torch.export.Dim("width", min=64, max=4096)
    inputs, outputs = io_names(tracker.levels)
    dynamic = {"frame": {2: h, 3: w}, "previous": {2: h, 3: w}, "positions": {0: p}, "lost": {0: p}}
    dynamic["filters"] = tuple({2: p} for _ in range(tracker.levels))  # forward's *filters
    with torch.no_grad():
        return export_onnx(tracker, args, path, inputs, outputs, dynamic_shapes=dynamic)


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.tracking_onnx", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="output .onnx path")
    parser.add_argument("--method", default="ccot", choices=["ccot", "ccot_ff", "mosse"])
    parser.add_argument("--height", type=int, default=240, help="example frame height (the graph is dynamic)")
    parser.add_argument("--width", type=int, default=320, help="example frame width (the graph is dynamic)")
    args = parser.parse_args(argv)
    return run_command("export.tracking_onnx",
                       lambda: print(f"wrote {export_tracking_step(args.out, args.method, args.height, args.width)}"))


if __name__ == "__main__":
    raise SystemExit(main())

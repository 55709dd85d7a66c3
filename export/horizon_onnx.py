"""Export the horizon networks and the levelling warp to ONNX (dynamo, opset 20) with onnxruntime parity.

    python -m export.horizon_onnx --which finder --ckpt finder.ckpt --out finder.onnx [--height 64 --width 512]
    python -m export.horizon_onnx --which segmenter --ckpt segmenter.ckpt --out segmenter.onnx
    python -m export.horizon_onnx --which level --out level.onnx

Graphs (batch and width dynamic; the width must stay a multiple of the backbone stride):
- finder: ``image`` (B, 3, H, W) tilted panorama -> ``sincos`` (B, 4) = (sin p, cos p, sin q, cos q).
- segmenter: ``image`` (B, 3, H, W) whole levelled panorama -> ``profiles`` (B, 2, W) tan elevation of the
  horizon and the water line (``models.horizon.segmenter.PanoramaSegmenter``).
- level: ``image`` (B, 3, H, W), ``pitch`` (B,), ``roll`` (B,) rad -> ``level`` (B, 3, H, W).
The deployed chain is finder -> atan2 -> level -> segmenter (ch. 4.3). Without ``--ckpt`` the network is
randomly initialised (for testing the export only).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch
from torch import nn

from core.command import CommandParser, run_command
from core.errors import InputError
from export.onnx import export_onnx
from models.builders import horizon_network
from models.onnx_graph import OnnxGraph

SPECS = {
    "finder": (("image",), ("sincos",)),
    "segmenter": (("image",), ("profiles",)),
    "level": (("image", "pitch", "roll"), ("level",)),
}


def example_inputs(which: str, height: int, width: int, batch: int = 2, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """Random inputs of the right shapes (tilts of a few degrees for ``level``)."""
    gen = torch.Generator().manual_seed(seed)
    image = torch.rand(batch, 3, height, width, generator=gen)
    if which == "level":
        return image, torch.randn(batch, generator=gen) * 0.05, torch.randn(batch, generator=gen) * 0.05
    return (image,)


def export_horizon(which: str, model: nn.Module, path: str | Path, height: int = 64, width: int = 512) -> Path:
    """Export ``model`` (``models.builders.horizon_network``) with dynamic batch and width; returns the path."""
    stride = 1 if which == "level" else model.backbone.strides[model.stage]
    if width % stride or height % stride:
        raise InputError(f"height and width must be multiples of the backbone stride {stride}, got {height}x{width}")
    inputs = example_inputs(which, height, width)
    batch = torch.export.Dim("batch", min=1, max=64)
    columns = stride * torch.export.Dim("columns", min=max(2, 64 // stride), max=16384 // stride)
    shapes: list = [{0: batch, 3: columns}] + [{0: batch}] * (len(inputs) - 1)
    names_in, names_out = SPECS[which]
    return export_onnx(model, inputs, path, names_in, names_out, dynamic_shapes=tuple(shapes))


def parity(which: str, model: nn.Module, path: str | Path, inputs: tuple[torch.Tensor, ...]) -> float:
    """Largest |onnxruntime - PyTorch| of the exported graph on ``inputs``."""
    with torch.no_grad():
        expected = model(*inputs)
    actual = OnnxGraph(path)(*inputs)
    return float((actual - expected).abs().max())


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.horizon_onnx", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--which", choices=tuple(SPECS), required=True)
    parser.add_argument("--ckpt", type=Path, help="Lightning checkpoint of the system (finder / segmenter)")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--height", type=int, default=64)
    parser.add_argument("--width", type=int, default=512)
    args = parser.parse_args(argv)

    def run() -> None:
        model = horizon_network(args.which, args.ckpt)
        path = export_horizon(args.which, model, args.out, args.height, args.width)
        error = parity(args.which, model, path, example_inputs(args.which, args.height, args.width, seed=1))
        print(f"wrote {path}; max |onnxruntime - torch| = {error:.2e}")

    return run_command("export.horizon_onnx", run)


if __name__ == "__main__":
    raise SystemExit(main())

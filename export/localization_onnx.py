"""Export the matching step of horizon localisation to ONNX (dynamo, opset 20) with an onnxruntime parity check.

    python -m export.localization_onnx --out matcher.onnx [--bins 1024 --frequencies 513 --band-deg 4]

Graph (``models.horizon.matching.BandPsr``; number of locations L and of queries B dynamic):
``filters`` (L, 2K) float32 bank chunk, ``profile`` (B, N) float32 tan elevations, ``heading_deg`` (B,) float32
-> ``psr`` (B, L) and ``heading`` (B, L) degrees. Stored float16 chunks are cast to float32 before the call.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from core.command import CommandParser, run_command
from core.errors import InputError
from export.onnx import export_onnx
from models.horizon.matching import BandPsr
from models.onnx_graph import OnnxGraph


def example_inputs(bins: int, frequencies: int, locations: int = 64, batch: int = 2, seed: int = 0):
    """Random filters, smooth random profiles and headings of the right shapes."""
    gen = torch.Generator().manual_seed(seed)
    filters = torch.randn(locations, 2 * frequencies, generator=gen)
    profile = torch.cumsum(torch.randn(batch, bins, generator=gen), -1) * 1e-3
    heading = torch.rand(batch, generator=gen) * 359.0
    return filters, profile, heading


def export_matcher(path: str | Path, bins: int = 1024, frequencies: int | None = None, band_deg: float = 4.0,
                   exclude: int = 11, threshold_deg: float = 1.0, drop_harmonics: int = 0) -> Path:
    """Export :class:`BandPsr` for profiles of ``bins`` bins and banks of ``frequencies`` stored frequencies."""
    frequencies = frequencies or bins // 2 + 1
    if not 2 <= frequencies <= bins // 2 + 1:
        raise InputError(f"--frequencies must be in [2, {bins // 2 + 1}], got {frequencies}")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    model = BandPsr(band_deg, exclude, threshold_deg, drop_harmonics).eval()
    locations, batch = torch.export.Dim("locations", min=2), torch.export.Dim("batch", min=1)
    shapes = {"filters": {0: locations}, "profile": {0: batch}, "heading_deg": {0: batch}}
    return export_onnx(model, example_inputs(bins, frequencies), path, ("filters", "profile", "heading_deg"),
                       ("psr", "heading"), dynamic_shapes=shapes)


def parity(path: str | Path, model: BandPsr, inputs: tuple[torch.Tensor, ...]) -> float:
    """Largest difference of the ONNX PSR from PyTorch on ``inputs``, relative to the largest PSR."""
    with torch.no_grad():
        reference = model(*inputs)[0].numpy()
    onnx_psr = OnnxGraph(path)(*inputs)[0].numpy()
    return float(np.max(np.abs(onnx_psr - reference)) / np.max(np.abs(reference)))


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.localization_onnx", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--bins", type=int, default=1024)
    parser.add_argument("--frequencies", type=int, default=None, help="stored half-spectrum length K")
    parser.add_argument("--band-deg", type=float, default=4.0)
    parser.add_argument("--exclude", type=int, default=11)
    parser.add_argument("--threshold-deg", type=float, default=1.0, help="profile normalisation threshold")
    parser.add_argument("--drop-harmonics", type=int, default=0, help="ignore the profiles' harmonics 1..H")
    args = parser.parse_args(argv)

    def run() -> None:
        path = export_matcher(args.out, args.bins, args.frequencies, args.band_deg, args.exclude,
                              args.threshold_deg, args.drop_harmonics)
        inputs = example_inputs(args.bins, args.frequencies or args.bins // 2 + 1, locations=500, batch=3, seed=1)
        error = parity(path, BandPsr(args.band_deg, args.exclude, args.threshold_deg, args.drop_harmonics), inputs)
        print(f"wrote {path}; onnxruntime vs PyTorch PSR difference (relative to the largest PSR) {error:.2e}")

    return run_command("export.localization_onnx", run)


if __name__ == "__main__":
    raise SystemExit(main())

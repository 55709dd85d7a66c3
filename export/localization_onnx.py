"""The matching step of horizon localisation as an ONNX graph (dynamo, opset 20), part of the horizon bundle
(``export.horizon_onnx``).

Graph (``models.horizon.matching.BandPsr``; number of locations L and of queries B dynamic):
``filters`` (L, 2K) float32 bank block, ``profile`` (B, N) float32 tan elevations, ``heading_deg`` (B,) float32
-> ``psr`` (B, L) and ``heading`` (B, L) degrees. Stored float16 chunks are cast to float32 before the call.
"""

from __future__ import annotations

from pathlib import Path

import torch

from core.errors import InputError
from export.onnx import export_onnx
from models.horizon.matching import BandPsr


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

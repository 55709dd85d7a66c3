"""``infer.py horizon-label``: the classical horizon pipeline on one panorama (thesis ch. 4.2, eq. 4.1)."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "horizon-label"
HELP = "Classical horizon pipeline (Canny + Hough + eq. 4.1 against the DEM) on one panorama."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--image", type=Path, required=True, help="tilted 360-degree panorama (column 0 = forward)")
    p.add_argument("--dem", type=Path, required=True, help="GeoTIFF or .npz DEM")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood the DEM at this level (m)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--position", type=float, nargs=2, metavar=("X", "Y"), help="GPS in DEM map metres")
    where.add_argument("--lonlat", type=float, nargs=2, metavar=("LON", "LAT"),
                       help="GPS in WGS84 degrees (needs a DEM with a CRS)")
    p.add_argument("--camera-height", type=float, default=2.0, metavar="M", help="above the sea (m)")
    p.add_argument("--compass", type=float, required=True, metavar="DEG", help="compass heading of column 0")
    p.add_argument("--max-range", type=float, default=8000.0, metavar="M", help="ray length (m)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    import math

    import numpy as np
    import torch

    from core.command import print_report
    from core.raycast import VirtualHorizon
    from data.horizon.classical import ClassicalHorizon
    from data.horizon.datamodule import read_full_panorama
    from data.world.dem import load_dem

    image = read_full_panorama(args.image)
    dem = load_dem(args.dem, sea_level=args.sea_level, require_crs=args.lonlat is not None)
    xy = dem.from_lonlat(np.array(args.lonlat)) if args.lonlat else np.array(args.position, dtype=np.float64)
    dem.check_positions(xy, "--position" if args.position else "--lonlat")
    labeller = ClassicalHorizon(VirtualHorizon(dem, bins=image.shape[-1], max_range=args.max_range, step=dem.cell))
    labels = labeller(image, torch.tensor(xy)[None], torch.tensor([args.camera_height], dtype=torch.float64),
                      torch.tensor([math.radians(args.compass)], dtype=torch.float64))
    report = {"pitch_deg": math.degrees(labels.pitch.item()), "roll_deg": math.degrees(labels.roll.item()),
              "heading_deg": math.degrees(labels.heading.item()), "quality": labels.quality.item(),
              "ok": bool(labels.ok.item())}
    print_report(report, args.json)
    return 0 if report["ok"] else 1

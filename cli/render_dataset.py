"""``infer.py render-dataset``: rendered, classically labelled horizon training data (thesis ch. 4.2)."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "render-dataset"
HELP = ("Render panoramas along boat trajectories, label them with the classical pipeline and write images, "
        "labels and ground truth.")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset directory to write")
    p.add_argument("--dem", type=Path, metavar="FILE",
                   help="GeoTIFF or .npz DEM (default: generate a procedural archipelago)")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood --dem at this level (m)")
    p.add_argument("--dem-size", type=float, default=16000.0, metavar="M", help="generated DEM side (m)")
    p.add_argument("--dem-cell", type=float, default=5.0, metavar="M", help="generated DEM cell size (m)")
    p.add_argument("--dem-seed", type=int, default=0, help="generated DEM seed")
    p.add_argument("--count", type=int, default=200, help="number of panoramas")
    p.add_argument("--width", type=int, default=2048, help="panorama width (px)")
    p.add_argument("--height", type=int, default=256, help="panorama height (px)")
    p.add_argument("--degraded-fraction", type=float, default=0.0, metavar="F",
                   help="share of frames with heavy haze, noise, blur and glare")
    p.add_argument("--gps-noise", type=float, default=0.0, metavar="M", help="GPS error std (m)")
    p.add_argument("--compass-noise", type=float, default=2.0, metavar="DEG", help="compass error std (deg)")
    p.add_argument("--seed", type=int, default=0, help="trajectory, appearance and noise seed")
    p.add_argument("--batch", type=int, default=4, help="panoramas rendered at a time")


def run(args: argparse.Namespace) -> int:
    from data.horizon.dataset import DatasetSettings, write_dataset
    from data.world.dem import generate_archipelago, load_dem

    if args.dem is not None:
        dem = load_dem(args.dem, sea_level=args.sea_level)
    else:
        dem = generate_archipelago(size_m=args.dem_size, cell=args.dem_cell, seed=args.dem_seed)
    settings = DatasetSettings(
        count=args.count, width=args.width, height=args.height, degraded_fraction=args.degraded_fraction,
        gps_noise_m=args.gps_noise, compass_noise_deg=args.compass_noise, seed=args.seed,
        render_bins=max(4096, 2 * args.width), label_bins=args.width,
    )
    out = write_dataset(args.out, dem, settings, batch=args.batch)
    print(f"wrote {settings.count} panoramas to {out}")
    return 0

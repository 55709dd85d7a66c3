"""``infer.py build-bank``: the 1-D MOSSE filter bank over the sea of a DEM (thesis ch. 4.4)."""

from __future__ import annotations

import argparse
from pathlib import Path

from core.errors import InputError

NAME = "build-bank"
HELP = "Build the 1-D MOSSE filter bank over the sea of a DEM for horizon localisation."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dem", type=Path, required=True,
                   help="GeoTIFF or .npz DEM (a geographic GeoTIFF is reprojected to its UTM zone)")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood the DEM at this level (m)")
    p.add_argument("--spacing", type=float, required=True, metavar="M", help="grid spacing of the locations (m)")
    p.add_argument("--out", type=Path, required=True, metavar="BANK",
                   help="bank directory (an interrupted build resumes at its first unfinished tile)")
    p.add_argument("--bins", type=int, default=1024, help="azimuth bins per profile (default 1024)")
    p.add_argument("--camera-height", type=float, default=2.0, metavar="M", help="above the sea (default 2 m)")
    p.add_argument("--max-range", type=float, default=4000.0, metavar="M", help="ray length (default 4000 m)")
    p.add_argument("--neighbourhood", type=float, default=50.0, metavar="M",
                   help="side of the training neighbourhood (default 50 m)")
    p.add_argument("--frequencies", type=int, metavar="K", help="keep K frequencies (band limit; default all)")
    p.add_argument("--bounds", type=float, nargs=4, metavar=("W", "S", "E", "N"), help="cover only this area")
    p.add_argument("--tile-points", type=int, default=2**15, metavar="N",
                   help="grid points ray cast per tile (memory ~ N x bins x 4 bytes; default 32768)")
    p.add_argument("--float32", action="store_true", help="store float32 spectra (default float16)")
    p.add_argument("--overwrite", action="store_true", help="replace another bank in --out")
    p.add_argument("--device", default="cpu", help="torch device for ray casting and training (default cpu)")
    p.add_argument("--devices", type=int, default=1, metavar="N",
                   help="build on N processes (Lightning DDP: N GPUs with --device cuda, else N CPU processes)")


def run(args: argparse.Namespace) -> int:
    import time

    from data.horizon.metric_dem import load_metric_dem
    from models.distributed import is_primary_process
    from models.horizon.filter_bank import BankSettings, build_filter_bank

    if args.devices < 1:
        raise InputError(f"--devices must be at least 1, got {args.devices}")

    dem = load_metric_dem(args.dem, sea_level=args.sea_level)
    start = time.perf_counter()
    settings = BankSettings(spacing=args.spacing, bins=args.bins, camera_height=args.camera_height,
                            max_range=args.max_range, neighbourhood=args.neighbourhood,
                            frequencies=args.frequencies)
    bank = build_filter_bank(dem, settings, args.out, bounds=tuple(args.bounds) if args.bounds else None,
                             storage_dtype="float32" if args.float32 else "float16", tile_points=args.tile_points,
                             source=str(args.dem),
                             sea_level=args.sea_level, overwrite=args.overwrite, device=args.device,
                             devices=args.devices)
    if not is_primary_process():
        return 0
    print(f"wrote {args.out}: {len(bank)} locations, {bank.nbytes / 1e6:.1f} MB, "
          f"in {time.perf_counter() - start:.1f} s")
    return 0

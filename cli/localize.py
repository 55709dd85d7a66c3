"""``infer.py localize``: position and heading from panoramas or horizon profiles on a filter bank (thesis
ch. 4.4)."""

from __future__ import annotations

import argparse
from pathlib import Path

from core.errors import InputError

NAME = "localize"
HELP = "Position and heading from panoramas (networks) or horizon profiles on a filter bank."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--bank", type=Path, required=True, help="filter bank directory (build-bank)")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", type=Path, metavar="DIR", help="folder of tilted 360-degree panoramas")
    source.add_argument("--profiles", type=Path, metavar="FILE",
                        help=".npz with horizon (T, N) tan elevations [and compass_deg (T,)], or .npy (T, N)")
    p.add_argument("--compass", type=Path, metavar="CSV", help="compass headings: image,compass_deg (or compass_deg)")
    p.add_argument("--finder", type=Path, help="HorizonFinder checkpoint (default: newest demo training)")
    p.add_argument("--segmenter", type=Path, help="HorizonSegmenter checkpoint (default: newest demo training)")
    p.add_argument("--onnx", type=Path, metavar="DIR",
                   help="instead of the checkpoints and PyTorch: a horizon bundle (export.horizon_onnx), run by the "
                   "torch-free runtime (runtime.localize)")
    p.add_argument("--input-width", type=int, default=512, metavar="PX", help="network input width (default 512)")
    p.add_argument("--dem", type=Path, help="check that the bank was built for this DEM")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="sea level of --dem (m)")
    p.add_argument("--band-deg", type=float, default=4.0, help="peak search band around the compass (default 4)")
    p.add_argument("--drop-harmonics", type=int, default=0, metavar="H",
                   help="ignore the profiles' harmonics 1..H (1 removes the sinusoid of a levelling error)")
    p.add_argument("--out", type=Path, required=True, metavar="track.csv", help="estimated positions and headings")


def _networks(args: argparse.Namespace) -> tuple:
    """(finder, segmenter) from the given checkpoints, or the newest demo trainings."""
    from models.builders import demo_horizon_checkpoint, horizon_finder, horizon_segmenter

    finder = args.finder or demo_horizon_checkpoint("finder")
    segmenter = args.segmenter or demo_horizon_checkpoint("segmenter")
    if finder is None or segmenter is None:
        raise InputError("no HorizonFinder/HorizonSegmenter checkpoint: pass --finder and --segmenter "
                         "(or --onnx BUNDLE)")
    return horizon_finder(ckpt=finder), horizon_segmenter(ckpt=segmenter)


def run(args: argparse.Namespace) -> int:
    import time

    import numpy as np
    import torch

    from core.track_io import image_paths, read_compass_csv, read_profiles, write_track
    from data.horizon.bank_io import FilterBank
    from data.horizon.datamodule import read_full_panorama
    from models.horizon.localizer import HorizonLocalizer

    bank = FilterBank(args.bank)
    if args.dem:
        from data.horizon.metric_dem import load_metric_dem

        bank.check_dem(load_metric_dem(args.dem, sea_level=args.sea_level), f"DEM {args.dem}")
    if args.onnx:
        from runtime.localize import localize_files

        if args.finder or args.segmenter:
            raise InputError("give --onnx BUNDLE or the checkpoints --finder and --segmenter, not both")
        print(localize_files(args.onnx, args.bank, args.out, args.images, args.profiles, args.compass))
        return 0
    if args.profiles:
        localizer = HorizonLocalizer(bank, band_deg=args.band_deg, drop_harmonics=args.drop_harmonics)
        names, profiles, compass = read_profiles(args.profiles, args.compass)
        if profiles.shape[1] != bank.bins:
            raise InputError(f"profile file {args.profiles} has {profiles.shape[1]} azimuth bins per profile, the "
                             f"bank {args.bank} {bank.bins}")
        profile = torch.from_numpy(profiles).float()
    else:
        if args.compass is None:
            raise InputError("--images needs --compass CSV (image,compass_deg)")
        names, compass = read_compass_csv(args.compass, need_image=True)
        paths = image_paths(args.images, names)
        localizer = HorizonLocalizer(bank, *_networks(args), input_width=args.input_width, band_deg=args.band_deg,
                                     drop_harmonics=args.drop_harmonics)
        profile = localizer.image_profiles([read_full_panorama(p) for p in paths])
    start = time.perf_counter()
    result = localizer.from_profiles(profile, torch.from_numpy(np.asarray(compass)).float())
    seconds = time.perf_counter() - start
    write_track(args.out, names, result.xy, result.heading_deg, result.psr)
    print(f"localised {len(names)} frames on {len(bank)} locations in {seconds:.2f} s "
          f"({len(names) * len(bank) / seconds:.3g} locations/s); wrote {args.out}")
    return 0

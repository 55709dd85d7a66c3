"""``infer.py horizon``: the horizon networks on one panorama (thesis ch. 4.3): pitch and roll, levelling, the
horizon and water-line profiles."""

from __future__ import annotations

import argparse
from pathlib import Path

from core.errors import InputError

NAME = "horizon"
HELP = ("Horizon networks on one panorama: HorizonFinder pitch/roll, levelling, HorizonSegmenter horizon and "
        "water profiles.")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--image", type=Path, required=True, help="tilted 360-degree panorama (column 0 = forward)")
    p.add_argument("--finder", type=Path, help="HorizonFinder checkpoint")
    p.add_argument("--segmenter", type=Path, help="HorizonSegmenter checkpoint")
    p.add_argument("--onnx", type=Path, metavar="DIR", help="instead of the checkpoints: a horizon bundle, run by the "
                   "torch-free runtime (runtime.horizon)")
    p.add_argument("--input-width", type=int, default=512, metavar="PX",
                   help="network input width (the panorama is resized; default 512; a bundle has its own)")
    p.add_argument("--out", type=Path, metavar="FILE.npz", help="write pitch, roll and the per-column profiles")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    import math

    from core.command import print_report

    if args.onnx is not None:
        from runtime.horizon import horizon_file

        if args.finder or args.segmenter:
            raise InputError("give --onnx BUNDLE or the checkpoints --finder and --segmenter, not both")
        print_report(horizon_file(args.onnx, args.image, args.out), args.json)
        return 0
    if args.finder is None or args.segmenter is None:
        raise InputError("give --finder CKPT and --segmenter CKPT (or --onnx BUNDLE)")

    import numpy as np
    import torch

    from core.cylinder import tangent_to_row
    from core.files import write_npz
    from data.horizon.datamodule import read_full_panorama
    from models.builders import horizon_finder, horizon_segmenter
    from models.horizon.localizer import panorama_profiles

    image = read_full_panorama(args.image)
    finder, segmenter = horizon_finder(ckpt=args.finder), horizon_segmenter(ckpt=args.segmenter)
    profiles, pitch, roll = panorama_profiles(image, finder, segmenter, args.input_width)
    horizon, water = profiles[0].numpy().astype(np.float64)
    height, width = image.shape[-2:]
    report = {"pitch_deg": math.degrees(pitch.item()), "roll_deg": math.degrees(roll.item()),
              "horizon_row_median": float(np.median(tangent_to_row(torch.from_numpy(horizon), height, width))),
              "land_columns": int(np.sum(horizon - water > 2 * math.pi / width))}
    if args.out:
        write_npz(args.out, pitch=np.array(pitch.item()), roll=np.array(roll.item()), horizon=horizon, water=water)
    print_report(report, args.json)
    return 0

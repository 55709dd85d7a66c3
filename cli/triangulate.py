"""``infer.py triangulate``: optimal N-view triangulation of a reconstruction's tracks (thesis ch. 2)."""

from __future__ import annotations

import argparse
from pathlib import Path

from core.errors import InputError

NAME = "triangulate"
HELP = "Triangulate the tracks of a reconstruction and compare with its reference points."


def add_arguments(p: argparse.ArgumentParser) -> None:
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--bundler", type=Path, metavar="FILE", help="Bundler v0.3 .out reconstruction")
    source.add_argument("--bal", type=Path, metavar="FILE", help="BAL problem file")
    p.add_argument("--views", type=int, default=3, metavar="K",
                   help="triangulate tracks with at least K views from their first K views (default 3)")
    p.add_argument("--method", choices=("dogleg", "midpoint", "dlt", "polynomial"), default="dogleg")
    p.add_argument("--dtype", choices=("float64", "float32"), default="float64")
    p.add_argument("--onnx", type=Path, metavar="DIR", help="run the dogleg of this triangulation bundle in the "
                   "torch-free runtime (runtime.triangulation; float32) instead of PyTorch")
    p.add_argument("--out", type=Path, metavar="points.ply", help="write the triangulated points as PLY")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")


def run(args: argparse.Namespace) -> int:
    from core.command import print_report

    if args.views < 2:
        raise InputError(f"--views must be at least 2, got {args.views}")
    if args.onnx:
        from runtime.triangulation import triangulate_file

        if args.method != "dogleg":
            raise InputError(f"--onnx runs the exported dogleg; --method {args.method} has no graph")
        print_report(triangulate_file(args.onnx, args.bundler or args.bal, args.bal is not None, args.views,
                                      args.out), args.json)
        return 0
    import torch

    from data.sfm.bal import read_bal
    from data.sfm.bundler import read_bundler
    from data.sfm.ply import write_ply
    from models.geometry.evaluation import evaluate_reconstruction

    recon = read_bundler(args.bundler) if args.bundler else read_bal(args.bal)
    report, result, index = evaluate_reconstruction(recon, args.views, args.method, getattr(torch, args.dtype))
    if args.out:
        write_ply(args.out, result.points[result.valid], recon.colors[index][result.valid])
    print_report(report, args.json)
    return 0

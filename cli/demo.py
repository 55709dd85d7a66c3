"""``infer.py demo``: every capability on the project's own synthetic data (``make demo``)."""

from __future__ import annotations

import argparse

NAME = "demo"
HELP = "Run every capability on the project's own synthetic data and print the results."

#: Demo parts and the benchmark module whose ``demo()`` runs each.
DEMOS = {"triangulation": "bench.triangulation", "point_tracking": "bench.point_tracking",
         "horizon_labels": "bench.horizon_labels", "horizon_networks": "bench.horizon_networks",
         "localization": "bench.localization", "vos": "bench.vos"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--only", nargs="+", choices=tuple(DEMOS), help="run only these parts (default: all)")


def run(args: argparse.Namespace) -> int:
    import importlib
    import time

    for name in args.only or DEMOS:
        start = time.perf_counter()
        print(f"\n=== {name} " + "=" * (70 - len(name)))
        importlib.import_module(DEMOS[name]).demo()
        print(f"({name}: {time.perf_counter() - start:.0f} s)")
    return 0

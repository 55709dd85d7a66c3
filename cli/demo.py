"""``infer.py demo``: every capability on the project's own synthetic data (``make demo``), with a report."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "demo"
HELP = "Run every capability on the project's own synthetic data, print the results and write an HTML report."

#: Demo parts: (benchmark module whose ``demo(report_dir, quick)`` runs it, title in the report).
DEMOS = {"triangulation": ("bench.triangulation", "Triangulation (thesis ch. 2)"),
         "point_tracking": ("bench.point_tracking", "Point tracking: correlation filters vs KLT (ch. 3)"),
         "point_tracking_speed": ("bench.point_tracking_scaling", "Point tracking: speed against the number of "
                                  "points (ch. 3)"),
         "horizon_labels": ("bench.horizon_labels", "Horizon labels: the classical pipeline (ch. 4.2)"),
         "horizon_networks": ("bench.horizon_networks", "Horizon networks (ch. 4.3)"),
         "localization": ("bench.localization", "Localisation on a filter bank (ch. 4.4)"),
         "vos": ("bench.vos", "Video object segmentation: FRTM (ch. 5)"),
         "davos": ("bench.davos_demo", "Distractor-aware video object segmentation: DAVOS (ch. 6)")}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--only", nargs="+", choices=tuple(DEMOS), help="run only these parts (default: all)")
    p.add_argument("--quick", action="store_true", help="a smoke run of about a minute (smaller sizes)")
    p.add_argument("--out", type=Path, default=Path("outputs/demo"), help="report folder (default outputs/demo)")


class _Tee:
    """A stdout that also keeps what is written."""

    def __init__(self, stream) -> None:
        self.stream, self.parts = stream, []

    def write(self, text: str) -> int:
        self.parts.append(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


def run(args: argparse.Namespace) -> int:
    import contextlib
    import importlib
    import sys
    import time

    from bench.report import DemoPart, write_report
    from core.files import writable_folder

    out = writable_folder(args.out)
    parts, begin = [], time.perf_counter()
    for name in args.only or DEMOS:
        module, title = DEMOS[name]
        start = time.perf_counter()
        print(f"\n=== {name} " + "=" * (70 - len(name)))
        tee = _Tee(sys.stdout)
        with contextlib.redirect_stdout(tee):
            figures = importlib.import_module(module).demo(out, args.quick)
        seconds = time.perf_counter() - start
        print(f"({name}: {seconds:.0f} s)")
        parts.append(DemoPart(name, title, seconds, "".join(tee.parts), figures))
    report = write_report(out, parts, time.perf_counter() - begin)
    print(f"\nreport: {report} (open it in a browser)")
    return 0

"""Printing a command's flat report as aligned ``key: value`` lines or as one JSON object."""

from __future__ import annotations

import json


def print_report(report: dict, as_json: bool) -> None:
    """Print ``report`` as one JSON object (``as_json``), else as right-aligned ``key: value`` lines."""
    if as_json:
        print(json.dumps(report))
        return
    width = max(map(len, report))
    for key, value in report.items():
        print(f"{key:>{width}}: {value:.6g}" if isinstance(value, float) else f"{key:>{width}}: {value}")

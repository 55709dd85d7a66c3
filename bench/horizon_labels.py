"""Accuracy of the classical horizon pipeline (the label maker, ch. 4.2) against the renderer's ground truth.

    python -m bench.horizon_labels --data DIR [DIR ...] [--json] [--plot labels.png]

Each DIR is a dataset written by ``python infer.py render-dataset``. For every dataset: the share of fits the
pipeline rejects, errors of the accepted fits (pitch, roll, heading in degrees; horizon and water profile in
pixels of the levelled panorama), and the failure rate = rejected or accepted but wrong (pitch or roll off by
more than 0.5 deg, heading by more than 1 deg, or a median horizon error above 2 px).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np

FAIL_TILT_DEG, FAIL_HEADING_DEG, FAIL_PROFILE_PX = 0.5, 1.0, 2.0


def label_errors(labels: dict[str, np.ndarray], truth: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-frame absolute errors of classical labels against ground truth (degrees and px)."""
    heading = np.degrees(np.abs((labels["heading"] - truth["heading"] + math.pi) % (2 * math.pi) - math.pi))
    return {
        "pitch_deg": np.degrees(np.abs(labels["pitch"] - truth["pitch"])),
        "roll_deg": np.degrees(np.abs(labels["roll"] - truth["roll"])),
        "heading_deg": heading,
        "horizon_px": np.median(np.abs(labels["horizon_rows"] - truth["level_horizon_rows"]), axis=1),
        "water_px": np.median(np.abs(labels["water_rows"] - truth["level_water_rows"]), axis=1),
    }


def failed(errors: dict[str, np.ndarray], ok: np.ndarray) -> np.ndarray:
    """Frames that are rejected or accepted with a wrong pose or profile."""
    wrong = ((errors["pitch_deg"] > FAIL_TILT_DEG) | (errors["roll_deg"] > FAIL_TILT_DEG)
             | (errors["heading_deg"] > FAIL_HEADING_DEG) | (errors["horizon_px"] > FAIL_PROFILE_PX))
    return ~ok | wrong


def evaluate(root: str | Path) -> dict[str, float]:
    """Summary of one dataset directory."""
    from data.horizon.dataset import read_split

    labels, truth = read_split(root, "labels"), read_split(root, "truth")
    errors = label_errors(labels, truth)
    ok = labels["ok"].astype(bool)
    width = labels["horizon_rows"].shape[1]
    report: dict[str, float] = {"frames": int(len(ok)), "width": int(width), "rejected": float(np.mean(~ok)),
                                "failure_rate": float(np.mean(failed(errors, ok)))}
    if ok.any():
        for key, values in errors.items():
            report[f"{key}_median"] = float(np.median(values[ok]))
            report[f"{key}_p95"] = float(np.percentile(values[ok], 95))
        all_columns = np.abs(labels["horizon_rows"] - truth["level_horizon_rows"])[ok]
        report["horizon_px_all_columns_median"] = float(np.median(all_columns))
        report["horizon_mrad_median"] = float(np.median(all_columns) / (width / (2 * math.pi)) * 1e3)
    return report


def print_table(reports: dict[str, dict[str, float]]) -> None:
    keys = sorted({k for r in reports.values() for k in r})
    print(f"{'':>30}" + "".join(f"{name[-18:]:>20}" for name in reports))
    for key in keys:
        cells = "".join(f"{r.get(key, float('nan')):>20.4g}" for r in reports.values())
        print(f"{key:>30}{cells}")


def plot(reports_errors: dict[str, dict[str, np.ndarray]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for name, errors in reports_errors.items():
        for ax, key in zip(axes, ("pitch_deg", "heading_deg", "horizon_px"), strict=True):
            values = np.sort(errors[key])
            ax.plot(values, np.arange(1, len(values) + 1) / len(values), label=Path(name).name)
            ax.set_xscale("log")
            ax.set_xlabel(key.replace("_", " "))
    axes[0].set_ylabel("share of frames")
    axes[0].legend()
    fig.suptitle("classical horizon pipeline vs ground truth (cumulative error)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def plot_panoramas(roots: dict[str, Path], path: Path, frame: int = 0) -> None:
    """Frame ``frame`` of each dataset with the ground-truth horizon and the classical pipeline's (rows)."""
    import cv2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from data.horizon.dataset import read_split

    fig, axes = plt.subplots(len(roots), 1, figsize=(12, 1.9 * len(roots)), squeeze=False)
    for ax, (name, root) in zip(axes[:, 0], roots.items(), strict=True):
        image = cv2.cvtColor(cv2.imread(str(root / "images" / f"{frame:06d}.png")), cv2.COLOR_BGR2RGB)
        truth, labels = read_split(root, "truth"), read_split(root, "labels")
        ax.imshow(image)
        ax.plot(truth["horizon_rows"][frame], color="lime", lw=1.2, label="ground truth")
        verdict = "accepted" if labels["ok"][frame] else "rejected"
        ax.plot(labels["horizon_rows"][frame], color="red", lw=0.9, ls="--", label=f"classical ({verdict})")
        ax.set_title(f"{name} panorama", fontsize=9, loc="left")
        ax.set_axis_off()
        ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Small version: 6 clean and 6 degraded 1024 px panoramas (3 of 512 px quick) on a 6 km archipelago. With
    ``report_dir``, writes the error curves and two labelled panoramas there; returns the figures."""
    from data.horizon.dataset import DatasetSettings, read_split, write_dataset
    from data.world.dem import generate_archipelago

    dem = generate_archipelago(size_m=6000, cell=10, seed=0)
    reports, figures = {}, []
    width = 512 if quick else 1024
    with tempfile.TemporaryDirectory() as tmp:
        roots = {name: Path(tmp) / name for name in ("clean", "degraded")}
        for name, fraction in (("clean", 0.0), ("degraded", 1.0)):
            settings = DatasetSettings(count=3 if quick else 6, width=width, height=width // 8,
                                       degraded_fraction=fraction, render_bins=2 * width, label_bins=width,
                                       max_range_m=4000.0, seed=3)
            write_dataset(roots[name], dem, settings, progress=False)
            reports[name] = evaluate(roots[name])
        print_table(reports)
        if report_dir is not None:
            plot_panoramas(roots, report_dir / "horizon_panoramas.png")
            plot({name: label_errors(read_split(r, "labels"), read_split(r, "truth")) for name, r in roots.items()},
                 report_dir / "horizon_labels.png")
            figures = [("horizon_panoramas.png", "A clean and a degraded (haze, noise, blur, glare) rendered panorama "
                        "with the ground-truth horizon and the classical pipeline's fit"),
                       ("horizon_labels.png", "Cumulative errors of the classical labels against the ground truth")]
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, nargs="+", required=True, help="dataset directories")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", type=Path, help="write cumulative error curves to this PNG")
    args = parser.parse_args()
    from data.horizon.dataset import read_split

    reports = {str(d): evaluate(d) for d in args.data}
    if args.json:
        print(json.dumps(reports))
    else:
        print_table(reports)
    if args.plot:
        plot({str(d): label_errors(read_split(d, "labels"), read_split(d, "truth")) for d in args.data}, args.plot)


if __name__ == "__main__":
    main()

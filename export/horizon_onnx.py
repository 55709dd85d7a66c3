"""Export the horizon bundle (``runtime.horizon``, ``runtime.localize``): HorizonFinder, the levelling warp,
HorizonSegmenter and the filter-bank matcher.

    python -m export.horizon_onnx --finder F.ckpt --segmenter S.ckpt --out DIR [--height 64 --width 512]
        [--input-width 512] [--bank BANK | --bins 1024 --frequencies K --threshold-deg 1] [--band-deg 4]
        [--exclude 11] [--drop-harmonics 0] [--workers N] [--check] [--int8 [--calibration 32]]

Graphs (dynamo, opset 20; batch and width dynamic, heights fixed by ``--height`` and ``--width``, the panoramas'
size, and ``--input-width``, the networks' input width; widths must stay multiples of the backbone stride):

- ``finder.onnx``: ``image`` (B, 3, h, w) tilted panorama resized to the input width -> ``sincos`` (B, 4) =
  (sin p, cos p, sin q, cos q).
- ``level.onnx``: ``image`` (B, 3, H, W) panorama, ``pitch`` (B,), ``roll`` (B,) rad -> ``level`` (B, 3, H, W).
- ``segmenter.onnx``: ``image`` (B, 3, h, w) levelled panorama -> ``profiles`` (B, 2, w) tan elevation of the
  horizon and the water line.
- ``matcher.onnx``: bank block ``filters`` (L, 2K), ``profile`` (B, N), ``heading_deg`` (B,) -> ``psr`` and
  ``heading`` (B, L) (``export.localization_onnx``); N, K and the normalisation threshold come from ``--bank``
  (or ``--bins``, ``--frequencies``, ``--threshold-deg``) and must be those of the banks it is used with.

The graphs export side by side, one process each (``--workers``, default one per core; 1: in this process).
``--check`` compares the chain in onnxruntime with PyTorch on rendered panoramas of the bundle's size (pitch and
roll in degrees, profiles in px). ``--int8`` replaces the finder and the segmenter by static int8 QDQ versions
calibrated on ``--calibration`` rendered panoramas (``export.int8``) and stores an accuracy report in the
manifest: median pitch, roll and horizon errors against the renderer's ground truth on other rendered panoramas,
float32 against int8, with each graph's size and speed.
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import torch
from torch import nn

from core.bank_reader import BankReader
from core.command import CommandParser, run_command
from core.errors import InputError
from core.files import writable_folder
from export.bundle import staged_bundle
from export.int8 import RecordingGraph, quantize_bundle_graphs
from export.localization_onnx import export_matcher
from export.onnx import OPSET, export_onnx
from export.pool import GraphJob, export_jobs
from models.builders import horizon_network
from runtime.bundle import Bundle, write_manifest
from runtime.horizon import HorizonChain, read_panorama

SPECS = {
    "finder": (("image",), ("sincos",)),
    "segmenter": (("image",), ("profiles",)),
    "level": (("image", "pitch", "roll"), ("level",)),
}


def example_inputs(which: str, height: int, width: int, batch: int = 2, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """Random inputs of the right shapes (tilts of a few degrees for ``level``)."""
    gen = torch.Generator().manual_seed(seed)
    image = torch.rand(batch, 3, height, width, generator=gen)
    if which == "level":
        return image, torch.randn(batch, generator=gen) * 0.05, torch.randn(batch, generator=gen) * 0.05
    return (image,)


def export_horizon(which: str, model: nn.Module, path: str | Path, height: int = 64, width: int = 512) -> Path:
    """Export ``model`` (``models.builders.horizon_network``) with dynamic batch and width; returns the path."""
    stride = 1 if which == "level" else model.backbone.strides[model.stage]
    if width % stride or height % stride:
        raise InputError(f"height and width must be multiples of the backbone stride {stride}, got {height}x{width}")
    inputs = example_inputs(which, height, width)
    batch = torch.export.Dim("batch", min=1, max=64)
    columns = stride * torch.export.Dim("columns", min=max(2, 64 // stride), max=16384 // stride)
    shapes: list = [{0: batch, 3: columns}] + [{0: batch}] * (len(inputs) - 1)
    names_in, names_out = SPECS[which]
    return export_onnx(model, inputs, path, names_in, names_out, dynamic_shapes=tuple(shapes))


def render_panoramas(folder: Path, count: int, height: int, width: int, seed: int) -> tuple[np.ndarray, dict]:
    """``count`` panoramas of ``height`` x ``width`` rendered over a generated archipelago into ``folder``
    (``data.horizon.dataset``, a fifth of them degraded), read back as the runtime reads them: (N, 3, H, W)
    float32 and the renderer's ground truth."""
    from data.horizon.dataset import DatasetSettings, read_split, write_dataset
    from data.world.dem import generate_archipelago

    dem = generate_archipelago(size_m=3000.0, cell=10.0, seed=seed, feature_scale_m=600.0)
    settings = DatasetSettings(count=count, width=width, height=height, frames_per_track=4,
                               degraded_fraction=0.2, render_bins=2 * width, label_bins=width,
                               max_range_m=3000.0, seed=seed)
    write_dataset(folder, dem, settings, progress=False)
    truth = read_split(folder, "truth")
    images = np.concatenate([read_panorama(folder / "images" / f"{k:06d}.png") for k in range(len(truth["pitch"]))])
    return images, truth


def chain_errors(chain: HorizonChain, images: np.ndarray, truth: dict) -> dict[str, float]:
    """Median |pitch|, |roll| errors (deg) and median per-panorama horizon error (px of the panorama) of the
    chain against the ground truth."""
    out = [chain(images[i : i + 8]) for i in range(0, len(images), 8)]
    profiles = np.concatenate([o[0] for o in out])[:, 0]
    pitch, roll = np.concatenate([o[1] for o in out]), np.concatenate([o[2] for o in out])
    focal = images.shape[-1] / (2 * math.pi)
    return {"pitch_deg_median": float(np.degrees(np.median(np.abs(pitch - truth["pitch"])))),
            "roll_deg_median": float(np.degrees(np.median(np.abs(roll - truth["roll"])))),
            "horizon_px_median": float(np.median(np.median(np.abs(profiles - truth["horizon"]), 1)) * focal)}


def parity(chain: HorizonChain, finder: nn.Module, segmenter: nn.Module, images: np.ndarray) -> dict[str, float]:
    """Largest differences of the onnxruntime chain from the PyTorch chain (``models.horizon.localizer
    .panorama_profiles``) on ``images``: pitch and roll in degrees, profiles in px of the panorama."""
    from models.horizon.localizer import panorama_profiles

    profiles, pitch, roll = chain(images)
    with torch.no_grad():
        ref, ref_pitch, ref_roll = panorama_profiles(torch.from_numpy(images), finder, segmenter, chain.input_width)
    focal = images.shape[-1] / (2 * math.pi)
    return {"angle_deg_max": float(np.degrees(max(np.abs(pitch - ref_pitch.numpy()).max(),
                                                  np.abs(roll - ref_roll.numpy()).max()))),
            "profile_px_max": float(np.abs(profiles - ref.numpy()).max() * focal)}


def export_bundle(
    out: str | Path, finder: nn.Module, segmenter: nn.Module, height: int = 64, width: int = 512,
    input_width: int = 512, bins: int = 1024, frequencies: int | None = None, threshold_deg: float = 1.0,
    band_deg: float = 4.0, exclude: int = 11, drop_harmonics: int = 0, int8: bool = False, calibration: int = 32,
    check: bool = False, workers: int | None = None,
) -> dict:
    """Write the horizon bundle of the networks ``finder`` (``horizon_finder``) and ``segmenter``
    (``horizon_segmenter``) for panoramas of ``height`` x ``width`` and banks of ``bins`` bins, ``frequencies``
    stored frequencies and ``threshold_deg``, its graphs exported by ``workers`` processes at once
    (:func:`export.pool.export_jobs`; default one per core); returns the ``--check`` parity and the int8 report
    (empty without)."""
    if width < 2 * height or input_width % 32 or input_width < 64:
        raise InputError(f"panoramas must be at least twice as wide as high ({width} x {height}) and --input-width a "
                         f"multiple of 32 of at least 64 ({input_width})")
    input_height = max(int(round(height * input_width / width)), 8)
    frequencies = frequencies or bins // 2 + 1
    if not 2 <= frequencies <= bins // 2 + 1:  # before anything is exported
        raise InputError(f"--frequencies must be in [2, {bins // 2 + 1}], got {frequencies}")
    report: dict = {}
    with staged_bundle(out) as folder, tempfile.TemporaryDirectory() as tmp:
        jobs = [GraphJob(f"{which}.onnx", export_horizon, (which, model, folder / f"{which}.onnx", h, w))
                for which, model, h, w in (("finder", finder, input_height, input_width),
                                           ("segmenter", segmenter, input_height, input_width),
                                           ("level", horizon_network("level"), height, width))]
        jobs.append(GraphJob("matcher.onnx", export_matcher, (folder / "matcher.onnx", bins, frequencies, band_deg,
                                                              exclude, threshold_deg, drop_harmonics)))
        export_jobs("export.horizon_onnx", jobs, workers)
        sections = {
            "input": {"image": "(B, 3, H, W) RGB float32 in [0, 1], 360 degrees, column 0 forward",
                      "panorama_height": height, "input_width": input_width, "input_height": input_height,
                      "stride": finder.backbone.strides[finder.stage], "resize": "area"},
            "normalisation": {"scale": 1 / 255, "order": "RGB"},
            "thresholds": {"band_deg": band_deg, "psr_exclude_bins": exclude},
            "settings": {"matcher": {"bins": bins, "half_spectrum": frequencies, "norm_threshold_deg": threshold_deg,
                                     "drop_harmonics": drop_harmonics}},
        }
        write_manifest(folder, "horizon", OPSET, **sections)
        if check or int8:
            images, truth = render_panoramas(Path(tmp) / "held_out", max(8, calibration // 2), height, width, seed=1)
        if check:
            report["check"] = parity(HorizonChain(folder), finder, segmenter, images)
        if int8:
            fp32 = Path(tmp) / "fp32"
            shutil.copytree(folder, fp32)
            calib, _ = render_panoramas(Path(tmp) / "calibration", calibration, height, width, seed=2)
            chain = HorizonChain(fp32)
            recorded = {"finder": RecordingGraph(chain.finder), "segmenter": RecordingGraph(chain.segmenter)}
            chain.finder, chain.segmenter = recorded["finder"], recorded["segmenter"]
            for i in range(0, len(calib), 4):
                chain(calib[i : i + 4])
            graphs = quantize_bundle_graphs(folder, recorded)
            write_manifest(folder, "horizon", OPSET, precision="int8", **sections)
            accuracy = {"float32": chain_errors(HorizonChain(fp32), images, truth),
                        "int8": chain_errors(HorizonChain(folder), images, truth), "panoramas": len(images)}
            report["int8"] = {"graphs": graphs, "accuracy": accuracy}
            write_manifest(folder, "horizon", OPSET, precision="int8", **sections, int8=report["int8"])
    return report


def matcher_settings(bank: Path | None, bins: int, frequencies: int | None, threshold_deg: float) -> tuple:
    """(bins, stored frequencies, normalisation threshold) of ``bank`` if given, else the arguments."""
    if bank is None:
        return bins, frequencies, threshold_deg
    reader = BankReader(bank)
    return reader.bins, reader.half_spectrum, float(reader.settings["norm_threshold_deg"])


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="export.horizon_onnx", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--finder", type=Path, required=True, help="HorizonFinderSystem checkpoint")
    parser.add_argument("--segmenter", type=Path, required=True, help="HorizonSegmenterSystem checkpoint")
    parser.add_argument("--out", type=Path, required=True, help="bundle folder to write")
    parser.add_argument("--height", type=int, default=64, help="panorama height in px (default 64)")
    parser.add_argument("--width", type=int, default=512, help="panorama width in px (default 512)")
    parser.add_argument("--input-width", type=int, default=512, help="network input width (default 512)")
    parser.add_argument("--bank", type=Path, help="take the matcher's bins, frequencies and threshold from this bank")
    parser.add_argument("--bins", type=int, default=1024, help="azimuth bins of the banks (default 1024)")
    parser.add_argument("--frequencies", type=int, default=None, help="stored half-spectrum length K (default all)")
    parser.add_argument("--threshold-deg", type=float, default=1.0, help="profile normalisation threshold")
    parser.add_argument("--band-deg", type=float, default=4.0, help="heading search band around the compass")
    parser.add_argument("--exclude", type=int, default=11, help="PSR exclusion window, bins")
    parser.add_argument("--drop-harmonics", type=int, default=0, help="ignore the profiles' harmonics 1..H")
    parser.add_argument("--workers", type=int, default=None,
                        help="graphs exported at once, one process each (default: one per core)")
    parser.add_argument("--check", action="store_true", help="compare onnxruntime with PyTorch on rendered panoramas")
    parser.add_argument("--int8", action="store_true", help="int8 finder and segmenter, with an accuracy report")
    parser.add_argument("--calibration", type=int, default=32, help="rendered panoramas to calibrate int8 on")
    args = parser.parse_args(argv)

    def run() -> None:
        writable_folder(args.out.parent)  # an unwritable output fails before the networks load
        finder, segmenter = horizon_network("finder", args.finder), horizon_network("segmenter", args.segmenter)
        bins, frequencies, threshold = matcher_settings(args.bank, args.bins, args.frequencies, args.threshold_deg)
        report = export_bundle(args.out, finder, segmenter, args.height, args.width, args.input_width, bins,
                               frequencies, threshold, args.band_deg, args.exclude, args.drop_harmonics, args.int8,
                               args.calibration, args.check, args.workers)
        print(f"wrote {args.out} (model {Bundle(args.out, 'horizon').manifest['model_hash'][:12]})")
        if "check" in report:
            c = report["check"]
            print(f"onnxruntime vs PyTorch on rendered panoramas: pitch/roll {c['angle_deg_max']:.2e} deg, profiles "
                  f"{c['profile_px_max']:.2e} px (largest differences)")
        for name, g in report.get("int8", {}).get("graphs", {}).items():
            print(f"int8 {name}: {g['fp32_bytes'] / 1e6:.2f} -> {g['int8_bytes'] / 1e6:.2f} MB, {g['fp32_ms']:.1f} -> "
                  f"{g['int8_ms']:.1f} ms per call (1 thread)")
        for precision, a in report.get("int8", {}).get("accuracy", {}).items():
            if isinstance(a, dict):
                print(f"{precision:>7}: median |pitch| {a['pitch_deg_median']:.3f} deg, |roll| "
                      f"{a['roll_deg_median']:.3f} deg, horizon {a['horizon_px_median']:.3f} px")

    return run_command("export.horizon_onnx", run)


if __name__ == "__main__":
    raise SystemExit(main())

"""dcfvision inference command line: one subcommand per capability.

Run ``python infer.py --help`` for the list and ``python infer.py COMMAND --help`` for each one.
Bad arguments and bad input files end with a one-line message and exit code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from data.errors import InputError


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> None:  # noqa: D102
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


Command = tuple[str, str, Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int]]
COMMANDS: list[Command] = []


def command(name: str, help_text: str, add_arguments: Callable[[argparse.ArgumentParser], None]):
    """Register ``run(args) -> exit code`` as subcommand ``name``."""

    def register(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        COMMANDS.append((name, help_text, add_arguments, run))
        return run

    return register


def print_report(report: dict, as_json: bool) -> None:
    """Print a flat report as one JSON object, or as aligned ``key: value`` lines."""
    if as_json:
        print(json.dumps(report))
        return
    width = max(map(len, report))
    for key, value in report.items():
        print(f"{key:>{width}}: {value:.6g}" if isinstance(value, float) else f"{key:>{width}}: {value}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="infer.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND")
    for name, help_text, add_arguments, run in COMMANDS:
        p = sub.add_parser(name, help=help_text, description=help_text)
        add_arguments(p)
        p.set_defaults(run=run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (InputError, FileNotFoundError) as err:
        sys.stderr.write(f"infer.py {args.command}: error: {err}\n")
        return 2


# --- triangulate (thesis chapter 2) ----------------------------------------------------------------------------


def _triangulate_arguments(p: argparse.ArgumentParser) -> None:
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--bundler", type=Path, metavar="FILE", help="Bundler v0.3 .out reconstruction")
    source.add_argument("--bal", type=Path, metavar="FILE", help="BAL problem file")
    p.add_argument("--views", type=int, default=3, metavar="K",
                   help="triangulate tracks with at least K views from their first K views (default 3)")
    p.add_argument("--method", choices=("dogleg", "midpoint", "dlt", "polynomial"), default="dogleg")
    p.add_argument("--dtype", choices=("float64", "float32"), default="float64")
    p.add_argument("--out", type=Path, metavar="points.ply", help="write the triangulated points as PLY")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")


@command("triangulate", "Triangulate the tracks of a reconstruction and compare with its reference points.",
         _triangulate_arguments)
def _triangulate(args: argparse.Namespace) -> int:
    import torch

    from data.sfm.bal import read_bal
    from data.sfm.bundler import read_bundler
    from data.sfm.evaluation import evaluate_reconstruction
    from data.sfm.ply import write_ply

    if args.views < 2:
        raise InputError(f"--views must be at least 2, got {args.views}")
    recon = read_bundler(args.bundler) if args.bundler else read_bal(args.bal)
    report, result, index = evaluate_reconstruction(recon, args.views, args.method, getattr(torch, args.dtype))
    if args.out:
        write_ply(args.out, result.points[result.valid], recon.colors[index][result.valid])
    print_report(report, args.json)
    return 0

# --- render-dataset (thesis chapter 4.2) ------------------------------------------------------------------------


def _render_dataset_arguments(p: argparse.ArgumentParser) -> None:
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


@command("render-dataset", "Render panoramas along boat trajectories, label them with the classical pipeline "
         "and write images, labels and ground truth.", _render_dataset_arguments)
def _render_dataset(args: argparse.Namespace) -> int:
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


def _read_panorama_arg(path: Path, min_width: int = 64):
    """(1, 3, H, W) panorama of ``--image``, checked to look like a 360-degree cylinder."""
    from data.horizon.datamodule import read_panorama

    image = read_panorama(path)
    height, width = image.shape[-2:]
    if width < min_width or height < 16 or width < 2 * height:
        raise InputError(f"{path}: a 360-degree panorama must be at least {min_width} x 16 px and at least twice "
                         f"as wide as high, got {width} x {height}")
    return image[None]


def _horizon_label_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--image", type=Path, required=True, help="tilted 360-degree panorama (column 0 = forward)")
    p.add_argument("--dem", type=Path, required=True, help="GeoTIFF or .npz DEM")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood the DEM at this level (m)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--position", type=float, nargs=2, metavar=("X", "Y"), help="GPS in DEM map metres")
    where.add_argument("--lonlat", type=float, nargs=2, metavar=("LON", "LAT"),
                       help="GPS in WGS84 degrees (needs a DEM with a CRS)")
    p.add_argument("--camera-height", type=float, default=2.0, metavar="M", help="above the sea (m)")
    p.add_argument("--compass", type=float, required=True, metavar="DEG", help="compass heading of column 0")
    p.add_argument("--max-range", type=float, default=8000.0, metavar="M", help="ray length (m)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


@command("horizon-label", "Classical horizon pipeline (Canny + Hough + eq. 4.1 against the DEM) on one panorama.",
         _horizon_label_arguments)
def _horizon_label(args: argparse.Namespace) -> int:
    import math

    import numpy as np
    import torch

    from data.horizon.classical import ClassicalHorizon
    from data.world.dem import load_dem
    from data.world.raycast import VirtualHorizon

    image = _read_panorama_arg(args.image)
    dem = load_dem(args.dem, sea_level=args.sea_level, require_crs=args.lonlat is not None)
    xy = dem.from_lonlat(np.array(args.lonlat)) if args.lonlat else np.array(args.position, dtype=np.float64)
    dem.check_positions(xy, "--position" if args.position else "--lonlat")
    width = image.shape[-1]
    labeller = ClassicalHorizon(VirtualHorizon(dem, bins=width, max_range=args.max_range, step=dem.cell))
    labels = labeller(image, torch.tensor(xy)[None], torch.tensor([args.camera_height], dtype=torch.float64),
                      torch.tensor([math.radians(args.compass)], dtype=torch.float64))
    report = {"pitch_deg": math.degrees(labels.pitch.item()), "roll_deg": math.degrees(labels.roll.item()),
              "heading_deg": math.degrees(labels.heading.item()), "quality": labels.quality.item(),
              "ok": bool(labels.ok.item())}
    print_report(report, args.json)
    return 0 if report["ok"] else 1


def _horizon_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--image", type=Path, required=True, help="tilted 360-degree panorama (column 0 = forward)")
    p.add_argument("--finder", type=Path, required=True, help="HorizonFinder checkpoint (.ckpt) or ONNX graph")
    p.add_argument("--segmenter", type=Path, required=True, help="HorizonSegmenter checkpoint or ONNX graph")
    p.add_argument("--input-width", type=int, default=512, metavar="PX",
                   help="network input width (the panorama is resized; default 512)")
    p.add_argument("--out", type=Path, metavar="FILE.npz", help="write pitch, roll and the per-column profiles")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _horizon_network(path: Path, which: str):
    """Callable image -> output tensor of a checkpoint (PyTorch) or an ONNX graph (onnxruntime)."""
    import torch

    if not path.is_file():
        raise InputError(f"{which} model not found: {path}")
    if path.suffix.lower() == ".onnx":
        from export.onnx import onnx_session, run_onnx

        session = onnx_session(path)
        return lambda image: torch.from_numpy(run_onnx(session, image)[0])
    from export.horizon_onnx import load_network

    net = load_network(which, path)
    return lambda image: net(image).detach()


@command("horizon", "Horizon networks on one panorama: HorizonFinder pitch/roll, levelling, HorizonSegmenter "
         "horizon and water profiles.", _horizon_arguments)
def _horizon(args: argparse.Namespace) -> int:
    import math

    import numpy as np
    import torch

    from data.horizon.datamodule import resize_panorama
    from models.horizon.cylinder import tangent_to_row, warp_panorama
    from models.horizon.finder import sincos_to_angles

    if args.input_width < 64 or args.input_width % 32:
        raise InputError(f"--input-width must be a multiple of 32 and >= 64, got {args.input_width}")
    image = _read_panorama_arg(args.image)
    finder = _horizon_network(args.finder, "finder")
    segmenter = _horizon_network(args.segmenter, "segmenter")
    with torch.no_grad():
        pitch, roll = sincos_to_angles(finder(resize_panorama(image, args.input_width)))
        level = warp_panorama(image, pitch, roll)
        profiles = segmenter(resize_panorama(level, args.input_width))  # tan elevation
    height, width = image.shape[-2:]
    profiles = torch.nn.functional.interpolate(profiles, size=width, mode="linear", align_corners=False)[0]
    horizon, water = profiles.numpy().astype(np.float64)
    report = {"pitch_deg": math.degrees(pitch.item()), "roll_deg": math.degrees(roll.item()),
              "horizon_row_median": float(np.median(tangent_to_row(torch.from_numpy(horizon), height, width))),
              "land_columns": int(np.sum(horizon - water > 2 * math.pi / width))}
    if args.out:
        np.savez(args.out, pitch=pitch.item(), roll=roll.item(), horizon=horizon, water=water)
    print_report(report, args.json)
    return 0

# --- track ------------------------------------------------------------------------------------------------------


def _track_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", required=True, help="folder of frames (sorted by name) or a glob like 'clip/*.png'")
    start = p.add_mutually_exclusive_group(required=True)
    start.add_argument("--points", help="start points in the first frame: .npy/.npz (P, 2) or text 'x y' lines")
    start.add_argument("--detect", type=int, help="detect this many good features to track in the first frame")
    p.add_argument("--method", default="ccot", choices=("ccot", "ccot_ff", "mosse", "klt"),
                   help="DCF variant, or klt = OpenCV pyramidal Lucas-Kanade (default: ccot)")
    p.add_argument("--out", required=True, help="output .npz with tracks (T, P, 2), lost (T, P), psr (T, P)")
    p.add_argument("--video", help="also write an overlay video (.mp4)")
    p.add_argument("--device", default="cpu", help="torch device for the DCF methods (default: cpu)")
    p.add_argument("--threads", type=int, default=1,
                   help="CPU threads for torch and OpenCV (default 1: fastest for many small filters)")
    p.add_argument("--compile", action="store_true",
                   help="run the DCF step through torch.compile: faster per frame, about a minute to compile")


@command("track", "Track points through gray frames with correlation filters (or KLT) and save the tracks.",
         _track_arguments)
def _track(args: argparse.Namespace) -> int:
    import numpy as np

    from data.flow.frames import read_frames, read_points
    from models.tracking.overlay import write_overlay_video
    from models.tracking.run import cpu_threads, track_points

    frames, paths = read_frames(args.frames)
    points = read_points(args.points) if args.points else None
    start = time.perf_counter()
    with cpu_threads(args.threads):
        result = track_points(frames, points, args.detect, args.method, args.device, progress=True,
                              compile=args.compile)
    seconds = time.perf_counter() - start
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    np.savez(args.out, method=args.method, frames=np.array([str(p) for p in paths]), **result)
    if args.video:
        write_overlay_video(args.video, frames, result["tracks"], result["lost"])
    n_frames, n_points = result["lost"].shape
    lost = int(result["lost"][-1].sum())
    print(f"{args.method}: {n_points} points through {n_frames} frames in {seconds:.1f} s "
          f"({n_points * max(n_frames - 1, 1) / seconds:.0f} point-frames/s), {lost} lost at the end; "
          f"wrote {args.out}" + (f" and {args.video}" if args.video else ""))
    return 0


# --- demo -------------------------------------------------------------------------------------------------------

DEMOS = {"triangulation": "bench.triangulation", "point_tracking": "bench.point_tracking",
         "horizon_labels": "bench.horizon_labels", "horizon_networks": "bench.horizon_networks",
         "localization": "bench.localization", "vos": "bench.vos"}


def _demo_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--only", nargs="+", choices=tuple(DEMOS), help="run only these parts (default: all)")


@command("demo", "Run every capability on the project's own synthetic data and print the results.", _demo_arguments)
def _demo(args: argparse.Namespace) -> int:
    import importlib

    for name in args.only or DEMOS:
        start = time.perf_counter()
        print(f"\n=== {name} " + "=" * (70 - len(name)))
        importlib.import_module(DEMOS[name]).demo()
        print(f"({name}: {time.perf_counter() - start:.0f} s)")
    return 0


# --- segment (FRTM video object segmentation, thesis ch. 5) -----------------------------------------------------


def _segment_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_argument_group("input: one video folder or a whole DAVIS split")
    src.add_argument("--video", help="folder of frames (sorted by name)")
    src.add_argument("--mask", help="first-frame mask PNG (palette ids or binary gray)")
    src.add_argument("--davis", help="DAVIS root; segments and scores every sequence of --split")
    src.add_argument("--split", default="val", help="DAVIS ImageSets split (default val)")
    src.add_argument("--resolution", default="480p", help="DAVIS resolution folder (default 480p)")
    src.add_argument("--max-frames", type=int, help="DAVIS: cut sequences to this many frames")
    model = p.add_argument_group("model: exactly one")
    model.add_argument("--ckpt", help="FRTMSegmentation checkpoint from train.py")
    model.add_argument("--onnx", help="folder written by `python -m export.vos_onnx`")
    p.add_argument("--out", required=True, help="output folder for palette PNG masks")
    p.add_argument("--overlay", help="also write an overlay video (e.g. out.mp4)")


@command("segment", "Segment objects through a video from a first-frame mask (FRTM), or a DAVIS split with J&F.",
         _segment_arguments)
def _segment(args: argparse.Namespace) -> int:
    from models.vos.inference import check_first_frame, load_tracker, segment_davis, segment_folder

    if args.davis is None and (args.video is None or args.mask is None):
        raise InputError("give --video DIR --mask FIRST.png, or --davis ROOT --split NAME")
    if args.davis is None:
        from data.vos.io import list_frames

        check_first_frame(list_frames(args.video), args.mask)  # bad input fails before the model loads
        tracker = load_tracker(args.ckpt, args.onnx)
        n, seconds = segment_folder(tracker, args.video, args.mask, args.out, args.overlay)
        print(f"segmented {n} frames in {seconds:.1f} s ({n / seconds:.2f} FPS); masks in {args.out}")
        return 0
    tracker = load_tracker(args.ckpt, args.onnx)
    result, fps = segment_davis(tracker, args.davis, args.split, args.resolution, args.out, args.max_frames)
    print(json.dumps({"J&F": result["J&F-Mean"], "J": result["J-Mean"], "F": result["F-Mean"], "FPS": fps}))
    return 0


# --- build-bank / localize (horizon-profile localisation, thesis ch. 4.4) ------------------------------------


def _build_bank_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dem", type=Path, required=True,
                   help="GeoTIFF or .npz DEM (a geographic GeoTIFF is reprojected to its UTM zone)")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood the DEM at this level (m)")
    p.add_argument("--spacing", type=float, required=True, metavar="M", help="grid spacing of the locations (m)")
    p.add_argument("--out", type=Path, required=True, metavar="BANK", help="bank directory (resumes if unfinished)")
    p.add_argument("--bins", type=int, default=1024, help="azimuth bins per profile (default 1024)")
    p.add_argument("--camera-height", type=float, default=2.0, metavar="M", help="above the sea (default 2 m)")
    p.add_argument("--max-range", type=float, default=4000.0, metavar="M", help="ray length (default 4000 m)")
    p.add_argument("--neighbourhood", type=float, default=50.0, metavar="M",
                   help="side of the training neighbourhood (default 50 m)")
    p.add_argument("--frequencies", type=int, metavar="K", help="keep K frequencies (band limit; default all)")
    p.add_argument("--bounds", type=float, nargs=4, metavar=("W", "S", "E", "N"), help="cover only this area")
    p.add_argument("--float32", action="store_true", help="store float32 spectra (default float16)")
    p.add_argument("--overwrite", action="store_true", help="replace another bank in --out")
    p.add_argument("--device", default="cpu", help="torch device for ray casting and training (default cpu)")


@command("build-bank", "Build the 1-D MOSSE filter bank over the sea of a DEM for horizon localisation.",
         _build_bank_arguments)
def _build_bank(args: argparse.Namespace) -> int:
    from data.horizon.metric_dem import load_metric_dem
    from models.horizon.filter_bank import BankSettings, build_filter_bank

    dem = load_metric_dem(args.dem, sea_level=args.sea_level)
    settings = BankSettings(spacing=args.spacing, bins=args.bins, camera_height=args.camera_height,
                            max_range=args.max_range, neighbourhood=args.neighbourhood,
                            frequencies=args.frequencies)
    bank = build_filter_bank(dem, settings, args.out, bounds=tuple(args.bounds) if args.bounds else None,
                             storage_dtype="float32" if args.float32 else "float16", source=str(args.dem),
                             sea_level=args.sea_level, overwrite=args.overwrite, device=args.device)
    print(f"wrote {args.out}: {len(bank)} locations, {bank.nbytes / 1e6:.1f} MB, "
          f"built in {bank.meta['build_seconds']:.1f} s")
    return 0


def _localize_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--bank", type=Path, required=True, help="filter bank directory (build-bank)")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", type=Path, metavar="DIR", help="folder of tilted 360-degree panoramas")
    source.add_argument("--profiles", type=Path, metavar="FILE",
                        help=".npz with horizon (T, N) tan elevations [and compass_deg (T,)], or .npy (T, N)")
    p.add_argument("--compass", type=Path, metavar="CSV", help="compass headings: image,compass_deg (or compass_deg)")
    p.add_argument("--finder", type=Path, help="HorizonFinder checkpoint (default: newest demo training)")
    p.add_argument("--segmenter", type=Path, help="HorizonSegmenter checkpoint (default: newest demo training)")
    p.add_argument("--onnx", type=Path, metavar="DIR",
                   help="use finder.onnx / segmenter.onnx (and matcher.onnx if present) from DIR instead")
    p.add_argument("--input-width", type=int, default=512, metavar="PX", help="network input width (default 512)")
    p.add_argument("--dem", type=Path, help="check that the bank was built for this DEM")
    p.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="sea level of --dem (m)")
    p.add_argument("--band-deg", type=float, default=4.0, help="peak search band around the compass (default 4)")
    p.add_argument("--drop-harmonics", type=int, default=0, metavar="H",
                   help="ignore the profiles' harmonics 1..H (1 removes the sinusoid of a levelling error)")
    p.add_argument("--out", type=Path, required=True, metavar="track.csv", help="estimated positions and headings")


@command("localize", "Position and heading from panoramas (networks) or horizon profiles on a filter bank.",
         _localize_arguments)
def _localize(args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from data.horizon.bank_io import FilterBank
    from data.horizon.track_io import image_paths, read_compass_csv, read_profiles, write_track
    from models.horizon.localizer import locate, network_profiles

    bank = FilterBank(args.bank)
    if args.dem:
        from data.horizon.metric_dem import load_metric_dem

        bank.check_dem(load_metric_dem(args.dem, sea_level=args.sea_level), f"DEM {args.dem}")
    matcher = None
    if args.onnx and (args.onnx / "matcher.onnx").is_file():
        from export.onnx import onnx_session, run_onnx

        session = onnx_session(args.onnx / "matcher.onnx")

        def matcher(*inputs):
            return tuple(torch.from_numpy(a) for a in run_onnx(session, *inputs))

    if args.profiles:
        names, profiles, compass = read_profiles(args.profiles, args.compass)
        profile = torch.from_numpy(profiles).float()
    else:
        if args.compass is None:
            raise InputError("--images needs --compass CSV (image,compass_deg)")
        names, compass = read_compass_csv(args.compass, need_image=True)
        paths = image_paths(args.images, names)
        if args.onnx:
            finder = _horizon_network(args.onnx / "finder.onnx", "finder")
            segmenter = _horizon_network(args.onnx / "segmenter.onnx", "segmenter")
        else:
            from bench.localization import find_checkpoint

            finder_path = args.finder or find_checkpoint("finder")
            segmenter_path = args.segmenter or find_checkpoint("segmenter")
            if finder_path is None or segmenter_path is None:
                raise InputError("no HorizonFinder/HorizonSegmenter checkpoint: pass --finder and --segmenter "
                                 "(or --onnx DIR)")
            finder = _horizon_network(finder_path, "finder")
            segmenter = _horizon_network(segmenter_path, "segmenter")
        chunks = []
        for start in range(0, len(paths), 8):
            image = torch.cat([_read_panorama_arg(p) for p in paths[start : start + 8]])
            chunks.append(network_profiles(image, finder, segmenter, bank.bins, args.input_width)[0])
        profile = torch.cat(chunks).float()
    start = time.perf_counter()
    if args.drop_harmonics and matcher is not None:
        raise InputError("--drop-harmonics needs the PyTorch matcher (export matcher.onnx with --drop-harmonics)")
    result = locate(bank, profile, torch.from_numpy(np.asarray(compass)).float(), args.band_deg, matcher=matcher,
                    drop_harmonics=args.drop_harmonics)
    seconds = time.perf_counter() - start
    write_track(args.out, names, result.xy, result.heading_deg, result.psr)
    print(f"localised {len(names)} frames on {len(bank)} locations in {seconds:.2f} s "
          f"({len(names) * len(bank) / seconds:.3g} locations/s); wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

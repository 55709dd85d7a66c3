"""Benchmark of horizon-profile localisation with the 1-D MOSSE filter bank (thesis ch. 4.4).

    python -m bench.localization [--dem DEM.tif --sea-level M] [--spacing 5] [--json] [--plot FILE.png]

A boat trajectory of >= 100 poses (not on the grid) over a synthetic archipelago (or any GeoTIFF/.npz DEM,
flooded at ``--sea-level``); a filter bank over the trajectory's area; then per input kind:

- ``gt_profiles``: the true virtual horizon at each pose plus 0.05 degree Gaussian noise per bin;
- ``classical``: rendered panoramas -> Hough levelling + per-column sky boundary (no network, no DEM);
- ``networks``: rendered panoramas -> HorizonFinder -> levelling -> HorizonSegmenter (trained checkpoints
  given by ``--finder``/``--segmenter`` or found under ``outputs/horizon``; reported as pending otherwise).

Compass = true heading + 1 degree noise; peak band +-4 degrees. Errors are distances of the estimate from the
true position; ``fail_rate`` = share of errors over 50 m. Image inputs are also scored with their first harmonic
ignored (``<kind>_tilt_free``): a levelling error adds exactly such a sinusoid to a measured profile.
Speed: the batched band-PSR matching on one query against a bank chunk of 2**17 locations, and a plain
per-location numpy FFT loop on the same filters, side by side.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

from core.cylinder import column_azimuths, interp_profile
from core.errors import InputError
from core.raycast import VirtualHorizon, virtual_horizon
from data.horizon.bank_io import FilterBank
from data.horizon.metric_dem import load_metric_dem
from data.world.dem import Dem, generate_archipelago
from models.builders import demo_horizon_checkpoint
from models.horizon.filter_bank import BankSettings, build_filter_bank, profile_normalize
from models.horizon.localizer import heading_error_deg, locate, resample_profile
from models.horizon.matching import band_bins, band_psr

KINDS = ("gt_profiles", "classical", "networks")


def synthetic_dem(size_m: float = 3000.0, seed: int = 7) -> Dem:
    """The benchmark's archipelago: 5 m cells, islands up to ~700 m."""
    return generate_archipelago(size_m=size_m, cell=5.0, seed=seed, feature_scale_m=700.0, land_fraction=0.15)


def trajectory(dem: Dem, count: int = 100, step_m: float = 4.0, shore_m: tuple[float, float] = (30.0, 500.0),
               camera_height: float = 2.0, margin_m: float = 600.0, seed: int = 0) -> np.ndarray:
    """One boat track of ``count`` poses (x, y, camera height, heading, pitch, roll) over water.

    A smooth random walk (4 degree turns) of ``step_m`` per frame, kept ``shore_m`` from land and ``margin_m``
    from the DEM edges; heading = course plus a random mount offset; pitch/roll of a few degrees (wave motion).
    """
    import cv2

    rng = np.random.default_rng(seed)
    sea = (dem.z <= 0).astype(np.uint8)
    shore = cv2.distanceTransform(sea, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * dem.cell
    west, south, east, north = dem.bounds

    def ok(p: np.ndarray) -> bool:
        if not (west + margin_m < p[0] < east - margin_m and south + margin_m < p[1] < north - margin_m):
            return False
        d = shore[int((dem.y0 - p[1]) // dem.cell), int((p[0] - dem.x0) // dem.cell)]
        return bool(shore_m[0] <= d <= shore_m[1])

    rr, cc = np.nonzero((shore >= shore_m[0]) & (shore <= shore_m[1]))
    starts = np.stack([dem.x0 + (cc + 0.5) * dem.cell, dem.y0 - (rr + 0.5) * dem.cell], -1)
    starts = starts[[ok(p) for p in starts]]
    if len(starts) == 0:
        raise InputError(f"the DEM has no water {shore_m} m from land and {margin_m} m from its edges")
    for _attempt in range(200):
        p = starts[rng.integers(len(starts))] + rng.uniform(-2, 2, 2)
        course, mount = rng.uniform(0, 2 * math.pi, 2)
        poses = []
        while len(poses) < count:
            heading = (course + mount) % (2 * math.pi)
            tilt = np.radians(2.0) * np.sin(len(poses) / 5.0 + np.array([0.0, 1.3]))
            poses.append([p[0], p[1], camera_height, heading, tilt[0], tilt[1]])
            for _ in range(24):
                turn = course + rng.normal(0, math.radians(4))
                nxt = p + step_m * np.array([math.sin(turn), math.cos(turn)])
                if ok(nxt):
                    course, p = turn, nxt
                    break
                course = rng.uniform(0, 2 * math.pi)
            else:
                break
        if len(poses) == count:
            return np.asarray(poses)
    raise InputError("could not fit a trajectory of the requested length on the DEM's water")


def gt_profiles(dem: Dem, poses: np.ndarray, bins: int, max_range: float, noise_deg: float, seed: int) -> torch.Tensor:
    """(B, bins) true profiles seen with each pose's heading (column 0 forward) plus Gaussian noise."""
    h = virtual_horizon(torch.from_numpy(dem.z), dem.x0, dem.y0, dem.cell, torch.from_numpy(poses[:, :2]).float(),
                        torch.from_numpy(poses[:, 2]).float(), bins, max_range, dem.cell).horizon
    psi = column_azimuths(bins)[None] + torch.from_numpy(poses[:, 3]).float()[:, None]
    profile = interp_profile(h, psi)
    gen = torch.Generator().manual_seed(seed)
    elevation = torch.atan(profile) + math.radians(noise_deg) * torch.randn(profile.shape, generator=gen)
    return torch.tan(elevation)


def render(dem: Dem, poses: np.ndarray, width: int, height: int, max_range: float, seed: int) -> torch.Tensor:
    """(B, 3, H, W) rendered tilted panoramas (clean conditions)."""
    from data.world.render import Appearance, render_panorama

    caster = VirtualHorizon(dem, bins=width, max_range=max_range, step=dem.cell)
    gen = torch.Generator().manual_seed(seed)
    images = []
    for start in range(0, len(poses), 8):
        batch = torch.from_numpy(poses[start : start + 8]).float()
        image, _ = render_panorama(caster, batch, width, height, Appearance.sample(len(batch), False, gen), gen)
        images.append(image)
    return torch.cat(images)


def network_inputs(images: torch.Tensor, bins: int, finder: Path, segmenter: Path) -> torch.Tensor:
    from models.builders import horizon_finder, horizon_segmenter
    from models.horizon.localizer import network_profiles

    f, s = horizon_finder(ckpt=finder), horizon_segmenter(ckpt=segmenter)
    out = [network_profiles(images[i : i + 8], f, s, bins)[0] for i in range(0, len(images), 8)]
    return torch.cat(out)


def numpy_loop_rate(filters: np.ndarray, profile: np.ndarray, heading_deg: float, band_deg: float,
                    exclude: int, threshold: float, count: int) -> float:
    """Locations per second of a plain per-location numpy loop: irfft of the full response, band peak, PSR."""
    bins = profile.shape[-1]
    z = np.fft.rfft(profile_normalize(torch.from_numpy(profile[None]), threshold).numpy()[0])
    half = filters.shape[1] // 2
    band = band_bins(band_deg, bins)
    centre = round(-heading_deg * bins / 360)
    lags = np.arange(centre - band, centre + band + 1) % bins
    start = time.perf_counter()
    for f in filters[:count]:
        h = np.zeros(bins // 2 + 1, np.complex64)
        h[:half] = f[0::2] + 1j * f[1::2]
        r = np.fft.irfft(h * z, n=bins)
        p = lags[np.argmax(r[lags])]
        mask = np.ones(bins, bool)
        mask[np.arange(p - exclude // 2, p + exclude // 2 + 1) % bins] = False
        side = r[mask]
        _ = (r[p] - side.mean()) / side.std()
    return count / (time.perf_counter() - start)


def speed(bank: FilterBank, profile: torch.Tensor, heading_deg: float, band_deg: float = 4.0, exclude: int = 11,
          locations: int = 2**17, chunk: int = 4096, loop_count: int = 2000) -> dict:
    """Matching rate of one query against ``locations`` bank filters (tiled if the bank is smaller), in chunks of
    ``chunk`` locations with 1 and 2 threads, and of the numpy loop on the same filters, in the same run."""
    stored = np.concatenate([c.numpy() for c in bank.chunks(2**16)])
    filters = torch.from_numpy(np.resize(stored, (locations, stored.shape[1])).astype(np.float32))
    threshold = float(bank.settings["norm_threshold_deg"])
    query, heading = profile[:1].float(), torch.tensor([heading_deg], dtype=torch.float32)
    threads_before = torch.get_num_threads()
    band_psr(filters[:chunk], query, heading, band_deg, exclude, threshold)  # warm up
    rates = {1: 0.0, 2: 0.0}
    loop = 0.0
    for _ in range(3):  # interleaved, best of three each: the load of a shared machine changes by the second
        for threads in (1, 2):
            torch.set_num_threads(threads)
            start = time.perf_counter()
            for s in range(0, locations, chunk):
                band_psr(filters[s : s + chunk], query, heading, band_deg, exclude, threshold)
            rates[threads] = max(rates[threads], locations / (time.perf_counter() - start))
        loop = max(loop, numpy_loop_rate(filters.numpy(), query[0].numpy(), heading_deg, band_deg, exclude,
                                         threshold, loop_count))
    torch.set_num_threads(threads_before)
    batched = max(rates.values())
    return {"locations": locations, "chunk": chunk, "locations_per_s": batched,
            "locations_per_s_1_thread": rates[1], "locations_per_s_2_threads": rates[2],
            "numpy_loop_locations_per_s": loop, "speedup_vs_numpy_loop": batched / loop}


def evaluate(bank: FilterBank, profile: torch.Tensor, poses: np.ndarray, compass: np.ndarray,
             band_deg: float = 4.0, drop_harmonics: int = 0) -> tuple[dict, object]:
    start = time.perf_counter()
    result = locate(bank, profile.float(), torch.from_numpy(compass).float(), band_deg, keep_scores=True,
                    drop_harmonics=drop_harmonics)
    seconds = time.perf_counter() - start
    err = np.linalg.norm(result.xy - poses[:, :2], axis=1)
    head = heading_error_deg(result.heading_deg, np.degrees(poses[:, 3]))
    return {
        "err_mean_m": float(err.mean()), "err_median_m": float(np.median(err)), "err_std_m": float(err.std()),
        "fail_rate": float((err > 50).mean()), "heading_err_median_deg": float(np.median(head)),
        "locations_per_s": len(bank) * len(profile) / seconds, "queries": len(profile),
    }, result


def run(dem: Dem | None = None, spacing: float = 5.0, count: int = 100, bins: int = 512, max_range: float = 1500.0,
        width: int = 2048, height: int = 256, kinds: tuple[str, ...] = KINDS, bank_dir: Path | None = None,
        finder: Path | None = None, segmenter: Path | None = None, speed_locations: int = 2**17,
        settings: dict | None = None, margin: float = 100.0, seed: int = 0, progress: bool = True) -> dict:
    """Build the bank over the trajectory's bounding box plus ``margin`` metres and evaluate every input kind;
    returns the report and extras (DEM, poses, bank, per-kind ``Localization``)."""
    import tempfile

    dem = dem or synthetic_dem()
    west, south, east, north = dem.bounds
    edge = min(max_range / 2.5, 0.25 * min(east - west, north - south))  # keep the rays' land in the DEM
    poses = trajectory(dem, count, margin_m=edge, seed=seed)
    rng = np.random.default_rng(seed + 1)
    compass = np.remainder(np.degrees(poses[:, 3]) + rng.normal(0, 1.0, len(poses)), 360.0)
    bounds = (poses[:, 0].min() - margin, poses[:, 1].min() - margin,
              poses[:, 0].max() + margin, poses[:, 1].max() + margin)
    bank_settings = BankSettings(**{"spacing": spacing, "bins": bins, "max_range": max_range, **(settings or {})})
    tmp = tempfile.TemporaryDirectory() if bank_dir is None else None
    out = Path(tmp.name) / "bank" if tmp else bank_dir
    start = time.perf_counter()
    bank = build_filter_bank(dem, bank_settings, out, bounds=bounds, progress=progress, overwrite=True)
    report: dict = {"bank_build_s": time.perf_counter() - start, "bank_bytes": bank.nbytes,
                    "bank_locations": len(bank), "poses": len(poses), "spacing_m": spacing, "bins": bins,
                    "settings": bank.settings, "dem_shape": list(dem.z.shape), "dem_cell_m": dem.cell}
    extras = {"dem": dem, "poses": poses, "bank": bank, "results": {}}
    images = None
    for kind in kinds:
        if kind == "gt_profiles":
            profile = gt_profiles(dem, poses, bins, max_range, 0.05, seed)
        elif kind == "classical":
            from models.horizon.classical_profile import classical_profile

            images = render(dem, poses, width, height, max_range, seed) if images is None else images
            profile = resample_profile(classical_profile(images, torch.from_numpy(poses[:, 2]))[0], bins)
        else:
            finder = finder or demo_horizon_checkpoint("finder")
            segmenter = segmenter or demo_horizon_checkpoint("segmenter")
            if finder is None or segmenter is None:
                report[kind] = {"pending": "no trained HorizonFinder/HorizonSegmenter checkpoints (train "
                                           "configs/demo/horizon_*.yaml or pass --finder/--segmenter)"}
                continue
            images = render(dem, poses, width, height, max_range, seed) if images is None else images
            profile = network_inputs(images, bins, finder, segmenter)
            report[kind + "_checkpoints"] = [str(finder), str(segmenter)]
        report[kind], extras["results"][kind] = evaluate(bank, profile, poses, compass)
        if kind != "gt_profiles":  # image profiles: also ignore harmonic 1 (the sinusoid of a levelling error)
            report[kind + "_tilt_free"], _ = evaluate(bank, profile, poses, compass, drop_harmonics=1)
    query = gt_profiles(dem, poses[:1], bins, max_range, 0.05, seed)
    report["speed"] = speed(bank, query, float(compass[0]), locations=speed_locations)
    if tmp is not None:
        extras["tmp"] = tmp
    return {"report": report, **extras}


def plot(outcome: dict, path: str | Path) -> None:
    """Response map of one query over the DEM (like fig. 4.7) and estimated vs true trajectory (fig. 4.8)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dem, poses, bank = outcome["dem"], outcome["poses"], outcome["bank"]
    results = outcome["results"]
    first = results.get("gt_profiles") or next(iter(results.values()))
    grid = bank.grid
    cells = bank.cells()
    fig, axes = plt.subplots(1, 2, figsize=(13, 6))
    pad = 150.0
    x_lo, x_hi = poses[:, 0].min() - pad, poses[:, 0].max() + pad
    y_lo, y_hi = poses[:, 1].min() - pad, poses[:, 1].max() + pad
    c0, c1 = int((x_lo - dem.x0) // dem.cell), int((x_hi - dem.x0) // dem.cell)
    r0, r1 = int((dem.y0 - y_hi) // dem.cell), int((dem.y0 - y_lo) // dem.cell)
    crop = dem.z[max(r0, 0) : r1, max(c0, 0) : c1]
    extent = (dem.x0 + max(c0, 0) * dem.cell, dem.x0 + c1 * dem.cell, dem.y0 - r1 * dem.cell,
              dem.y0 - max(r0, 0) * dem.cell)
    for ax in axes:
        ax.imshow(np.where(crop > 0, crop, np.nan), cmap="Greens", extent=extent, origin="upper", vmin=-10)
        ax.set_facecolor("#9ecae1")
    score = np.full((grid["rows"], grid["cols"]), np.nan)
    score[cells[:, 0], cells[:, 1]] = first.scores[0]
    gx0, gy0, s = grid["x0"], grid["y0"], grid["spacing"]
    im = axes[0].imshow(score, cmap="Reds", alpha=0.85, origin="upper",
                        extent=(gx0 - s / 2, gx0 + (grid["cols"] - 0.5) * s, gy0 - (grid["rows"] - 0.5) * s,
                                gy0 + s / 2))
    axes[0].plot(*poses[0, :2], "c+", ms=14, mew=2, label="true position")
    axes[0].plot(*first.xy[0], "yx", ms=10, mew=2, label="estimate")
    axes[0].set_title("PSR of every bank location for one query (cf. fig. 4.7)")
    axes[0].legend(loc="lower right")
    fig.colorbar(im, ax=axes[0], shrink=0.7, label="PSR")
    axes[1].plot(poses[:, 0], poses[:, 1], "o", mfc="none", mec="red", ms=6, label="truth")
    markers = {"gt_profiles": ("yx", "gt profiles"), "classical": ("b+", "classical"), "networks": ("g1", "networks")}
    for kind, result in results.items():
        style, label = markers[kind]
        axes[1].plot(result.xy[:, 0], result.xy[:, 1], style, ms=6, label=label)
    axes[1].set_xlim(x_lo, x_hi)
    axes[1].set_ylim(y_lo, y_hi)
    axes[1].set_title("estimated trajectory vs truth (cf. fig. 4.8)")
    axes[1].legend(loc="lower right")
    for ax in axes:
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table(report: dict) -> str:
    lines = [f"bank: {report['bank_locations']} locations at {report['spacing_m']} m, {report['bins']} bins, "
             f"{report['bank_bytes'] / 1e6:.1f} MB, built in {report['bank_build_s']:.1f} s"]
    lines.append(f"{'input':>20} {'mean m':>8} {'median m':>9} {'std m':>7} {'fail':>6} {'head deg':>9} {'loc/s':>10}")
    for kind in [k for base in KINDS for k in (base, base + "_tilt_free")]:
        r = report.get(kind)
        if r is None:
            continue
        if "pending" in r:
            lines.append(f"{kind:>20}  pending: {r['pending']}")
            continue
        lines.append(f"{kind:>20} {r['err_mean_m']:8.2f} {r['err_median_m']:9.2f} {r['err_std_m']:7.2f} "
                     f"{r['fail_rate']:6.1%} {r['heading_err_median_deg']:9.3f} {r['locations_per_s']:10.3g}")
    s = report["speed"]
    lines.append(f"matching speed on {s['locations']} locations: {s['locations_per_s_1_thread']:.3g} (1 thread) / "
                 f"{s['locations_per_s_2_threads']:.3g} (2 threads) loc/s batched vs "
                 f"{s['numpy_loop_locations_per_s']:.3g} loc/s numpy loop ({s['speedup_vs_numpy_loop']:.0f}x)")
    return "\n".join(lines)


def demo(report_dir: Path | None = None, quick: bool = False) -> list[tuple[str, str]]:
    """Small version (< 1 minute on 2 cores): 1.5 km map, 10 m grid, 256 bins, 40 poses (20 quick), ground-truth
    profiles. With ``report_dir``, writes the response map and the trajectory there; returns the figures."""
    count = 20 if quick else 40
    print(f"horizon localisation: filter bank around a {count}-pose boat track, ground-truth profiles + 0.05 deg "
          "noise")
    dem = generate_archipelago(size_m=1500.0, cell=5.0, seed=7, feature_scale_m=500.0, land_fraction=0.15)
    outcome = run(dem, spacing=10.0, count=count, bins=256, max_range=700.0, kinds=("gt_profiles",),
                  speed_locations=2**13 if quick else 2**15, margin=50.0, progress=False)
    print(_table(outcome["report"]))
    if report_dir is None:
        return []
    plot(outcome, report_dir / "localization.png")
    return [("localization.png", "Localisation on the filter bank: the PSR response of one query over the map "
             "(thesis fig. 4.7) and the estimated against the true boat trajectory (fig. 4.8)")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dem", type=Path, help="GeoTIFF or .npz DEM (default: a synthetic archipelago)")
    parser.add_argument("--sea-level", type=float, default=0.0, metavar="M", help="flood the DEM at this level")
    parser.add_argument("--spacing", type=float, default=5.0, metavar="M", help="bank grid spacing (default 5)")
    parser.add_argument("--poses", type=int, default=100, help="trajectory length (default 100)")
    parser.add_argument("--bins", type=int, default=512, help="azimuth bins (default 512)")
    parser.add_argument("--max-range", type=float, default=1500.0, metavar="M", help="ray length (default 1500)")
    parser.add_argument("--neighbourhood", type=float, default=None, metavar="M",
                        help="training neighbourhood side (default: the BankSettings default)")
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    parser.add_argument("--finder", type=Path, help="HorizonFinder checkpoint (default: newest demo one)")
    parser.add_argument("--segmenter", type=Path, help="HorizonSegmenter checkpoint (default: newest demo one)")
    parser.add_argument("--margin", type=float, default=100.0, metavar="M",
                        help="the bank covers the trajectory's box plus this margin (default 100 m)")
    parser.add_argument("--bank", type=Path, help="keep the bank in this directory")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", type=Path, metavar="FILE.png", help="draw the response map and the trajectory")
    args = parser.parse_args(argv)
    try:
        dem = load_metric_dem(args.dem, sea_level=args.sea_level) if args.dem else None
        settings = {} if args.neighbourhood is None else {"neighbourhood": args.neighbourhood}
        outcome = run(dem, args.spacing, args.poses, args.bins, args.max_range, kinds=tuple(args.kinds),
                      bank_dir=args.bank, finder=args.finder, segmenter=args.segmenter, settings=settings,
                      margin=args.margin, progress=not args.json)
    except InputError as err:
        sys.stderr.write(f"bench/localization.py: error: {err}\n")
        return 2
    report = outcome["report"]
    report["dem"] = str(args.dem) if args.dem else "synthetic archipelago 3 x 3 km, 5 m cells, seed 7"
    if args.plot:
        plot(outcome, args.plot)
    print(json.dumps(report) if args.json else _table(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

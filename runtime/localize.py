"""Horizon-profile localisation on a filter bank from the exported graphs (thesis ch. 4.4), torch-free.

    python -m runtime.localize --bundle DIR --bank BANK (--images DIR --compass CSV | --profiles FILE [--compass CSV])
                               --out track.csv [--threads N] [--provider cpu|cuda|tensorrt|coreml]

Panoramas go through the horizon chain (``runtime.horizon``) and their horizon profiles are resampled to the
bank's azimuth bins (or profiles come from a file); the bundle's ``matcher`` graph scores every location of the
memory-mapped bank block by block (band PSR around the compass heading); the best location is refined on the grid
by a parabola and written with its heading to the track CSV of ``infer.py localize``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from core.bank_reader import BankReader, subgrid_refine
from core.command import CommandParser, run_command
from core.errors import InputError
from core.track_io import image_paths, read_compass_csv, read_profiles, write_track
from runtime.bundle import Bundle, add_runtime_arguments
from runtime.horizon import HorizonChain, read_panorama, resample_profile


class OnnxLocalizer:
    """Localisation on ``bank`` with the matcher (and, for panoramas, the networks) of a horizon bundle.

    Args:
        bundle: the bundle folder; bank: the filter bank folder (its bins, stored frequencies and normalisation
            threshold must be the matcher's); threads, provider: as ``runtime.session.Graph``; chunk: locations
            per matcher call; batch: panoramas per network call.
    """

    def __init__(self, bundle: str | Path, bank: str | Path, threads: int | None = None, provider: str = "cpu",
                 chunk: int = 8192, batch: int = 8) -> None:
        self.bundle = Bundle(bundle, "horizon", threads, provider)
        self.bank = BankReader(bank)
        matcher = self.bundle.section("settings")["matcher"]
        stored = {"bins": self.bank.bins, "half_spectrum": self.bank.half_spectrum,
                  "norm_threshold_deg": float(self.bank.settings["norm_threshold_deg"])}
        if stored != {k: matcher[k] for k in stored}:
            raise InputError(f"filter bank {self.bank.path} ({stored}) does not fit the bundle's matcher "
                             f"({ {k: matcher[k] for k in stored} }); export the bundle with --bank {self.bank.path}")
        if len(self.bank) == 0:
            raise InputError(f"filter bank {self.bank.path} has no sea locations")
        self.matcher = self.bundle.graph("matcher")
        self.chain: HorizonChain | None = None
        self.chunk, self.batch = chunk, batch

    def image_profiles(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(B, bins) horizon profiles of tilted panoramas (each (1, 3, H, W)), ``batch`` at a time."""
        self.chain = self.chain or HorizonChain(self.bundle)
        out = []
        for start in range(0, len(images), self.batch):
            profiles, _, _ = self.chain(np.concatenate(images[start : start + self.batch]))
            out.append(resample_profile(profiles[:, 0], self.bank.bins))
        return np.concatenate(out).astype(np.float32)

    def locate(self, profile: np.ndarray, heading_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                             np.ndarray]:
        """Position (B, 2) m, heading (B,) deg, PSR (B,) and fractional grid cell (B, 2) of profiles (B, bins) tan
        elevation with compass headings (B,) deg."""
        profile = np.ascontiguousarray(profile, np.float32)
        heading_deg = np.asarray(heading_deg, np.float32)
        if profile.ndim != 2 or profile.shape[1] != self.bank.bins:
            raise InputError(f"profiles must be (B, {self.bank.bins}) for bank {self.bank.path}, got {profile.shape}")
        if not np.isfinite(profile).all():
            raise InputError("profiles contain NaN or infinite values")
        if heading_deg.shape != profile.shape[:1]:
            raise InputError(f"need one compass heading per profile: {heading_deg.shape} vs {profile.shape[0]}")
        bad = ~np.isfinite(heading_deg) | (heading_deg < 0) | (heading_deg >= 360)
        if bad.any():
            raise InputError(f"compass heading {heading_deg[bad][0]:g} deg is outside [0, 360)")
        scores = np.full((len(profile), len(self.bank)), -np.inf, np.float32)
        headings = np.zeros_like(scores)
        for offset, cells, filters in self.bank.arrays(self.chunk):
            count = len(cells)
            filters = np.concatenate([filters, filters]) if count == 1 else filters  # the graph takes >= 2
            psr, heading = self.matcher(filters, profile, heading_deg)
            scores[:, offset : offset + count] = psr[:, :count]
            headings[:, offset : offset + count] = heading[:, :count]
        best = scores.argmax(1)
        grid = self.bank.grid
        cell = subgrid_refine(scores, self.bank.cells(), grid["rows"], grid["cols"], best)
        xy = np.stack([grid["x0"] + cell[:, 1] * grid["spacing"], grid["y0"] - cell[:, 0] * grid["spacing"]], -1)
        queries = np.arange(len(best))
        return xy, headings[queries, best], scores[queries, best], cell


def localize_files(bundle: str | Path, bank: str | Path, out: str | Path, images: str | Path | None = None,
                   profiles: str | Path | None = None, compass: str | Path | None = None, threads: int | None = None,
                   provider: str = "cpu") -> str:
    """Localise the panoramas of the folder ``images`` (with the ``compass`` CSV) or the ``profiles`` file on
    ``bank`` with the bundle and write the track CSV ``out``; returns a one-line summary (the command
    ``runtime.localize``)."""
    localizer = OnnxLocalizer(bundle, bank, threads, provider)
    if profiles is not None:
        names, profile, heading = read_profiles(profiles, compass)
        if profile.shape[1] != localizer.bank.bins:
            raise InputError(f"profile file {profiles} has {profile.shape[1]} azimuth bins per profile, the bank "
                             f"{bank} {localizer.bank.bins}")
    else:
        if compass is None:
            raise InputError("--images needs --compass CSV (image,compass_deg)")
        names, heading = read_compass_csv(compass, need_image=True)
        paths = image_paths(images, names)
        panoramas = [read_panorama(p) for p in paths]
        localizer.chain = HorizonChain(localizer.bundle)
        for path, panorama in zip(paths, panoramas, strict=True):
            localizer.chain.check(panorama, f"panorama {path}")
        profile = localizer.image_profiles(panoramas)
    start = time.perf_counter()
    xy, heading_out, psr, _ = localizer.locate(profile, heading)
    seconds = time.perf_counter() - start
    write_track(out, names, xy, heading_out, psr)
    return (f"localised {len(names)} frames on {len(localizer.bank)} locations in {seconds:.2f} s "
            f"({len(names) * len(localizer.bank) / seconds:.3g} locations/s, onnxruntime); wrote {out}")


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="runtime.localize", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_runtime_arguments(parser)
    parser.add_argument("--bank", type=Path, required=True, help="filter bank directory (infer.py build-bank)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", type=Path, metavar="DIR", help="folder of tilted 360-degree panoramas")
    source.add_argument("--profiles", type=Path, metavar="FILE",
                        help=".npz with horizon (T, N) tan elevations [and compass_deg (T,)], or .npy (T, N)")
    parser.add_argument("--compass", type=Path, metavar="CSV", help="compass headings: image,compass_deg")
    parser.add_argument("--out", type=Path, required=True, metavar="track.csv", help="positions and headings")
    args = parser.parse_args(argv)

    def run() -> None:
        print(localize_files(args.bundle, args.bank, args.out, args.images, args.profiles, args.compass, args.threads,
                             args.provider))

    return run_command("runtime.localize", run)


if __name__ == "__main__":
    raise SystemExit(main())

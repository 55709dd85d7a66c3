"""The horizon networks of thesis ch. 4.3 from the exported graphs, torch-free: HorizonFinder (pitch, roll) ->
levelling warp -> HorizonSegmenter (horizon and water-line profiles).

    python -m runtime.horizon --bundle DIR --image PANO [--out FILE.npz] [--json] [--threads N] [--provider cpu]

A panorama (RGB, 360 degrees, column 0 forward) is area-resized to the networks' input width; the finder's (sin,
cos) outputs give pitch and roll by ``atan2``; the ``level`` graph warps the full-size panorama with them; the
segmenter reads the resized levelled panorama and its profiles (tan elevation) are resampled to the panorama's
width. Prints what ``infer.py horizon`` prints (``pitch_deg``, ``roll_deg``, ``horizon_row_median``,
``land_columns``); ``--out`` writes pitch, roll (rad) and the per-column profiles.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import cv2
import numpy as np

from core.command import CommandParser, print_report, run_command
from core.errors import InputError
from core.files import write_npz
from runtime.area import area_resize
from runtime.bundle import Bundle, add_runtime_arguments


def read_panorama(path: str | Path) -> np.ndarray:
    """(1, 3, H, W) float32 RGB in [0, 1] of a 360-degree panorama (at least 64 x 16 px, twice as wide as high)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"panorama image missing or unreadable: {path}")
    height, width = image.shape[:2]
    if width < 64 or height < 16 or width < 2 * height:
        raise InputError(f"{path}: a 360-degree panorama must be at least 64 x 16 px and at least twice as wide as "
                         f"high, got {width} x {height}")
    return np.ascontiguousarray(image[..., ::-1].transpose(2, 0, 1)[None], np.float32) / np.float32(255)


def resize_panorama(image: np.ndarray, width: int) -> np.ndarray:
    """(B, 3, H, W) panorama area-resized to ``width`` keeping the cylinder aspect (``data.horizon.datamodule``)."""
    if image.shape[-1] == width:
        return image
    return area_resize(image, (max(int(round(image.shape[-2] * width / image.shape[-1])), 8), width))


def resample_profile(profile: np.ndarray, bins: int) -> np.ndarray:
    """Circular linear resampling of (B, W) profiles (column u at azimuth 2 pi u / W) to (B, bins)."""
    width = profile.shape[-1]
    if width == bins:
        return profile
    psi = np.float32(2 * math.pi) * np.arange(bins, dtype=np.float32) / np.float32(bins)
    x = np.remainder(psi, np.float32(2 * math.pi)) * np.float32(width / (2 * math.pi))
    j0 = np.clip(np.floor(x).astype(np.int64), 0, width - 1)
    frac = x - j0.astype(np.float32)
    return profile[:, j0] * (1 - frac) + profile[:, (j0 + 1) % width] * frac


class HorizonChain:
    """The finder -> level -> segmenter chain of a horizon bundle.

    Args:
        bundle: the bundle folder (or an opened ``Bundle``); threads, provider: as ``runtime.session.Graph``.
    """

    def __init__(self, bundle: str | Path | Bundle, threads: int | None = None, provider: str = "cpu") -> None:
        self.bundle = bundle if isinstance(bundle, Bundle) else Bundle(bundle, "horizon", threads, provider)
        size = self.bundle.section("input")
        self.height, self.input_width = int(size["panorama_height"]), int(size["input_width"])
        self.input_height, self.stride = int(size["input_height"]), int(size["stride"])
        self.finder, self.level, self.segmenter = (self.bundle.graph(g) for g in ("finder", "level", "segmenter"))

    def check(self, image: np.ndarray, name: str = "panorama") -> None:
        """``InputError`` (naming ``name``) unless ``image`` (B, 3, H, W) has the panorama height of the bundle and
        resizes to its networks' input size."""
        height, width = image.shape[-2:]
        resized = max(int(round(height * self.input_width / width)), 8)
        if image.ndim != 4 or image.shape[1] != 3 or height != self.height or resized != self.input_height:
            raise InputError(f"{name} of shape {image.shape[1:]} does not fit the bundle: it takes (3, "
                             f"{self.height}, W) panoramas whose resize to width {self.input_width} is "
                             f"{self.input_height} px high")

    def angles(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pitch and roll (B,) rad of tilted panoramas (B, 3, H, W) in [0, 1]."""
        self.check(image)
        sincos = self.finder(resize_panorama(image, self.input_width))
        return np.arctan2(sincos[:, 0], sincos[:, 1]), np.arctan2(sincos[:, 2], sincos[:, 3])

    def __call__(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Profiles (B, 2, W) tan elevation of the horizon and the water line, pitch (B,) and roll (B,) rad."""
        image = np.ascontiguousarray(image, np.float32)
        pitch, roll = self.angles(image)
        level = self.level(image, pitch, roll)
        profiles = self.segmenter(resize_panorama(level, self.input_width))
        width = image.shape[-1]
        return np.stack([resample_profile(profiles[:, i], width) for i in range(2)], 1), pitch, roll


def horizon_report(profiles: np.ndarray, pitch: float, roll: float, height: int) -> dict:
    """What ``infer.py horizon`` prints for one panorama: angles in degrees, the median horizon row (px from the
    top pixel centre) and the columns with land (horizon above the water line by more than 2 px)."""
    horizon, water = profiles.astype(np.float64)
    width = horizon.shape[-1]
    rows = (height - 1) / 2.0 - horizon * (width / (2 * math.pi))
    return {"pitch_deg": math.degrees(pitch), "roll_deg": math.degrees(roll),
            "horizon_row_median": float(np.median(rows)),
            "land_columns": int(np.sum(horizon - water > 2 * math.pi / width))}


def horizon_file(bundle: str | Path, image_path: str | Path, out: str | Path | None = None,
                 threads: int | None = None, provider: str = "cpu") -> dict:
    """Run the chain on one panorama file, optionally write pitch, roll (rad) and the profiles to ``out`` (.npz);
    returns the report (the command ``runtime.horizon``)."""
    chain = HorizonChain(bundle, threads, provider)
    image = read_panorama(image_path)
    chain.check(image, f"panorama {image_path}")
    profiles, pitch, roll = chain(image)
    if out:
        horizon, water = profiles[0].astype(np.float64)
        write_npz(out, pitch=np.array(float(pitch[0])), roll=np.array(float(roll[0])), horizon=horizon, water=water)
    return horizon_report(profiles[0], float(pitch[0]), float(roll[0]), image.shape[-2])


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="runtime.horizon", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_runtime_arguments(parser)
    parser.add_argument("--image", type=Path, required=True, help="tilted 360-degree panorama (column 0 = forward)")
    parser.add_argument("--out", type=Path, metavar="FILE.npz", help="write pitch, roll and the per-column profiles")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    def run() -> None:
        print_report(horizon_file(args.bundle, args.image, args.out, args.threads, args.provider), args.json)

    return run_command("runtime.horizon", run)


if __name__ == "__main__":
    raise SystemExit(main())

"""Rendered horizon datasets: boat trajectories through the archipelago, panoramas, classical labels, truth.

``write_dataset`` drives boats along random trajectories over the water of a DEM, renders a panorama per frame
(``data.world.render``), runs the classical label maker (``data.horizon.classical``) on it with a noisy GPS
position and compass, and writes::

    out/meta.json        sizes, settings, seeds, DEM file
    out/dem.tif          the DEM (GeoTIFF with CRS and transform)
    out/images/NNNNNN.png  tilted panoramas (8-bit RGB)
    out/labels.npz       classical labels + sensor readings (what the networks train on)
    out/truth.npz        the renderer's ground truth (what they are evaluated against)

Angles are in radians, profiles in tan(elevation) per levelled column, rows in pixels of the stored images.
"""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from tqdm import tqdm

from core.errors import InputError
from core.files import atomic_path, writable_folder, write_bytes, write_npz, write_text
from core.raycast import VirtualHorizon
from data.horizon.classical import ClassicalHorizon
from data.world.dem import Dem, dem_fingerprint, save_dem
from data.world.render import Appearance, render_panorama

LABEL_KEYS = ("pitch", "roll", "heading", "horizon", "water", "horizon_rows", "water_rows", "quality", "ok")
TRUTH_KEYS = ("pitch", "roll", "heading", "horizon", "water", "level_horizon_rows", "level_water_rows",
              "horizon_rows", "water_rows")


@dataclass
class DatasetSettings:
    """How a dataset is rendered and labelled.

    Attributes:
        count: number of panoramas.
        width, height: panorama size in pixels.
        frames_per_track: frames per boat trajectory.
        step_m: distance between frames along a trajectory, metres.
        shore_m: (min, max) distance of the boat from land, metres (keeps land in view, keeps off the rocks).
        camera_height_m: (min, max) camera height above the sea per trajectory, metres.
        tilt_deg: amplitude scale of the boat's pitch and roll, degrees.
        degraded_fraction: share of frames rendered with heavy haze, noise, blur and glare.
        gps_noise_m: standard deviation of the GPS position error, metres.
        compass_noise_deg: standard deviation of the compass error, degrees.
        render_bins: azimuth bins of the renderer's ray casting (>= width).
        label_bins: azimuth bins of the label maker's virtual horizon.
        max_range_m: ray length, metres.
        seed: random seed.
    """

    count: int = 200
    width: int = 2048
    height: int = 256
    frames_per_track: int = 10
    step_m: float = 25.0
    shore_m: tuple[float, float] = (40.0, 1500.0)
    camera_height_m: tuple[float, float] = (1.5, 3.0)
    tilt_deg: float = 3.0
    degraded_fraction: float = 0.0
    gps_noise_m: float = 0.0
    compass_noise_deg: float = 2.0
    render_bins: int = 4096
    label_bins: int = 2048
    max_range_m: float = 8000.0
    seed: int = 0


def random_trajectories(dem: Dem, settings: DatasetSettings, rng: np.random.Generator) -> np.ndarray:
    """Boat poses along random trajectories over water.

    Each trajectory starts on a random water cell between ``shore_m`` distances from land, then turns by a
    random 8-degree walk and steps ``step_m`` per frame, turning away when the next step would leave the
    allowed water. The camera's forward axis has a random mount offset from the course; pitch and roll follow
    slow sinusoids (wave motion) plus jitter.

    Returns:
        (count, 6) poses (x, y, camera height, heading, pitch, roll) in metres and radians.
    """
    sea = (dem.z <= 0).astype(np.uint8)
    shore = cv2.distanceTransform(sea, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * dem.cell
    rows, cols = dem.z.shape
    margin = settings.max_range_m / 8
    ok = (shore >= settings.shore_m[0]) & (shore <= settings.shore_m[1])
    rr, cc = np.nonzero(ok)
    x = dem.x0 + (cc + 0.5) * dem.cell
    y = dem.y0 - (rr + 0.5) * dem.cell
    west, south, east, north = dem.bounds
    inner = (x > west + margin) & (x < east - margin) & (y > south + margin) & (y < north - margin)
    if not inner.any():
        raise InputError(f"the DEM has no water {settings.shore_m} m from land away from its edges")
    starts = np.stack([x[inner], y[inner]], -1)

    def allowed(p: np.ndarray) -> bool:
        c = int((p[0] - dem.x0) // dem.cell)
        r = int((dem.y0 - p[1]) // dem.cell)
        inside = west + margin < p[0] < east - margin and south + margin < p[1] < north - margin
        return inside and 0 <= r < rows and 0 <= c < cols and bool(ok[r, c])

    poses = []
    tilt = math.radians(settings.tilt_deg)
    while len(poses) < settings.count:
        p = starts[rng.integers(len(starts))].astype(np.float64)
        course = rng.uniform(0, 2 * math.pi)
        mount = rng.uniform(0, 2 * math.pi)
        cam_h = rng.uniform(*settings.camera_height_m)
        amp = tilt * rng.uniform(0.3, 1.0, 2)
        period = rng.uniform(4.0, 9.0, 2)  # frames per wave cycle
        phase = rng.uniform(0, 2 * math.pi, 2)
        for frame in range(settings.frames_per_track):
            pitch, roll = amp * np.sin(2 * math.pi * frame / period + phase) + rng.normal(0, 0.15 * tilt, 2)
            poses.append([p[0], p[1], cam_h, (course + mount) % (2 * math.pi), pitch, roll])
            if len(poses) == settings.count:
                break
            for _ in range(12):
                turn = course + rng.normal(0, math.radians(8))
                step = settings.step_m * np.array([math.sin(turn), math.cos(turn)])
                if allowed(p + step):
                    course, p = turn, p + step
                    break
                course = rng.uniform(0, 2 * math.pi)
            else:
                break  # boxed in: start a new trajectory
    return np.asarray(poses, dtype=np.float64)


#: Folder of a dataset being written: one archive per finished batch, removed when the dataset is complete.
PARTIAL_DIR = ".partial"


def _job(dem: Dem, settings: DatasetSettings, batch: int) -> dict:
    """What a dataset folder is being written from (a resumed job must match it)."""
    return json.loads(json.dumps({"settings": asdict(settings), "batch": batch, "dem": dem_fingerprint(dem)}))


def _start_or_resume(out: Path, job: dict) -> Path:
    """The partial folder of ``out``, emptied unless it holds batches of the same ``job``."""
    partial = out / PARTIAL_DIR
    job_file = partial / "job.json"
    if partial.is_dir() and not (job_file.is_file() and json.loads(job_file.read_text()) == job):
        shutil.rmtree(partial)
    if not partial.is_dir():
        partial.mkdir(parents=True)
        write_text(job_file, json.dumps(job, indent=1))
    return partial


def write_dataset(
    out: str | Path, dem: Dem, settings: DatasetSettings, batch: int = 4, progress: bool = True
) -> Path:
    """Render, label and write a dataset (layout in the module docstring); returns ``out``.

    Resumable: every finished batch of ``batch`` panoramas is kept in ``out/.partial/`` (its images, labels,
    truth and the random generator's state after it), so a rerun after an interruption continues at the first
    unfinished batch and writes the same files as an uninterrupted run. ``meta.json`` is written last; a folder
    with a ``meta.json`` of the same settings is complete and returned as it is, one of other settings is an
    ``InputError``.
    """
    if settings.count < 1 or settings.render_bins < settings.width:
        raise InputError("count must be >= 1 and render_bins >= width")
    if batch < 1:
        raise InputError(f"batch must be >= 1, got {batch}")
    out = Path(out)
    meta = json.loads(json.dumps({"count": settings.count, "settings": asdict(settings), "dem": "dem.tif",
                                  "images": "images/{index:06d}.png"}))
    if (out / "meta.json").is_file():
        if json.loads((out / "meta.json").read_text()).get("settings") == meta["settings"]:
            return out
        raise InputError(f"{out} already holds a horizon dataset with other settings; write to another folder")
    job = _job(dem, settings, batch)
    partial = _start_or_resume(writable_folder(out), job)
    rng = np.random.default_rng(settings.seed)
    generator = torch.Generator().manual_seed(settings.seed)
    poses = random_trajectories(dem, settings, rng)
    count = meta["count"] = len(poses)
    degraded = rng.random(count) < settings.degraded_fraction
    gps = poses[:, :2] + rng.normal(0, settings.gps_noise_m, (count, 2))
    compass = (poses[:, 3] + rng.normal(0, math.radians(settings.compass_noise_deg), count)) % (2 * math.pi)
    renderer = VirtualHorizon(dem, bins=settings.render_bins, max_range=settings.max_range_m,
                              step=dem.cell / 2)
    labeller = ClassicalHorizon(VirtualHorizon(dem, bins=settings.label_bins, max_range=settings.max_range_m,
                                               step=dem.cell))
    starts = range(0, count, batch)
    for start in tqdm(starts, desc="render + label", disable=not progress, unit="batch"):
        shard = partial / f"batch_{start:06d}.npz"
        if shard.is_file():  # finished before an interruption: continue from its generator state
            with np.load(shard) as done:
                generator.set_state(torch.from_numpy(done["generator_state"]))
            continue
        index = np.arange(start, min(start + batch, count))
        clean = Appearance.sample(len(index), False, generator)
        heavy = Appearance.sample(len(index), True, generator)
        pick = torch.from_numpy(degraded[index])
        appearance = Appearance(*(torch.where(pick, getattr(heavy, k), getattr(clean, k))
                                  for k in Appearance.__dataclass_fields__))
        image, gt = render_panorama(renderer, torch.from_numpy(poses[index]).float(), settings.width,
                                    settings.height, appearance, generator)
        image8 = (image * 255).round().to(torch.uint8)
        for i, k in enumerate(index):
            _, png = cv2.imencode(".png", image8[i].permute(1, 2, 0).numpy()[..., ::-1])
            write_bytes(out / "images" / f"{k:06d}.png", png.tobytes())
        # Label what was stored (8-bit), as a real camera pipeline would.
        lab = labeller(image8.float() / 255, torch.from_numpy(gps[index]), torch.from_numpy(poses[index, 2]),
                       torch.from_numpy(compass[index]))
        arrays = {f"label_{k}": getattr(lab, k).cpu().numpy() for k in LABEL_KEYS}
        arrays |= {f"truth_{k}": getattr(gt, k).double().cpu().numpy() for k in TRUTH_KEYS}
        arrays |= {f"appearance_{k}": getattr(appearance, k).numpy() for k in Appearance.__dataclass_fields__}
        write_npz(shard, generator_state=generator.get_state().numpy(), **arrays)
    batches = [dict(np.load(partial / f"batch_{start:06d}.npz")) for start in starts]

    def joined(prefix: str) -> dict[str, np.ndarray]:
        keys = [k for k in batches[0] if k.startswith(prefix)]
        return {k.removeprefix(prefix): np.concatenate([b[k] for b in batches]) for k in keys}

    write_npz(out / "labels.npz", gps=gps, compass=compass, camera_height=poses[:, 2], **joined("label_"))
    appearance = {f"appearance_{k}": v for k, v in joined("appearance_").items()}
    write_npz(out / "truth.npz", pose=poses, degraded=degraded, **joined("truth_"), **appearance)
    with atomic_path(out / "dem.tif") as tmp:
        save_dem(tmp, dem)
    write_text(out / "meta.json", json.dumps(meta, indent=2))
    shutil.rmtree(partial)
    return out


def read_split(root: str | Path, name: str) -> dict[str, np.ndarray]:
    """Arrays of ``labels.npz`` or ``truth.npz`` (``name`` = "labels" or "truth") of a dataset directory."""
    path = Path(root) / f"{name}.npz"
    if not path.is_file():
        raise InputError(f"horizon dataset file not found: {path} (create it with `infer.py render-dataset`)")
    with np.load(path) as data:
        return {k: data[k] for k in data.files}

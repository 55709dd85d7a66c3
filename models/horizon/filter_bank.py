"""A bank of 1-D MOSSE filters over the sea of a DEM (thesis ch. 4.4, "Horizon matching").

Every sea location of a square grid (spacing a few metres) gets one MOSSE filter trained on the virtual
horizons rendered from a 50 x 50 m neighbourhood around it, with a Gaussian label at heading 0. Profiles are
in the world frame: bin j looks at azimuth ``2 pi j / N`` clockwise from north.

Sample sharing: the training horizons of a location are the horizons of the grid points in its neighbourhood
(every ``sample_step`` metres: 5 x 5 samples at offsets -20 .. 20 m by default), so each grid point is ray cast
once and serves up to M filters: building costs one ray cast per location instead of M. The samples are weighted
by a Gaussian of their distance (``sample_sigma``, 5 m by default; None = the plain MOSSE sum): with equal
weights the filters of neighbouring locations become nearly identical and the position blurs (measured in
docs/results.md). The grid is built in tiles of whole grid rows plus a halo of neighbourhood rows, one stored
chunk per tile.

Profile normalisation (:func:`profile_normalize`): elevations in degrees, divided by their maximum when that
exceeds ``norm_threshold_deg`` (the thesis's rule, "divide by the maximum if some h > 1.0"; its units are not
stated, degrees are assumed here), then the mean is removed. No log, no window, no unit variance (thesis
ch. 4.4): the profile is periodic, so circular correlation over the full circle is exact.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn
from tqdm import tqdm

from core.errors import InputError
from core.raycast import virtual_horizon
from data.horizon.bank_io import BankWriter, FilterBank
from data.world.dem import Dem, dem_fingerprint
from models.dcf.mosse import Mosse, mosse_filter, mosse_train
from models.distributed import barrier, is_primary_process


@dataclass(frozen=True)
class BankSettings:
    """How a filter bank is built.

    Attributes:
        spacing: grid spacing in metres (5-10 m in the thesis's setting).
        bins: azimuth bins of a profile over 360 degrees.
        camera_height: camera height above the sea in metres, for the virtual horizons.
        neighbourhood: side of the square neighbourhood whose horizons train a filter, metres (50 in the thesis).
        sample_step: distance between training samples inside the neighbourhood, metres (rounded to grid steps).
        sample_sigma: samples are weighted by a Gaussian of their distance from the location with this std,
            metres (None = equal weights, plain MOSSE sums).
        sigma: standard deviation of the Gaussian label, bins.
        eps_rel: MOSSE regularisation relative to the mean energy of the samples.
        norm_threshold_deg: profiles whose highest elevation exceeds this (degrees) are divided by it.
        frequencies: stored half-spectrum length K (band limit, 2 <= K <= bins // 2 + 1); None = all.
        max_range: ray length of the virtual horizons, metres.
        ray_step: sample distance along the rays, metres (None = one DEM cell).
    """

    spacing: float = 5.0
    bins: int = 1024
    camera_height: float = 2.0
    neighbourhood: float = 50.0
    sample_step: float = 10.0
    sample_sigma: float | None = 5.0
    sigma: float = 1.0
    eps_rel: float = 0.01
    norm_threshold_deg: float = 1.0
    frequencies: int | None = None
    max_range: float = 4000.0
    ray_step: float | None = None

    def __post_init__(self) -> None:
        checks = {
            "spacing": self.spacing > 0, "bins": self.bins >= 16, "camera_height": self.camera_height > 0,
            "neighbourhood": self.neighbourhood >= 0, "sample_step": self.sample_step > 0,
            "sample_sigma": self.sample_sigma is None or self.sample_sigma > 0, "sigma": self.sigma > 0,
            "eps_rel": self.eps_rel > 0, "max_range": self.max_range > 0,
            "ray_step": self.ray_step is None or self.ray_step > 0,
            "frequencies": self.frequencies is None or 2 <= self.frequencies <= self.bins // 2 + 1,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise InputError(f"bad filter bank settings: {', '.join(f'{k}={getattr(self, k)}' for k in bad)}")

    @property
    def half_spectrum(self) -> int:
        """Stored frequencies K."""
        return self.frequencies or self.bins // 2 + 1

    def sample_offsets(self) -> list[tuple[int, int]]:
        """Grid offsets (d_row, d_col) of the training samples of a location (the location itself included)."""
        stride = max(1, round(self.sample_step / self.spacing))
        reach = int(math.floor(self.neighbourhood / 2 / (stride * self.spacing) + 1e-9))
        steps = [k * stride for k in range(-reach, reach + 1)]
        return [(dr, dc) for dr in steps for dc in steps]

    def sample_weights(self) -> list[float]:
        """Weight of each of :meth:`sample_offsets` (1 at the location itself)."""
        if self.sample_sigma is None:
            return [1.0] * len(self.sample_offsets())
        scale = self.spacing / self.sample_sigma
        return [math.exp(-0.5 * (dr * dr + dc * dc) * scale * scale) for dr, dc in self.sample_offsets()]

    def to_dict(self) -> dict:
        return asdict(self)


def profile_normalize(profile: Tensor, threshold_deg: float = 1.0) -> Tensor:
    """The thesis's profile normalisation, then mean removal.

    Args:
        profile: ``(..., N)`` tan elevation of the horizon per azimuth bin.
        threshold_deg: profiles whose maximum elevation (degrees) exceeds this are divided by that maximum.
    Returns:
        ``(..., N)`` elevations in degrees (or in units of the maximum), zero mean.
    """
    if not isinstance(profile, Tensor) or not profile.is_floating_point() or profile.dim() < 1:
        raise InputError("profile must be a floating tensor (..., N)")
    degrees = torch.rad2deg(torch.atan(profile))
    peak = degrees.amax(-1, keepdim=True)
    degrees = degrees / torch.where(peak > threshold_deg, peak, torch.ones_like(peak))
    return degrees - degrees.mean(-1, keepdim=True)


class ProfileNormalize(nn.Module):
    """Module form of :func:`profile_normalize`."""

    def __init__(self, threshold_deg: float = 1.0) -> None:
        super().__init__()
        self.threshold_deg = threshold_deg

    def forward(self, profile: Tensor) -> Tensor:
        return profile_normalize(profile, self.threshold_deg)


def bank_mosse(settings: BankSettings) -> Mosse:
    """The 1-D MOSSE of the bank: no log, no standardisation, no window (profiles are normalised before)."""
    return Mosse(ndim=1, sigma=settings.sigma, eps=0.0, eps_rel=settings.eps_rel, log=False, normalize=False,
                 window=False)


def train_location_filters(samples: Tensor, valid: Tensor, settings: BankSettings) -> Tensor:
    """MOSSE filters of locations from their neighbourhood horizons (eq. 3.4), samples weighted by
    ``settings.sample_weights()`` (``A = sum w Y conj(X)``, ``B = sum w |X|^2``: samples and labels scaled by
    ``sqrt(w)``).

    Args:
        samples: ``(L, M, N)`` tan elevation profiles of the M neighbourhood samples of each location.
        valid: ``(L, M)`` bool, sample exists (on the sea and on the grid); invalid samples contribute nothing.
    Returns:
        ``(L, K)`` complex conjugate filter spectra ``H*`` (band-limited to ``settings.half_spectrum``).
    """
    if samples.dim() != 3 or valid.shape != samples.shape[:2]:
        raise InputError(f"samples must be (L, M, N) with valid (L, M), got {tuple(samples.shape)}, "
                         f"{tuple(valid.shape)}")
    mosse = bank_mosse(settings)
    weights = torch.tensor(settings.sample_weights(), dtype=samples.dtype, device=samples.device)
    if weights.shape[0] != samples.shape[1]:
        raise InputError(f"need {weights.shape[0]} samples per location for these settings, got {samples.shape[1]}")
    root = (weights.sqrt() * valid.to(samples.dtype))[..., None]  # (L, M, 1)
    x = profile_normalize(samples, settings.norm_threshold_deg) * root
    A, B = mosse_train(x, mosse.label(x) * root, 1)
    H = mosse_filter(A, B, 1, mosse.eps, mosse.eps_rel)
    return H[..., : settings.half_spectrum]


@dataclass(frozen=True)
class BankGrid:
    """The square grid of candidate locations, aligned with the DEM.

    Attributes:
        x0, y0: map coordinates of grid point (0, 0) (north-west), metres.
        spacing: metres; rows run south, columns east.
        rows, cols: grid size.
    """

    x0: float
    y0: float
    spacing: float
    rows: int
    cols: int

    def xy(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Map coordinates (..., 2) of grid points."""
        return np.stack([self.x0 + np.asarray(col) * self.spacing, self.y0 - np.asarray(row) * self.spacing], -1)

    def cell_of(self, xy: np.ndarray) -> np.ndarray:
        """Fractional (row, col) (..., 2) of map points."""
        xy = np.asarray(xy, dtype=np.float64)
        return np.stack([(self.y0 - xy[..., 1]) / self.spacing, (xy[..., 0] - self.x0) / self.spacing], -1)


def bank_grid(dem: Dem, spacing: float, bounds: tuple[float, float, float, float] | None = None) -> BankGrid:
    """Grid of spacing ``spacing`` over the DEM (or the part of it inside ``bounds`` = (west, south, east, north))."""
    west, south, east, north = dem.bounds
    if bounds is not None:
        w, s, e, n = bounds
        if not (w < e and s < n):
            raise InputError(f"bounds must be (west, south, east, north) with west < east, south < north: {bounds}")
        west, south, east, north = max(west, w), max(south, s), min(east, e), min(north, n)
        if not (west < east and south < north):
            raise InputError(f"bounds {bounds} do not overlap the DEM {dem.bounds}")
    cols = int(math.floor((east - west) / spacing))
    rows = int(math.floor((north - south) / spacing))
    if rows < 1 or cols < 1:
        raise InputError(f"spacing {spacing} m is larger than the area {east - west:.0f} x {north - south:.0f} m")
    return BankGrid(west + spacing / 2, north - spacing / 2, spacing, rows, cols)


def sea_mask(dem: Dem, grid: BankGrid, rows: np.ndarray | None = None, cols: np.ndarray | None = None) -> np.ndarray:
    """(R, C) bool, grid point lies on the sea (DEM height 0) inside the DEM; ``rows``, ``cols`` select grid
    rows and columns (default all; indices outside the grid extend it)."""
    rows = np.arange(grid.rows) if rows is None else np.asarray(rows)
    cols = np.arange(grid.cols) if cols is None else np.asarray(cols)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    xy = grid.xy(rr, cc)
    return (dem.height_at(xy) <= 0) & dem.contains(xy)


class BankTiles:
    """The tiles of a bank build (strips of whole grid rows, ray cast with a halo of neighbourhood rows): tile
    ``index`` -> (filters (L, 2K) float32 (re, im) of ``H*``, grid cells (L, 2)) of its sea locations.

    Args:
        dem, settings, grid: the flooded DEM, the bank settings and the location grid.
        tile_points: grid points per tile (memory: about ``tile_points * bins * 4`` bytes of horizons).
        device: where to ray cast and train.
    """

    def __init__(self, dem: Dem, settings: BankSettings, grid: BankGrid, tile_points: int = 2**15,
                 device: torch.device | str | None = None) -> None:
        if tile_points < 1:
            raise InputError(f"tile_points must be at least 1, got {tile_points}")
        self.dem, self.settings, self.grid = dem, settings, grid
        self.offsets = settings.sample_offsets()
        self.halo = max(abs(dr) for dr, _ in self.offsets)
        self.tile_rows = max(1, tile_points // grid.cols)
        self.starts = list(range(0, grid.rows, self.tile_rows))
        self.heights = torch.from_numpy(np.ascontiguousarray(dem.z, dtype=np.float32)).to(device)
        self.ext_cols = np.arange(-self.halo, grid.cols + self.halo)

    def __len__(self) -> int:
        return len(self.starts)

    @torch.no_grad()
    def __call__(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        dem, settings, grid, halo, heights = self.dem, self.settings, self.grid, self.halo, self.heights
        r0 = self.starts[index]
        r1 = min(r0 + self.tile_rows, grid.rows)
        rows = np.arange(r0 - halo, r1 + halo)
        sea = sea_mask(dem, grid, rows, self.ext_cols)
        rr, cc = np.meshgrid(rows, self.ext_cols, indexing="ij")
        positions = torch.from_numpy(grid.xy(rr[sea], cc[sea])).to(heights)
        profiles = torch.zeros(*sea.shape, settings.bins, dtype=heights.dtype, device=heights.device)
        if len(positions):
            horizons = virtual_horizon(heights, dem.x0, dem.y0, dem.cell, positions, settings.camera_height,
                                       settings.bins, settings.max_range, settings.ray_step or dem.cell)
            profiles[torch.from_numpy(sea).to(heights.device)] = horizons.horizon
        inner = np.zeros_like(sea)
        inner[halo : halo + r1 - r0, halo : halo + grid.cols] = True
        li, lj = np.nonzero(sea & inner)
        filters = [np.zeros((0, 2 * settings.half_spectrum), np.float32)]
        for s in range(0, len(li), 4096):
            i, j = li[s : s + 4096], lj[s : s + 4096]
            si = np.stack([i + dr for dr, _ in self.offsets], 1)
            sj = np.stack([j + dc for _, dc in self.offsets], 1)
            samples = profiles[torch.from_numpy(si), torch.from_numpy(sj)]
            valid = torch.from_numpy(sea[si, sj]).to(heights.device)
            H = train_location_filters(samples, valid, settings)
            filters.append(torch.view_as_real(H).flatten(-2).cpu().numpy())
        return np.concatenate(filters), np.stack([li - halo + r0, lj - halo], -1)


def build_filter_bank(
    dem: Dem,
    settings: BankSettings,
    out: str | Path,
    bounds: tuple[float, float, float, float] | None = None,
    storage_dtype: str = "float16",
    tile_points: int = 2**15,
    source: str | None = None,
    sea_level: float = 0.0,
    overwrite: bool = False,
    progress: bool = True,
    device: torch.device | str | None = None,
    devices: int = 1,
) -> FilterBank:
    """Build and store the filter bank of every sea grid location (module docstring), tile by tile.

    Args:
        dem: the flooded DEM.
        settings: bank settings.
        out: bank directory (see ``data.horizon.bank_io``); an interrupted build of the same bank resumes.
        bounds: (west, south, east, north) metres to cover only part of the DEM (default: all of it).
        storage_dtype: ``float16`` (half the size) or ``float32``.
        tile_points: grid points per tile (memory: about ``tile_points * bins * 4`` bytes of horizons).
        source, sea_level: recorded with the DEM fingerprint, for error messages.
        device: where to ray cast and train (default CPU); with ``devices`` > 1, ``cuda`` means GPUs.
        devices: processes of a distributed build (Lightning DDP ``predict`` over the tiles,
            ``models.horizon.bank_distributed``): each writes the chunks of its tiles, the first one the manifest
            when all are done. The chunks equal a single process's with the same threads per process.
    Returns:
        The opened ``FilterBank``.
    """
    grid = bank_grid(dem, settings.spacing, bounds)
    tiles = BankTiles(dem, settings, grid, tile_points, device if devices == 1 else None)
    meta = {
        "settings": {**settings.to_dict(), "half_spectrum": settings.half_spectrum, "samples": len(tiles.offsets)},
        "grid": asdict(grid),
        "bounds": list(bounds) if bounds is not None else None,
        "dem": {"fingerprint": dem_fingerprint(dem), "source": source, "sea_level": sea_level,
                "shape": list(dem.z.shape), "cell": dem.cell, "crs": dem.crs},
        "storage_dtype": storage_dtype,
    }
    writer = BankWriter(out, meta, overwrite, primary=is_primary_process())
    if devices > 1:
        from models.horizon.bank_distributed import build_distributed

        accelerator = "gpu" if str(device or "cpu").startswith("cuda") else "cpu"
        if build_distributed(tiles, writer, devices, accelerator, progress):
            writer.finish(len(tiles))
        barrier()
        return FilterBank(out)
    for index in tqdm(range(len(tiles)), desc="filter bank", unit="tile", disable=not progress):
        if not writer.has_chunk(index):
            writer.write_chunk(index, *tiles(index))
    writer.finish(len(tiles))
    return FilterBank(out)

"""Digital elevation models (DEMs) of an archipelago: procedural generator, flooding and I/O (ch. 4.1).

A ``Dem`` is a north-up raster of heights in metres above sea level, the sea at exactly 0 m. World coordinates
are metric map coordinates (x east, y north, metres) in the DEM's CRS; cell (row, col) has its centre at
``x = x0 + (col + 0.5) * cell``, ``y = y0 - (row + 0.5) * cell`` ((x0, y0) is the north-west corner, as in a
GeoTIFF geotransform). Everything outside the raster is sea.

Any real DEM becomes an archipelago by flooding: heights at or below the chosen sea level become sea (0 m) and
the rest are re-referenced to that sea level (``flood``, ``load_dem(..., sea_level=...)``). GeoTIFFs are read
and written with rasterio (CRS and transform kept), ``.npz`` files hold ``z``, ``transform`` (x0, cell, y0)
and ``crs``. Missing values (nodata, NaN) count as sea.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError

GEOTIFF_SUFFIXES = (".tif", ".tiff")


@dataclass(frozen=True)
class Dem:
    """A north-up square-cell DEM.

    Attributes:
        z: (H, W) float32 heights in metres above sea level (sea = 0, never negative); row 0 is north.
        x0: x (east) of the west edge in metres.
        y0: y (north) of the north edge in metres.
        cell: cell size in metres.
        crs: CRS as a string understood by rasterio (e.g. ``"EPSG:3006"``), or None when unknown.
    """

    z: np.ndarray
    x0: float = 0.0
    y0: float = 0.0
    cell: float = 5.0
    crs: str | None = None

    def __post_init__(self) -> None:
        if self.z.ndim != 2 or min(self.z.shape) < 2:
            raise InputError(f"DEM heights must be a 2-D array of >= 2 x 2 cells, got shape {self.z.shape}")
        if not np.isfinite(self.z).all() or (self.z < 0).any():
            raise InputError("DEM heights must be finite and >= 0 (flood the DEM first: sea = 0 m)")
        if not self.cell > 0:
            raise InputError(f"DEM cell size must be positive, got {self.cell}")

    @property
    def shape(self) -> tuple[int, int]:
        return self.z.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(west, south, east, north) edges in metres."""
        rows, cols = self.z.shape
        return self.x0, self.y0 - rows * self.cell, self.x0 + cols * self.cell, self.y0

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether points lie inside the raster. xy: (..., 2) metres (x east, y north); returns (...) bool."""
        xy = np.asarray(xy, dtype=np.float64)
        west, south, east, north = self.bounds
        return (xy[..., 0] >= west) & (xy[..., 0] <= east) & (xy[..., 1] >= south) & (xy[..., 1] <= north)

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Height of the cell holding each point (sea outside). xy: (..., 2) m; returns (...) m."""
        xy = np.asarray(xy, dtype=np.float64)
        col = np.floor((xy[..., 0] - self.x0) / self.cell).astype(np.int64)
        row = np.floor((self.y0 - xy[..., 1]) / self.cell).astype(np.int64)
        inside = (row >= 0) & (row < self.z.shape[0]) & (col >= 0) & (col < self.z.shape[1])
        rows, cols = self.z.shape
        return np.where(inside, self.z[row.clip(0, rows - 1), col.clip(0, cols - 1)], 0.0)

    def from_lonlat(self, lonlat: np.ndarray) -> np.ndarray:
        """WGS84 (longitude, latitude) degrees (..., 2) to the DEM's map coordinates (..., 2) metres."""
        if self.crs is None:
            raise InputError("the DEM has no CRS, which is needed to place longitude/latitude positions on it")
        from rasterio.warp import transform

        lonlat = np.asarray(lonlat, dtype=np.float64)
        x, y = transform("EPSG:4326", self.crs, lonlat[..., 0].ravel(), lonlat[..., 1].ravel())
        return np.stack([np.asarray(x), np.asarray(y)], -1).reshape(lonlat.shape)

    def check_positions(self, xy: np.ndarray, name: str = "position") -> None:
        """Raise ``InputError`` naming the first point of xy (..., 2) that lies outside the DEM."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        outside = ~self.contains(xy)
        if outside.any():
            x, y = xy[np.flatnonzero(outside)[0]]
            west, south, east, north = self.bounds
            raise InputError(
                f"{name} ({x:.1f}, {y:.1f}) m lies outside the DEM "
                f"(x {west:.1f}..{east:.1f}, y {south:.1f}..{north:.1f})"
            )


def fractal_noise(
    shape: tuple[int, int],
    beta: float,
    rng: np.random.Generator,
    corner: float = 0.0,
    anisotropy: float = 1.0,
) -> np.ndarray:
    """Zero-mean unit-variance fractal (1/f) noise by spectral synthesis.

    Args:
        shape: (H, W) output size.
        beta: spectral exponent: power ~ 1 / |f| ** beta (2 = rough, 3-4 = terrain-like smooth).
        rng: random generator.
        corner: frequency (cycles per sample) below which the spectrum flattens, i.e. the largest feature size
            is about ``1 / corner`` samples; 0 = pure power law.
        anisotropy: frequency scale along rows relative to columns (> 1 stretches features horizontally).

    Returns:
        (H, W) float64 array, periodic in both directions.
    """
    fy = np.fft.fftfreq(shape[0])[:, None] * anisotropy
    fx = np.fft.rfftfreq(shape[1])[None, :]
    radius = np.hypot(np.hypot(fx, fy), corner)
    radius[0, 0] = np.inf
    spectrum = np.fft.rfft2(rng.standard_normal(shape)) * radius ** (-beta / 2)
    noise = np.fft.irfft2(spectrum, s=shape)
    return (noise - noise.mean()) / noise.std()


def generate_archipelago(
    size_m: float = 16000.0,
    cell: float = 5.0,
    seed: int = 0,
    land_fraction: float = 0.12,
    max_height: float = 30.0,
    forest_height: float = 15.0,
    feature_scale_m: float = 1500.0,
    beta: float = 3.2,
    x0: float = 0.0,
    y0: float | None = None,
    crs: str | None = "EPSG:3006",
) -> Dem:
    """Procedural archipelago: islands and islets from fractal noise, sea at 0 m, optional forest on land.

    The noise field is thresholded at its ``1 - land_fraction`` quantile; land rises with the square root of
    the height above the threshold (steep shores, rounded tops like scoured skerries) to ``max_height``.
    Forest (canopy ``forest_height`` m, varying +-30 %) grows on land further than ~2 cells from the shore.

    Args:
        size_m: side of the square area in metres.
        cell: cell size in metres.
        seed: random seed.
        land_fraction: fraction of cells that are land, in (0, 1).
        max_height: highest ground in metres.
        forest_height: mean canopy height in metres (0 = bare ground).
        feature_scale_m: largest island size in metres (the noise spectrum is flat at longer wavelengths).
        beta: spectral exponent of the terrain noise.
        x0, y0: north-west corner in metres (``y0`` defaults to ``size_m``, so the area spans 0..size_m).
        crs: CRS string stored with the DEM (default SWEREF99 TM).

    Returns:
        The ``Dem``.
    """
    if not 0 < land_fraction < 1:
        raise InputError(f"land_fraction must be in (0, 1), got {land_fraction}")
    n = int(round(size_m / cell))
    if n < 8:
        raise InputError(f"size_m / cell must give at least 8 cells, got {size_m} / {cell}")
    rng = np.random.default_rng(seed)
    noise = fractal_noise((n, n), beta, rng, corner=cell / feature_scale_m)
    threshold = np.quantile(noise, 1.0 - land_fraction)
    above = np.clip(noise - threshold, 0.0, None)
    ground = max_height * np.sqrt(above / above.max())
    z = ground
    if forest_height > 0:
        land = (ground > 0).astype(np.uint8)
        shore_distance = cv2.distanceTransform(land, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        canopy = forest_height * (1.0 + 0.3 * np.tanh(fractal_noise((n, n), 2.5, rng)))
        grow = np.clip((shore_distance - 2.0) / 2.0, 0.0, 1.0)
        z = ground + canopy * grow
    return Dem(z.astype(np.float32), x0=x0, y0=size_m if y0 is None else y0, cell=cell, crs=crs)


def flood(z: np.ndarray, sea_level: float = 0.0, nodata: float | None = None) -> np.ndarray:
    """Heights relative to ``sea_level`` with everything at or below it (and nodata/NaN) set to sea (0 m).

    Args:
        z: (H, W) heights in metres.
        sea_level: water level in metres in the heights' datum.
        nodata: value marking missing cells, or None.

    Returns:
        (H, W) float32 heights >= 0.
    """
    z = np.asarray(z, dtype=np.float64)
    missing = ~np.isfinite(z)
    if nodata is not None:
        missing |= z == nodata
    return np.where(missing, 0.0, np.clip(z - sea_level, 0.0, None)).astype(np.float32)


def _check_transform(a: float, b: float, c: float, d: float, e: float, f: float, path: Path) -> tuple:
    if abs(b) > 1e-9 * abs(a) or abs(d) > 1e-9 * abs(a) or a <= 0 or e >= 0:
        raise InputError(f"DEM {path}: only north-up rasters are supported, got {(a, b, c, d, e, f)}")
    if abs(a + e) > 1e-6 * a:
        raise InputError(f"DEM {path}: cells must be square, got {a} x {-e}")
    return c, f, a


def check_heights(z: np.ndarray, path: str | Path) -> np.ndarray:
    """``z`` unless it holds infinite heights (NaN and nodata cells are sea; an infinity is a broken file)."""
    infinite = int(np.isinf(z).sum())
    if infinite:
        raise InputError(f"DEM {path} has {infinite} infinite heights (NaN and nodata cells are read as sea)")
    return z


def load_dem(path: str | Path, sea_level: float = 0.0, require_crs: bool = False) -> Dem:
    """Read a GeoTIFF (rasterio) or ``.npz`` DEM and flood it at ``sea_level``.

    Args:
        path: ``.tif``/``.tiff`` (first band) or ``.npz`` (``z``, ``transform`` = (x0, cell, y0), ``crs``).
        sea_level: heights at or below this (in the file's datum) become sea.
        require_crs: raise if the file has no CRS (needed when positions come in another reference system).

    Returns:
        The flooded ``Dem``. A geographic CRS (degrees) is refused: ray casting needs metric coordinates.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"DEM file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in GEOTIFF_SUFFIXES:
        import rasterio

        try:
            with rasterio.open(path) as src:
                z = src.read(1, masked=False).astype(np.float64)
                x0, y0, cell = _check_transform(*tuple(src.transform)[:6], path)
                nodata = src.nodata
                crs = src.crs
        except rasterio.errors.RasterioError as err:
            raise InputError(f"DEM {path} is not a readable GeoTIFF: {err}") from err
        if crs is not None and crs.is_geographic:
            raise InputError(f"DEM {path} has a geographic CRS ({crs}); reproject it to a metric CRS first")
        crs_text = crs.to_string() if crs is not None else None
    elif suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                z = np.asarray(data["z"], dtype=np.float64)
                x0, cell, y0 = (float(v) for v in np.asarray(data["transform"], dtype=np.float64).ravel())
                crs_text = str(data["crs"]) if "crs" in data and str(data["crs"]) else None
        except (KeyError, ValueError, OSError) as err:
            message = f"DEM {path} is not a DEM .npz (z, transform = (x0, cell, y0), crs): {err}"
            raise InputError(message) from err
        nodata = None
    else:
        raise InputError(f"DEM {path}: unknown format {suffix!r} (use .tif, .tiff or .npz)")
    if require_crs and crs_text is None:
        raise InputError(f"DEM {path} has no CRS, but one is needed (positions are given in map coordinates)")
    return Dem(flood(check_heights(z, path), sea_level, nodata), x0=x0, y0=y0, cell=cell, crs=crs_text)


def save_dem(path: str | Path, dem: Dem) -> None:
    """Write ``dem`` as a GeoTIFF (float32, deflate, CRS and transform) or ``.npz``, chosen by the suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in GEOTIFF_SUFFIXES:
        import rasterio
        from rasterio.transform import Affine

        profile = {
            "driver": "GTiff",
            "height": dem.z.shape[0],
            "width": dem.z.shape[1],
            "count": 1,
            "dtype": "float32",
            "crs": dem.crs,
            "transform": Affine(dem.cell, 0.0, dem.x0, 0.0, -dem.cell, dem.y0),
            "compress": "deflate",
        }
        with rasterio.open(path, "w", **profile) as dst:
            dst.write(dem.z.astype(np.float32), 1)
    elif suffix == ".npz":
        np.savez_compressed(
            path,
            z=dem.z.astype(np.float32),
            transform=np.array([dem.x0, dem.cell, dem.y0]),
            crs=dem.crs or "",
        )
    else:
        raise InputError(f"DEM {path}: unknown format {suffix!r} (use .tif, .tiff or .npz)")


def dem_fingerprint(dem: Dem) -> str:
    """SHA-256 (hex) of the DEM's flooded float32 heights, shape and geotransform."""
    digest = hashlib.sha256()
    z = np.ascontiguousarray(dem.z, dtype=np.float32)
    digest.update(np.asarray(z.shape, dtype=np.int64).tobytes())
    digest.update(np.asarray([dem.x0, dem.y0, dem.cell], dtype=np.float64).tobytes())
    digest.update(z.tobytes())
    return digest.hexdigest()

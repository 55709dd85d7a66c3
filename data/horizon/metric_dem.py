"""Any GeoTIFF DEM as a metric DEM for localisation: geographic rasters are reprojected to their UTM zone.

``data.world.dem.load_dem`` reads metric DEMs (GeoTIFF or ``.npz``) and refuses a geographic CRS, which ray
casting cannot use. :func:`load_metric_dem` passes metric files through to it and reprojects a geographic
GeoTIFF (e.g. SRTM tiles in EPSG:4326) with rasterio to the WGS84 UTM zone of its centre, with square cells of
about the original ground resolution (bilinear, nodata kept as sea), before flooding at ``sea_level``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from core.errors import InputError
from data.world.dem import GEOTIFF_SUFFIXES, Dem, check_heights, flood, load_dem


def utm_crs(lon: float, lat: float) -> str:
    """EPSG code of the WGS84 UTM zone holding (lon, lat) degrees."""
    zone = int(math.floor((lon + 180.0) / 6.0)) % 60 + 1
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def load_metric_dem(path: str | Path, sea_level: float = 0.0) -> Dem:
    """A flooded metric ``Dem`` from any GeoTIFF or ``.npz`` DEM (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"DEM file not found: {path}")
    if path.suffix.lower() not in GEOTIFF_SUFFIXES:
        return load_dem(path, sea_level)
    import rasterio
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    try:
        with rasterio.open(path) as src:
            if src.crs is None or not src.crs.is_geographic:
                return load_dem(path, sea_level)
            west, south, east, north = src.bounds
            target = utm_crs((west + east) / 2, (south + north) / 2)
            lat = math.radians((south + north) / 2)
            cell = abs(src.transform.a) * 111320.0 * math.cos(lat)  # metres per pixel east-west
            transform, width, height = calculate_default_transform(
                src.crs, target, src.width, src.height, *src.bounds, resolution=(cell, cell))
            z = np.full((height, width), np.nan, dtype=np.float64)
            source = check_heights(src.read(1).astype(np.float64), path)
            if src.nodata is not None:
                source[source == src.nodata] = np.nan
            reproject(source, z, src_transform=src.transform, src_crs=src.crs, src_nodata=np.nan,
                      dst_transform=transform, dst_crs=target, dst_nodata=np.nan, resampling=Resampling.bilinear)
    except rasterio.errors.RasterioError as err:
        raise InputError(f"DEM {path} is not a readable GeoTIFF: {err}") from err
    return Dem(flood(z, sea_level), x0=transform.c, y0=transform.f, cell=transform.a, crs=target)

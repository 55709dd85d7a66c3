"""Any GeoTIFF DEM for the filter bank: a geographic raster is reprojected to UTM (checked against a closed-form
height ramp), and a real DEM flooded at a sea level gets a bank."""

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from rasterio.warp import transform as warp_points

from data.horizon.metric_dem import load_metric_dem, utm_crs
from models.horizon.filter_bank import BankSettings, build_filter_bank


def test_utm_zone():
    assert utm_crs(15.6, 56.2) == "EPSG:32633"  # Karlskrona
    assert utm_crs(-97.3, 32.7) == "EPSG:32614"
    assert utm_crs(151.2, -33.9) == "EPSG:32756"


def test_geographic_geotiff_is_reprojected(tmp_path):
    lon0, lat0, step = 15.50, 56.20, 0.0005  # about 31 x 56 m cells
    lon = lon0 + step * (np.arange(120) + 0.5)
    lat = lat0 - step * (np.arange(80) + 0.5)
    z = 1000 * (lon[None] - lon0) + 2000 * (lat0 - lat[:, None]) + 5  # metres, a ramp: 5 .. 165 m
    path = tmp_path / "geo.tif"
    profile = {"driver": "GTiff", "height": 80, "width": 120, "count": 1, "dtype": "float32", "crs": "EPSG:4326",
               "transform": from_origin(lon0, lat0, step, step), "nodata": -9999.0}
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(z.astype(np.float32), 1)
    dem = load_metric_dem(path, sea_level=50.0)
    assert dem.crs == "EPSG:32633"
    assert abs(dem.cell - step * 111320 * np.cos(np.radians(lat0 - 0.02))) < 1.0
    rows, cols = dem.z.shape
    rr, cc = np.meshgrid(np.arange(10, rows - 10, 7), np.arange(10, cols - 10, 7), indexing="ij")
    x, y = dem.x0 + (cc + 0.5) * dem.cell, dem.y0 - (rr + 0.5) * dem.cell
    plon, plat = warp_points(dem.crs, "EPSG:4326", x.ravel(), y.ravel())
    expected = np.clip(1000 * (np.array(plon) - lon0) + 2000 * (lat0 - np.array(plat)) + 5 - 50, 0, None)
    inside = (np.array(plon) > lon[1]) & (np.array(plon) < lon[-2]) & (np.array(plat) < lat[1]) & (
        np.array(plat) > lat[-2])
    got = dem.z[rr, cc].ravel()
    np.testing.assert_allclose(got[inside], expected[inside], atol=0.5)


def test_bank_on_real_dem_flooded(shared_data, tmp_path):
    dem = load_metric_dem(shared_data / "dem" / "pysheds_dem.tif", sea_level=200.0)
    assert 0.2 < (dem.z > 0).mean() < 0.9
    west, south, east, north = dem.bounds
    cx, cy = (west + east) / 2, (south + north) / 2
    settings = BankSettings(spacing=400, bins=128, max_range=6000, neighbourhood=0, camera_height=5)
    bank = build_filter_bank(dem, settings, tmp_path / "bank", bounds=(cx - 4000, cy - 4000, cx + 4000, cy + 4000),
                             progress=False)
    assert len(bank) > 10
    bank.check_dem(load_metric_dem(shared_data / "dem" / "pysheds_dem.tif", sea_level=200.0))
    with pytest.raises(ValueError, match="another DEM"):
        bank.check_dem(load_metric_dem(shared_data / "dem" / "pysheds_dem.tif", sea_level=210.0))

"""DEM generator, sea-level flooding and GeoTIFF / .npz round trips."""

import numpy as np
import pytest
import rasterio
from rasterio.transform import Affine

from core.errors import InputError
from data.world.dem import Dem, flood, generate_archipelago, load_dem, save_dem


def test_archipelago_land_fraction_sea_level_and_seed():
    kwargs = {"size_m": 2000, "cell": 10, "land_fraction": 0.2, "max_height": 25, "forest_height": 12}
    dem = generate_archipelago(seed=3, **kwargs)
    assert dem.z.shape == (200, 200)
    land = dem.z > 0
    assert abs(land.mean() - 0.2) < 0.01
    assert (dem.z[~land] == 0).all() and dem.z.min() == 0
    assert 25 <= dem.z.max() <= 25 + 12 * 1.3 + 1e-3
    # Forest makes inland cells taller than bare ground can be near the shore.
    assert np.percentile(dem.z[land], 90) > 12
    same, other = generate_archipelago(seed=3, **kwargs), generate_archipelago(seed=4, **kwargs)
    assert np.array_equal(dem.z, same.z) and not np.array_equal(dem.z, other.z)
    assert dem.bounds == (0.0, 0.0, 2000.0, 2000.0)


def test_flood_turns_terrain_into_archipelago():
    z = np.array([[-3.0, 1.0, 5.0], [2.0, np.nan, 7.5], [-9999.0, 4.0, 2.5]])
    out = flood(z, sea_level=2.0, nodata=-9999.0)
    expected = np.array([[0, 0, 3.0], [0, 0, 5.5], [0, 2.0, 0.5]], dtype=np.float32)
    np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize("suffix", [".tif", ".npz"])
def test_round_trip_keeps_heights_transform_and_crs(tmp_path, suffix):
    dem = generate_archipelago(size_m=640, cell=5, seed=1, x0=500000.0, y0=6230000.0)
    path = tmp_path / f"dem{suffix}"
    save_dem(path, dem)
    back = load_dem(path)
    np.testing.assert_array_equal(back.z, dem.z)
    assert (back.x0, back.y0, back.cell) == (500000.0, 6230000.0, 5.0)
    assert back.crs == "EPSG:3006"


def test_real_geotiff_with_sea_level_and_nodata(tmp_path):
    """A GeoTIFF written by rasterio directly (as a real DEM would be) is flooded at the chosen sea level."""
    z = np.array([[10.0, 12.0, -32768.0], [11.0, 14.0, 9.0], [30.0, 10.5, 10.0]], dtype=np.float32)
    path = tmp_path / "real.tif"
    transform = Affine(2.0, 0.0, 1000.0, 0.0, -2.0, 2000.0)
    with rasterio.open(path, "w", driver="GTiff", height=3, width=3, count=1, dtype="float32",
                       crs="EPSG:32633", transform=transform, nodata=-32768.0) as dst:
        dst.write(z, 1)
    dem = load_dem(path, sea_level=10.0)
    np.testing.assert_allclose(dem.z, [[0, 2, 0], [1, 4, 0], [20, 0.5, 0]])
    assert dem.crs == "EPSG:32633" and dem.cell == 2.0 and dem.bounds == (1000.0, 1994.0, 1006.0, 2000.0)
    assert dem.height_at(np.array([[1003.0, 1995.0]]))[0] == pytest.approx(0.5)


def test_bad_dem_inputs_give_clear_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_dem(tmp_path / "missing.tif")
    no_crs = tmp_path / "nocrs.tif"
    save_dem(no_crs, Dem(np.ones((4, 4), np.float32), cell=2.0, crs=None))
    assert load_dem(no_crs).crs is None
    with pytest.raises(InputError, match="no CRS"):
        load_dem(no_crs, require_crs=True)
    geographic = tmp_path / "wgs84.tif"
    with rasterio.open(geographic, "w", driver="GTiff", height=2, width=2, count=1, dtype="float32",
                       crs="EPSG:4326", transform=Affine(0.001, 0.0, 15.0, 0.0, -0.001, 56.0)) as dst:
        dst.write(np.ones((2, 2), np.float32), 1)
    with pytest.raises(InputError, match="geographic CRS"):
        load_dem(geographic)
    corrupt = tmp_path / "corrupt.tif"
    corrupt.write_bytes(b"not a tiff")
    with pytest.raises(InputError, match="not a readable GeoTIFF"):
        load_dem(corrupt)
    bad_npz = tmp_path / "bad.npz"
    np.savez(bad_npz, heights=np.ones((3, 3)))
    with pytest.raises(InputError, match="not a DEM .npz"):
        load_dem(bad_npz)
    (tmp_path / "x.png").write_bytes(b"x")
    with pytest.raises(InputError, match="unknown format"):
        load_dem(tmp_path / "x.png")
    dem = Dem(np.zeros((10, 10), np.float32), cell=5.0)
    with pytest.raises(InputError, match=r"outside the DEM"):
        dem.check_positions(np.array([[10.0, 20.0]]))

"""End-to-end ingest: DEM → store → Terrain, checked against the source raster."""

import numpy as np
import pytest
import rasterio

import geoterrain
from geoterrain.ingest.raster import read_raster
from tests.conftest import write_tif


def _roundtrip(src, tmp_path, **kw):
    out = geoterrain.preprocess(src, tmp_path / "s.geoterrain", **kw)
    t = geoterrain.open(out)
    r = read_raster(src, band=kw.get("band"), encoding=kw.get("encoding", "auto"))
    X, Y, Z = t.scene_xyz()
    assert Z.shape == r.shape
    # lossless default: exact heights at every valid sample, NaN elsewhere
    np.testing.assert_array_equal(t.frame.heights_from_z(Z)[r.valid] * 1.0,
                                  t.frame.heights_from_z(t.frame.z(r.heights[r.valid])))
    assert np.isnan(Z[~r.valid]).all()
    assert np.isfinite(X).all() and np.isfinite(Y).all()
    return t, r


def test_real_dems_round_trip(real_dem_path, tmp_path):
    t, r = _roundtrip(real_dem_path, tmp_path)
    h, _ = t.level_heights(0)
    np.testing.assert_array_equal(h[: r.shape[0], : r.shape[1]][r.valid], r.heights[r.valid])
    info = t.info()
    assert info["grid"] == list(r.shape)
    assert sum(info["tiles_per_level"].values()) == len(t.tile_info)


@pytest.mark.parametrize("shape", [(2, 2), (3, 3), (2, 7), (9, 4), (65, 66), (130, 17)])
@pytest.mark.parametrize("dtype", ["int16", "uint16", "int32", "float32", "float64"])
def test_small_and_odd_grids(tmp_path, shape, dtype):
    rng = np.random.default_rng(sum(shape))
    z = (rng.random(shape) * 300).astype(dtype)
    src = write_tif(tmp_path / "d.tif", z)
    t, r = _roundtrip(src, tmp_path, tile_size=4)
    H, W = shape
    _, _, Z = t.scene_xyz()
    np.testing.assert_array_equal(Z, z.astype(np.float64))


@pytest.mark.fast
def test_nodata_and_nan_are_masks(tmp_path):
    z = np.arange(100, dtype=np.float32).reshape(10, 10)
    z[2, 3] = -9999
    z[5, 5] = np.nan
    src = write_tif(tmp_path / "d.tif", z, nodata=-9999)
    t, r = _roundtrip(src, tmp_path)
    _, _, Z = t.scene_xyz()
    assert np.isnan(Z[2, 3]) and np.isnan(Z[5, 5])
    assert np.isfinite(Z).sum() == 98


@pytest.mark.fast
def test_all_padding_or_nodata_tiles_are_not_stored(tmp_path):
    z = np.zeros((70, 70), np.int16)
    z[:, 40:] = -32768
    src = write_tif(tmp_path / "d.tif", z, nodata=-32768)
    out = geoterrain.preprocess(src, tmp_path / "s.geoterrain", tile_size=16, root_grid=False)
    t = geoterrain.open(out)
    assert t.grid.size == 129
    # level 0 tiles span 16 samples: columns ≥ 48 are nodata or padding, rows ≥ 80 padding
    xs = {x for (L, x, y) in t.tile_info if L == 0}
    ys = {y for (L, x, y) in t.tile_info if L == 0}
    assert max(xs) == 2 and max(ys) == 4
    # the default root grid has no tile past row 80 or column 80 at all (a 1 × 1 root over
    # 5 × 5 tiles); the nodata tiles are not stored there either: the same level-0 tiles
    r = geoterrain.open(geoterrain.preprocess(src, tmp_path / "r.geoterrain", tile_size=16))
    assert (r.grid.layout, r.grid.tiles(0), r.grid.shape) == ("roots", (5, 5), (81, 81))
    assert {k for k in r.tile_info if k[0] == 0} == {k for k in t.tile_info if k[0] == 0}


@pytest.mark.fast
def test_terrain_rgb_png_decodes_to_known_heights(tmp_path):
    rgb = np.zeros((3, 4, 4), np.uint8)
    code = 100000 + np.arange(16).reshape(4, 4)  # h = -10000 + code * 0.1 = 0.0 … 1.5
    rgb[0], rgb[1], rgb[2] = code // 65536, (code // 256) % 256, code % 256
    p = tmp_path / "t.png"
    with rasterio.open(p, "w", driver="PNG", width=4, height=4, count=3, dtype="uint8") as d:
        d.write(rgb)
    r = read_raster(p)
    assert r.encoding == "terrain-rgb"
    np.testing.assert_allclose(r.heights, (code - 100000) * 0.1, atol=1e-9)
    t, _ = _roundtrip(p, tmp_path)
    assert t.frame.kind == "pixel"


@pytest.mark.fast
def test_z_scale_and_pixel_size_are_recorded(tmp_path):
    z = np.full((5, 5), 10.0, np.float32)
    src = write_tif(tmp_path / "d.tif", z)
    out = geoterrain.preprocess(src, tmp_path / "s.geoterrain", z_scale=3.0, z_units="ft")
    t = geoterrain.open(out)
    _, _, Z = t.scene_xyz()
    np.testing.assert_allclose(Z, 10 * 0.3048 * 3)
    assert t.info()["z_scale"] == 3.0


@pytest.mark.slow
def test_8193_synthetic(tmp_path):
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "big.tif", generate("fbm", 8193, seed=1))
    t, r = _roundtrip(src, tmp_path)
    assert t.grid.size == 8193


@pytest.mark.parametrize("driver,ext", [("AAIGrid", "asc"), ("SRTMHGT", "hgt")])
def test_other_gdal_formats(tmp_path, driver, ext):
    """Esri ASCII grids and SRTM .hgt tiles read through GDAL like any GeoTIFF."""
    from rasterio.transform import from_origin

    if driver == "SRTMHGT":
        n, name = 1201, "N35E139.hgt"  # SRTM3: 1201² samples, 3″, named by its corner
        z = (np.arange(n * n) % 700).reshape(n, n).astype(np.int16)
        t = from_origin(139 - 1.5 / 3600, 36 + 1.5 / 3600, 3 / 3600, 3 / 3600)
        crs = "EPSG:4326"
    else:
        name = "d.asc"
        z = np.arange(35, dtype=np.float32).reshape(5, 7)
        z[2, 3] = -9999
        t, crs = from_origin(500000, 5000000, 30, 30), "EPSG:32633"
    src = tmp_path / name
    tif = write_tif(tmp_path / "tmp.tif", z, nodata=-9999 if driver == "AAIGrid" else -32768)
    with rasterio.open(tif) as s:
        prof = s.profile
    prof.update(driver=driver, transform=t, crs=crs)
    for k in ("blockxsize", "blockysize", "tiled", "compress", "interleave"):
        prof.pop(k, None)
    with rasterio.open(src, "w", **prof) as d:
        d.write(z, 1)
    t_, r = _roundtrip(src, tmp_path)
    assert t_.info()["grid"] == list(z.shape)


@pytest.mark.fast
def test_a_dem_too_big_for_memory_is_refused_in_one_line_by_its_frame(tmp_path, monkeypatch):
    """The memory check counts the measured bytes per sample of the DEM's frame kind: a
    geographic DEM needs more than a projected one of the same size, and the refusal is
    one line that names the fix, with no store written."""
    import geoterrain.ingest.raster as R
    from geoterrain.exceptions import InputError

    z = np.arange(64 * 64, dtype=np.float32).reshape(64, 64)
    proj = write_tif(tmp_path / "utm.tif", z)
    geo = write_tif(tmp_path / "geo.tif", z, crs="EPSG:4326", origin=(10.0, 47.0),
                    spacing=1 / 3600)
    need = {k: 64 * 64 * b for k, b in R.PREPROCESS_BYTES_PER_SAMPLE.items()}
    assert need["geographic"] > need["projected"]
    monkeypatch.setattr(R, "available_memory", lambda: need["projected"])
    R.read_raster(proj)  # fits exactly
    with pytest.raises(InputError) as e:
        geoterrain.preprocess(geo, tmp_path / "geo.geoterrain")
    assert "GiB to preprocess" in str(e.value) and "\n" not in str(e.value)
    assert not list(tmp_path.glob("*.geoterrain")) and not list(tmp_path.glob(".*partial*"))

"""Every input streams (issue 45): geographic rasters, mosaics (lists and globs, also in
geographic coordinates), Terrain-RGB and Terrarium PNG tiles (z/x/y placed, ``tile``,
``pixel_size``), a band of a multi-band raster, a given nodata, each through
:func:`geoterrain.preprocessing.streaming.preprocess_streaming` to the store
:func:`geoterrain.preprocessing.pipeline.preprocess` writes from the raster read whole:
every blob, tile row and metadata entry but the timings.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from geoterrain.cli.main import cli
from geoterrain.exceptions import InputError, UsageError
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.streaming import preprocess_streaming, streaming_band
from tests.conftest import real_dem
from tests.ingest.test_mosaic import split
from tests.preprocessing.test_streaming import _assert_same_store


def _geo_tif(path, z, west, north, deg, nodata=None, south_up=False):
    H, W = z.shape
    tr = rasterio.transform.from_origin(west, north, deg, deg)
    if south_up:
        tr = rasterio.Affine(deg, 0, west, 0, deg, north - deg * H)
        z = z[::-1]
    with rasterio.open(path, "w", driver="GTiff", height=H, width=W, count=1, dtype=z.dtype,
                       crs="EPSG:4326", transform=tr, nodata=nodata) as ds:
        ds.write(z, 1)
    return str(path)


def _relief(seed, rows, cols, dtype="float32", holes=0.0, nodata=-9999):
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, (rows, cols))
    z = z.astype(dtype)
    if holes:
        z[rng.random(z.shape) < holes] = nodata
    return z


# (west, north, degrees a pixel) of geographic rasters: mid-latitude, across the
# antimeridian, down to the south pole, the north pole, the whole world
PLACES = {"mid": (10.0, 47.0, 1 / 1200), "antimeridian": (179.8, -40.0, 0.01),
          "south_pole": (-30.0, -75.0, 0.3), "north_pole": (0.0, 90.0, 0.5),
          "world": (-180.0, 90.0, 360 / 64)}


@settings(max_examples=10, deadline=None)
@given(place=st.sampled_from(sorted(PLACES)), seed=st.integers(0, 10_000),
       rows=st.integers(5, 50), cols=st.integers(5, 64), tile=st.sampled_from([4, 16]),
       holes=st.sampled_from([0.0, 0.1]), eps=st.sampled_from([None, 0.5]),
       band=st.sampled_from([2, 8, 32]), south_up=st.booleans())
def test_a_geographic_raster_streams_to_the_preprocessed_store(tmp_path_factory, place, seed,
                                                               rows, cols, tile, holes, eps,
                                                               band, south_up):
    """Curvilinear x, y (pyproj), δ and r in metric x/y, level 0's slack, δ_edge's terms,
    the normals and the tile boxes from each row's x, y: the whole-grid store."""
    west, north, deg = PLACES[place]
    rows = min(rows, int(180 / deg) - 1)
    cols = min(cols, int(360 / deg))
    tmp = tmp_path_factory.mktemp("geo")
    z = _relief(seed, rows, cols, holes=holes)
    src = _geo_tif(tmp / "g.tif", z, west, north, deg, -9999 if holes else None, south_up)
    a = preprocess(src, tmp / "a.gt", tile_size=tile, codec_error=eps)
    b = preprocess_streaming(src, tmp / "b.gt", tile_size=tile, codec_error=eps, band=band)
    _assert_same_store(a, b)
    assert a.read_bytes() == b.read_bytes()  # the same blob rows in the same order too


@pytest.mark.parametrize("eps", [None, 0.5])
def test_streamed_and_whole_stores_are_the_same_file(tmp_path, eps):
    """Byte for byte, not only blob for blob: the whole-grid preprocess inserts its blob
    rows in the streamed order (levelblobs.tile_row_order), which sets each row's id and
    page. A padded grid (δ_edge of stored and unstored tiles), geographic and projected."""
    z = _relief(3, 45, 70, holes=0.05)
    geo = _geo_tif(tmp_path / "g.tif", z, 10.0, 47.0, 1 / 1200, nodata=-9999)
    for src in (geo, [str(p) for p in split(Path(geo), tmp_path / "tiles", 1)]):
        a = preprocess(src, tmp_path / "a.gt", tile_size=8, codec_error=eps, overwrite=True)
        b = preprocess_streaming(src, tmp_path / "b.gt", tile_size=8, codec_error=eps,
                                 band=8, overwrite=True)
        assert a.read_bytes() == b.read_bytes(), src


def test_a_real_geographic_dem_streams(tmp_path):
    """srtm3_pysheds (EPSG:4326, declared nodata, padded 359 × 367 → 385² on its root grid)."""
    src = real_dem("srtm3_pysheds.tif")
    a = preprocess(src, tmp_path / "a.gt")
    b = preprocess_streaming(src, tmp_path / "b.gt", band=32)
    _assert_same_store(a, b)


@pytest.mark.slow
def test_srtm1_japan_streams(tmp_path):
    src = real_dem("srtm1_japan.tif")
    _assert_same_store(preprocess(src, tmp_path / "a.gt", root_grid=False),  # the square,
                       preprocess_streaming(src, tmp_path / "b.gt", band=64))  # for now


def test_a_geographic_mosaic_streams_as_a_list_and_a_glob(tmp_path):
    """Four tiles of a geographic raster (one of them with its own nodata value): the
    list and the glob stream to the store of the list read whole."""
    z = _relief(5, 60, 70, dtype="int16", holes=0.05, nodata=-32768)
    merged = _geo_tif(tmp_path / "m.tif", z, 8.0, 46.0, 1 / 1200, nodata=-32768)
    tiles = split(merged, tmp_path / "tiles", overlap=1, nodatas=(-32768, -9999, -32768, 0))
    a = preprocess([str(p) for p in tiles], tmp_path / "a.gt", tile_size=16)
    b = preprocess_streaming([str(p) for p in tiles], tmp_path / "b.gt", tile_size=16, band=8)
    _assert_same_store(a, b)
    c = preprocess_streaming(str(tmp_path / "tiles" / "tile_*.tif"), tmp_path / "c.gt",
                             tile_size=16, band=16)
    _assert_same_store(a, c)


def _rgb_png(path, heights, encoding, alpha=None):
    if encoding == "terrain-rgb":
        code = np.round((heights + 10000) * 10).astype(np.int64)
    else:
        code = np.round((heights + 32768) * 256).astype(np.int64)
    rgb = np.stack([(code >> 16) & 255, (code >> 8) & 255, code & 255], -1).astype(np.uint8)
    if alpha is not None:
        rgb = np.concatenate([rgb, alpha[..., None].astype(np.uint8)], -1)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(rgb).save(path)
    return str(path)


@pytest.mark.parametrize("encoding", ["terrain-rgb", "terrarium"])
@pytest.mark.parametrize("how", ["auto", "named", "zxy", "tile", "pixel_size", "alpha", "eps"])
def test_png_tiles_stream(tmp_path, encoding, how):
    """Terrain-RGB and Terrarium tiles decoded a window at a time: the auto-detected
    encoding (the red band's median) and its roughness check computed exactly over
    bands, placed by a z/x/y path or ``tile``, or by ``pixel_size``; transparent pixels
    as voids; lossy."""
    rng = np.random.default_rng(2)
    h = 800 + rng.normal(0, 8, (70, 70)).cumsum(0).cumsum(1) / 6
    alpha = (rng.random(h.shape) > 0.1) * 255 if how == "alpha" else None
    path = tmp_path / ("12/3637/1612.png" if how == "zxy" else "t.png")
    src = _rgb_png(path, h, encoding, alpha)
    kw = {"encoding": encoding} if how == "named" else {}
    kw |= {"tile": "12/3637/1612"} if how == "tile" else {}
    kw |= {"pixel_size": 30.0} if how == "pixel_size" else {}
    kw |= {"codec_error": 0.4} if how == "eps" else {}
    a = preprocess(src, tmp_path / "a.gt", tile_size=16, **kw)
    b = preprocess_streaming(src, tmp_path / "b.gt", tile_size=16, band=8, **kw)
    _assert_same_store(a, b)


@pytest.mark.parametrize("name", ["fuji_terrain_rgb.png", "terrarium.png"])
def test_real_png_tiles_stream(tmp_path, name):
    src = real_dem(name)
    _assert_same_store(preprocess(src, tmp_path / "a.gt"),
                       preprocess_streaming(src, tmp_path / "b.gt", band=16))


def test_a_rough_auto_detected_png_is_refused_by_both(tmp_path):
    """Noise read as Terrain-RGB: the streamed roughness check refuses it as the whole
    read does, in one line."""
    rgb = np.random.default_rng(0).integers(0, 256, (40, 40, 3)).astype(np.uint8)
    Image.fromarray(rgb).save(tmp_path / "noise.png")
    for run in (preprocess, preprocess_streaming):
        with pytest.raises(InputError, match="neighbouring heights differ"):
            run(str(tmp_path / "noise.png"), tmp_path / "x.gt")
    assert not list(tmp_path.glob("*.gt"))


def test_a_band_of_a_multiband_raster_and_a_given_nodata_stream(tmp_path):
    z = _relief(4, 45, 50)
    other = np.full_like(z, 7.0)
    z[3:6, 3:9] = 12345.0
    with rasterio.open(tmp_path / "m.tif", "w", driver="GTiff", height=45, width=50, count=2,
                       dtype="float32", crs="EPSG:32633",
                       transform=rasterio.transform.from_origin(500000, 5e6, 10, 10)) as ds:
        ds.write(other, 1)
        ds.write(z, 2)
    src = str(tmp_path / "m.tif")
    a = preprocess(src, tmp_path / "a.gt", band=2, nodata=12345.0, tile_size=16)
    b = preprocess_streaming(src, tmp_path / "b.gt", raster_band=2, nodata=12345.0,
                             tile_size=16, band=4)
    _assert_same_store(a, b)
    with pytest.raises(UsageError, match="has 2 bands"):
        preprocess_streaming(src, tmp_path / "c.gt")


@pytest.mark.fast
def test_streaming_band_takes_every_frame():
    """Geographic rasters go to the streaming preprocess too, by their own bytes a sample."""
    assert streaming_band((4097, 2049), 1 << 40, geographic=True) is None
    assert streaming_band((4097, 2049), 1 << 30, geographic=True) is not None
    assert streaming_band((1025, 513), 1 << 30, geographic=True) is None


def test_the_cli_streams_a_geographic_mosaic_over_its_memory_limit(tmp_path, monkeypatch):
    """``--memory-limit`` sends a geographic mosaic whose whole-grid preprocess would need
    more (here: made to need 1 MB a sample) through the streaming preprocess."""
    import geoterrain.ingest.raster as raster

    monkeypatch.setitem(raster.PREPROCESS_BYTES_PER_SAMPLE, "geographic", 1 << 20)
    z = _relief(8, 64, 96)
    merged = _geo_tif(tmp_path / "m.tif", z, 130.0, 35.0, 1 / 3600)
    tiles = split(merged, tmp_path / "tiles")
    run = CliRunner().invoke(cli, ["-q", "preprocess", *map(str, tiles), "-o",
                                   str(tmp_path / "s.gt"), "--memory-limit", "64M",
                                   "--tile-size", "16"])
    assert run.exit_code == 0, run.output
    import geoterrain

    timings: dict = {}
    preprocess([str(p) for p in tiles], tmp_path / "s2.gt", tile_size=16,
               memory_limit=64 << 20, timings=timings)
    assert "scan" in timings  # the streaming preprocess's stages (not in the store)
    with geoterrain.open(tmp_path / "s.gt") as t:
        assert "preprocess_seconds" not in t.meta
    _assert_same_store(tmp_path / "s.gt", preprocess([str(p) for p in tiles],
                                                     tmp_path / "w.gt", tile_size=16))

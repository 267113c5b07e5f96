"""The streaming preprocess (geoterrain.preprocessing.streaming) writes the store preprocess writes.

The oracle is :func:`geoterrain.preprocessing.pipeline.preprocess` on the same GeoTIFF: every
blob (kind, tile, bytes), every tile row and every metadata entry but the timings must
be equal, whatever the band. The stages' own equalities are in test_streaming_stages.py.
"""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest
import rasterio
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import InputError, UsageError
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.conftest import real_dem
from tests.store.storesql import all_blobs, all_tiles, read_meta


def _content(path) -> tuple[dict, dict, dict]:
    con = sqlite3.connect(path)
    try:
        blobs, tiles = all_blobs(con), all_tiles(con)
        meta = read_meta(con)
    finally:
        con.close()
    return blobs, tiles, meta


def _assert_same_store(a, b) -> None:
    (ba, ta, ma), (bb, tb, mb) = _content(a), _content(b)
    assert ba.keys() == bb.keys()
    assert sorted(k for k in ba if ba[k] != bb[k]) == []
    assert ta == tb
    assert ma == mb


def _tif(path, z, nodata=None, crs="EPSG:32633", south_up=False) -> str:
    H, W = z.shape
    tr = (rasterio.transform.from_origin(10, 50, 0.001, 0.001) if crs == "EPSG:4326" else
          rasterio.transform.from_origin(500000, 5000000, 10, 10))
    if south_up:
        tr = rasterio.Affine(10, 0, 500000, 0, 10, 5000000 - 10 * H)
        z = z[::-1]
    with rasterio.open(path, "w", driver="GTiff", height=H, width=W, count=1,
                       dtype=z.dtype, crs=crs, transform=tr, nodata=nodata) as ds:
        ds.write(z, 1)
    return str(path)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(5, 150), cols=st.integers(5, 150),
       tile=st.sampled_from([2, 4, 16, 64]), holes=st.sampled_from([0.0, 0.05, 0.6]),
       dtype=st.sampled_from(["float32", "int16", "tenths", "tenths64"]),
       eps=st.sampled_from([None, 0.5, 2.0]),
       band=st.sampled_from([2, 8, 64]), south_up=st.booleans())
def test_streamed_store_is_the_preprocessed_one(tmp_path_factory, seed, rows, cols, tile,
                                                holes, dtype, eps, band, south_up):
    """Padded shapes, voids (declared nodata), integer, float and decimal float sources,
    lossless and ε, tiles of 3 to 65 samples, south-up files, bands of 2 to 64 rows."""
    tmp = tmp_path_factory.mktemp("st")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, (rows, cols))
    # "tenths": float32 heights of one decimal place (the "decimal" quantizer);
    # "tenths64": the same float32 values written as float64
    if dtype.startswith("tenths"):
        z = (np.rint(z * 10) / 10).astype(np.float32)
        z = z.astype(np.float64) if dtype == "tenths64" else z
    else:
        z = z.astype(dtype)
    nodata = None
    if holes:
        z[rng.random(z.shape) < holes] = -9999
        nodata = -9999
    src = _tif(tmp / "dem.tif", z, nodata, south_up=south_up)
    a = preprocess(src, tmp / "a.geoterrain", tile_size=tile, codec_error=eps)
    b = preprocess_streaming(src, tmp / "b.geoterrain", tile_size=tile, codec_error=eps,
                             band=band)
    _assert_same_store(a, b)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(20, 140), cols=st.integers(20, 140),
       tile=st.sampled_from([2, 4, 8]), holes=st.sampled_from([0.0, 0.05, 0.6]),
       window=st.integers(1, 3), crs=st.sampled_from(["EPSG:32633", "EPSG:4326"]),
       eps=st.sampled_from([None, 1.0]))
def test_a_tile_row_coded_in_windows_is_the_same_store_bytes(tmp_path_factory, seed, rows,
                                                             cols, tile, holes, window, crs,
                                                             eps):
    """The blobs stage codes a tile row WINDOW_TILES tiles at a time: with windows of 1
    to 3 tiles the streamed store is the same file, byte for byte, as with windows as
    wide as the raster (padded shapes, so δ_edge too; voids; projected and geographic)."""
    import geoterrain.preprocessing.streaming as sm

    tmp = tmp_path_factory.mktemp("win")
    rng = np.random.default_rng(seed)
    z = (rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 5).astype(np.float32)
    nodata = None
    if holes:
        z[rng.random(z.shape) < holes] = -9999
        nodata = -9999
    src = _tif(tmp / "dem.tif", z, nodata, crs=crs)
    got = []
    for name, across in (("a.gt", 1 << 30), ("b.gt", window)):  # one window a row; narrow
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(sm, "WINDOW_TILES", across)
            got.append(preprocess_streaming(src, tmp / name, tile_size=tile,
                                            codec_error=eps, band=8).read_bytes())
    assert got[1] == got[0]


def test_streamed_store_of_a_real_dem(tmp_path):
    """A projected SRTM DEM in US feet (z units from the CRS, padding, voids)."""
    src = real_dem("roi_epsg3089.tif")
    a = preprocess(src, tmp_path / "a.geoterrain")
    b = preprocess_streaming(src, tmp_path / "b.geoterrain", band=16)
    _assert_same_store(a, b)
    assert geoterrain.open(b).tile(0, 0, 0).heights.shape == (65, 65)


def test_streamed_store_of_an_undeclared_void_sentinel(tmp_path):
    """Voids written as -32768 without a declared nodata are found by the first pass,
    as the whole-raster reader finds them."""
    z = np.random.default_rng(1).normal(100, 5, (40, 30)).astype(np.float32)
    z[3:9, 4:12] = -32768
    src = _tif(tmp_path / "v.tif", z)
    a = preprocess(src, tmp_path / "a.geoterrain", tile_size=8)
    b = preprocess_streaming(src, tmp_path / "b.geoterrain", tile_size=8, band=4)
    _assert_same_store(a, b)
    assert _content(b)[2]["source_nodata"] == -32768.0


@pytest.mark.fast
def test_streaming_refuses_what_it_does_not_take(tmp_path):
    z = np.zeros((9, 9), np.float32)
    with pytest.raises(UsageError, match="power of two"):
        preprocess_streaming(_tif(tmp_path / "b.tif", z), tmp_path / "b.gt", band=3)
    nd = np.full((9, 9), -1, np.float32)
    with pytest.raises(InputError, match="nodata"):
        preprocess_streaming(_tif(tmp_path / "n.tif", nd, nodata=-1), tmp_path / "n.gt")
    inf = z.copy()
    inf[2, 2] = np.inf
    with pytest.raises(InputError, match="inf"):
        preprocess_streaming(_tif(tmp_path / "i.tif", inf), tmp_path / "i.gt")
    assert not list(tmp_path.glob("*.gt")) and not list(tmp_path.glob(".*partial*"))


def test_the_cli_streams_a_raster_over_its_memory_limit(tmp_path):
    """`preprocess --memory-limit` sends a raster whose whole-grid preprocess would need
    more (1025² × 72 bytes: 76 MB > 64M) through the streaming preprocess, to the store
    the whole-grid one writes."""
    from click.testing import CliRunner

    from geoterrain.cli.main import cli
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.streaming import streaming_band

    dem = str(write_geotiff(str(tmp_path / "d.tif"), generate("fbm", 1025, seed=3)))
    assert streaming_band((1025, 1025), 64 << 20) is not None
    run = CliRunner().invoke(cli, ["-q", "preprocess", dem, "-o", str(tmp_path / "s.gt"),
                                   "--memory-limit", "64M"])
    assert run.exit_code == 0, run.output
    _assert_same_store(tmp_path / "s.gt", preprocess(dem, tmp_path / "w.gt"))


@pytest.mark.slow
@pytest.mark.parametrize("eps", [None, 1.0])
def test_a_16385_dem_preprocesses_in_bounded_memory(tmp_path, eps):
    """Issue 12's memory target: a 16385² DEM over a 1 GiB memory limit streams, and the
    process peaks under 1.5 GB and within 10 % of a 4097² DEM under the same limit
    (each in a fresh process; VmHWM); lossless, and with ε (residual bins: the decoded
    heights go through a scratch file)."""
    import subprocess
    import sys

    from geoterrain.ingest.synth import generate, write_geotiff

    code = ("import sys, json; from geoterrain.preprocessing.pipeline import preprocess; "
            "from geoterrain.core.memory import peak_rss; "
            f"preprocess(sys.argv[1], sys.argv[2], memory_limit=1 << 30, codec_error={eps}); "
            "print(json.dumps(peak_rss()))")
    peaks = {}
    for n in (4097, 16385):
        dem = str(write_geotiff(str(tmp_path / f"f{n}.tif"), generate("fbm", n, seed=7)))
        run = subprocess.run([sys.executable, "-c", code, dem, str(tmp_path / f"f{n}.gt")],
                             capture_output=True, text=True, check=True)
        peaks[n] = json.loads(run.stdout.strip().splitlines()[-1])
        (tmp_path / f"f{n}.tif").unlink()
    print("peaks MB", {n: p / 2**20 for n, p in peaks.items()})
    assert peaks[16385] <= 1.5e9
    assert peaks[16385] <= 1.1 * peaks[4097]


def test_a_vrt_mosaic_streams_to_the_merged_raster_s_store(tmp_path):
    """A .vrt of a 2×2 mosaic (a void across the seam) is a single raster to the
    streaming preprocess: its store is the merged GeoTIFF's, but the source name."""
    from geoterrain.ingest.mosaic import build_vrt
    from tests.ingest.test_mosaic import _synthetic, split, store_contents

    merged = _synthetic(tmp_path)
    vrt = tmp_path / "mosaic.vrt"
    vrt.write_text(build_vrt(split(merged, tmp_path / "tiles")))
    ref = store_contents(preprocess(merged, tmp_path / "merged.gt", tile_size=16))
    got = store_contents(preprocess_streaming(vrt, tmp_path / "v.gt", tile_size=16, band=8))
    assert got == ref


@pytest.mark.parametrize("eps", [2.0, 0.25])
def test_binned_heights_stream_through_super_tiles(tmp_path, monkeypatch, eps):
    """A lossy store (residual bins: decoded heights that depend on the pyramid) streams
    to the preprocessed one when the height pass codes super-tiles under a coarse grid
    (a small coarse grid here, as a 16385² raster has): the decoded heights it writes for
    the other passes are the whole grid's, super-tile corners and borders included."""
    import geoterrain.preprocessing.passes as sp

    monkeypatch.setattr(sp, "COARSE_MAX", 9)
    rng = np.random.default_rng(4)
    z = (rng.normal(0, 20, (120, 125)).cumsum(0).cumsum(1) / 40).astype(np.float32)
    z[30:40, 50:70] = -9999
    src = _tif(tmp_path / "dem.tif", z, -9999)
    a = preprocess(src, tmp_path / "a.geoterrain", tile_size=4, codec_error=eps)
    b = preprocess_streaming(src, tmp_path / "b.geoterrain", tile_size=4, codec_error=eps,
                             band=16)
    _assert_same_store(a, b)
    assert geoterrain.open(b).quantizer.bins > 1


def test_the_tile_pass_leaves_its_table_in_its_record(tmp_path, monkeypatch):
    """run_pass hands back no tile table (the streamed preprocess would hold it, which
    grows with the raster, through the normals and height passes): pass_result reads it
    from the pass's record, the same arrays, also for a resumed run's recorded pass."""
    import dataclasses

    import geoterrain.preprocessing.passes as sp
    from geoterrain.bounds.tilebounds import TileTable

    rng = np.random.default_rng(3)
    table = TileTable(np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0]]), rng.normal(size=(3, 9)))
    blocks = rng.normal(size=(1, 2, 2))
    calls = []
    monkeypatch.setitem(sp.PASSES, "tiles", lambda job: calls.append(1) or (table, blocks))
    job = dataclasses.replace(sp.Job(None, {}, {}, None, 2, "", False), folder=str(tmp_path))
    assert sp.run_pass(job, "tiles") is None
    assert sp.run_pass(job, "tiles") is None and calls == [1]  # recorded: not run again
    got, b = sp.pass_result(job, "tiles")
    assert np.array_equal(got.keys, table.keys) and np.array_equal(got.rows, table.rows)
    assert np.array_equal(b, blocks)

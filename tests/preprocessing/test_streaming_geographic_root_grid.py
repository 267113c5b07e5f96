"""A geographic raster streamed on its rectangular root grid (issue 45): the store the
whole-grid geographic root-grid preprocess writes, blob for blob and byte for byte (the
heights here are coded in one piece), whatever the band, on every scheduler, from a
mosaic too.

The metric (curvilinear) stages are checked first against their whole-grid twins with
``span`` on the roots' extent (:func:`geoterrain.bounds.curvature.metric_terms`,
``metric_bounds``, :func:`geoterrain.bounds.tileblobs.radius_codes`,
:func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`, δ_edge over the replicated
grid), on pyproj's scene x, y of 2 × 1, 1 × 2, 3 × 1, 1 × 3 and 2 × 2 roots at mid and
high latitudes, across the antimeridian and down to a pole; then whole stores against
:func:`geoterrain.preprocessing.pipeline.preprocess` with ``root_grid`` (itself checked
against brute forces in ``tests/bounds/test_root_curvature.py``).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np
import pytest
import rasterio
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import saturate, vertex_errors
from geoterrain.bounds.edgepad import edge_deltas, edge_support, has_padding
from geoterrain.bounds.leafbounds import geographic_leaf_delta
from geoterrain.bounds.radii import vertex_radii
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.bands.curvature import band_metric_terms
from geoterrain.preprocessing.bands.delta import (
    _saturate,
    band_vertex_errors,
    copy_levels,
    edge_rows,
    raise_delta,
    rows_of,
)
from geoterrain.preprocessing.bands.leaf import band_leaf_slack, follow_slack
from geoterrain.preprocessing.bands.radii import band_metric_radius_codes
from geoterrain.preprocessing.bands.tiles import band_tile_bounds
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.scratch import ScratchArrays
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.preprocessing.test_streaming import _assert_same_store

# (west, north, degrees a pixel) of the rasters the stage tests place: where the scene's
# x, y bend (high latitudes), wrap (the antimeridian) or fold (padding past a pole)
PLACES = {
    "mid": (10.0, 61.0, 0.02),
    "high": (-40.0, 79.0, 0.05),
    "antimeridian": (179.5, -40.5, 0.02),
    "south_pole": (-20.0, -80.0, 0.1),  # 90 rows reach -89°; the padding passes the pole
}
# (rows, cols) of the data, each on its own roots with 4-sample tiles: 2 × 1, 1 × 2,
# 3 × 1, 1 × 3 and 2 × 2 (a data rectangle short of the extent both ways)
SHAPES = [(20, 57), (57, 20), (13, 90), (90, 13), (50, 61), (9, 33)]


def _geo_roots(shape, place, seed, holes, tile=4):
    """A geographic root grid's extent: the grid, scene X, Y (pyproj) of every sample of
    the extent, heights with voids and validity padded to it (the whole-grid
    preprocess's arrays)."""
    rows, cols = shape
    west, north, deg = PLACES[place]
    tr = rasterio.transform.from_origin(west, north, deg, deg)
    frame = Frame.from_raster(tuple(tr)[:6], rasterio.crs.CRS.from_epsg(4326).to_wkt(), rows,
                              cols)
    g = Grid.for_shape(rows, cols, tile, roots=True)
    X, Y = frame.grid_xy(g.extent)
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 30, (rows, cols)).cumsum(0).cumsum(1) / 10
    v = rng.random((rows, cols)) >= holes
    Z = g.pad(np.where(v, z, np.nan), np.nan, whole=True)
    V = g.pad(v, False, whole=True)
    return g, np.ascontiguousarray(X), np.ascontiguousarray(Y), Z, V


def _grid_of(sa, pre, shape, n, dtype):
    """The extent's grid of per-level arrays ``{pre}{x}{k}`` (0 at the roots' corners)."""
    out = np.zeros(shape, dtype)
    for k in range(n):
        h = 1 << k
        s = 2 * h
        for x, (di, dj) in zip("CRK", ((h, h), (h, 0), (0, h)), strict=True):
            out[di::s, dj::s] = sa.read(f"{pre}{x}{k}", 0, sa.shape(f"{pre}{x}{k}")[0])
    return out


def _xy(X, Y):
    return lambda a, b: (X[a:b], Y[a:b])


@settings(max_examples=15, deadline=None)
@given(shape=st.sampled_from(SHAPES), place=st.sampled_from(sorted(PLACES)),
       seed=st.integers(0, 10_000), holes=st.sampled_from([0.0, 0.05, 0.5]),
       band=st.sampled_from([2, 4, 16, 64]))
@example(shape=(13, 90), place="south_pole", seed=3, holes=0.0, band=2)
@example(shape=(90, 13), place="high", seed=5, holes=0.05, band=4)
def test_banded_metric_terms_on_the_roots_are_metric_terms(shape, place, seed, holes, band):
    """δ_m, r_m, the bulges and the largest search margin of the extent, and δ_edge's
    terms over the replicated grid with that base: the whole-grid bits with ``span``,
    for wide and tall roots and bands of 2 rows to wider than a root."""
    g, X, Y, Z, V = _geo_roots(shape, place, seed, holes)
    assume(not g.square)
    R, C = g.extent
    S = g.span
    ref = metric_terms(X, Y, Z, V, span=S)
    sa = ScratchArrays()
    bt = band_metric_terms(rows_of(Z, V), _xy(X, Y), (R, C), band, sa, span=S)
    assert np.array_equal(_grid_of(sa, "dm", (R, C), g.n, float), ref[0])
    assert np.array_equal(_grid_of(sa, "rm", (R, C), g.n, float), ref[1])
    assert np.array_equal(_grid_of(sa, "b", (R, C), g.n, np.uint8).astype(bool), ref[2])
    assert bt.M == ref[3]
    # the bands past the data's rows (± half a band) skipped: the same terms, bit for bit
    sk, bk, read, full = _skipping(g, X, Y, Z, V, band)
    for pre, dtype in (("dm", float), ("rm", float), ("b", np.uint8)):
        assert np.array_equal(_grid_of(sk, pre, (R, C), g.n, dtype),
                              _grid_of(sa, pre, (R, C), g.n, dtype))
    assert bk.M == bt.M
    assert read <= full
    if has_padding(g):
        Zr, ok = edge_support(Z, V, g)
        win = (g.rows, g.cols)
        eref = metric_terms(X, Y, Zr, ok, window=win, base=ref, span=S)
        band_metric_terms(rows_of(Zr, ok), _xy(X, Y), (R, C), band, sa, pre="e", window=win,
                          base=bt, span=S)
        assert np.array_equal(_grid_of(sa, "edm", (R, C), g.n, float), eref[0])
        assert np.array_equal(_grid_of(sa, "eb", (R, C), g.n, np.uint8).astype(bool), eref[2])


def _skipping(g, X, Y, Z, V, band):
    """band_metric_terms with ``empty_from`` the data's rows: its arrays and terms, and
    the rows it read against the rows read without it."""
    counts = []

    def counted(n):
        def rows(a, b):
            n[0] += b - a
            return Z[a:b], V[a:b]
        return rows

    for empty_from in (None, g.rows):
        n = [0]
        sk = ScratchArrays()
        bk = band_metric_terms(counted(n), _xy(X, Y), g.extent, band, sk, span=g.span,
                               empty_from=empty_from)
        counts.append(n[0])
    return sk, bk, counts[1], counts[0]


def test_metric_terms_skip_the_bands_below_the_data():
    """A 13 × 90 raster on 1 × 2 roots of 64 (extent 65 × 129), bands of 2: the bands
    from row 14 on hold no vertex with a valid triangle, and are not read."""
    g, X, Y, Z, V = _geo_roots((13, 90), "mid", 1, 0.0)
    assert g.extent == (65, 129)
    _, _, read, full = _skipping(g, X, Y, Z, V, 2)
    assert read < full - 30


@pytest.mark.parametrize("holes", [0.0, 0.3])
def test_the_tile_table_reads_no_x_y_of_the_bands_below_the_data(holes):
    """Level 0's tile boxes take the x, y of valid samples only: the banded tile table
    of a 13 × 90 geographic raster on 1 × 2 roots of 64 (extent 65 × 129, bands of 2)
    asks no scene x, y of the rows past the data (14 …), and is the whole grid's."""
    g, X, Y, Z, V = _geo_roots((13, 90), "mid", 1, holes)
    asked = []

    def xy(a, b):
        asked.append(b)
        return X[a:b], Y[a:b]

    got = band_tile_bounds(lambda a, b: (Z[a:b], V[a:b]), g.extent, g.t, np.zeros(g.extent[1]),
                           np.zeros(g.extent[0]), band=2, xy=xy, span=g.span)
    want = tile_and_block_errors(Z, V, X, Y, g.t, span=g.span)
    assert got[0] == want[0] and np.array_equal(got[1], want[1])
    assert asked and max(asked) == 14


@settings(max_examples=10, deadline=None)
@given(shape=st.sampled_from(SHAPES), place=st.sampled_from(sorted(PLACES)),
       seed=st.integers(0, 10_000), holes=st.sampled_from([0.0, 0.1]),
       band=st.sampled_from([2, 8, 32]), on_disk=st.booleans())
@example(shape=(57, 20), place="high", seed=11, holes=0.1, band=2, on_disk=False)
def test_banded_geographic_bounds_on_the_roots_are_the_whole_grid_bounds(
        tmp_path_factory, shape, place, seed, holes, band, on_disk):
    """δ raised by the metric terms and saturated per root again, the radius codes nested
    on the raised radii across the roots' shared edges, level 0's slack over the
    extent's tiles down and across with δ re-saturated, and δ_edge following it: each
    the whole-grid root-grid value (surface.vertex_bounds, levelblobs.tile_blobs with
    ``span``)."""
    g, X, Y, Z, V = _geo_roots(shape, place, seed, holes)
    assume(not g.square)
    R, C = g.extent
    S, n = g.span, g.n
    delta = vertex_errors(Z, V, span=S)
    radius = vertex_radii(X, Y, Z, V, span=S)
    terms = metric_terms(X, Y, Z, V, span=S)
    d_ref, r_ref = metric_bounds(delta, radius, X, Y, Z, V, terms=terms, span=S)
    codes, e = radius_codes(X, Y, Z, V, r_ref, span=S)
    before = d_ref.copy()
    slack = geographic_leaf_delta(d_ref, Z, V, g.t, terms[0], terms[2], S)
    sa = ScratchArrays(tmp_path_factory.mktemp("s") if on_disk else None)
    rows = rows_of(Z, V)
    band_vertex_errors(rows, (R, C), band=band, scratch=sa, heights=True, span=S)
    # as the bounds pass calls them: the bands and tile rows past the data's rows skipped
    bt = band_metric_terms(rows, _xy(X, Y), (R, C), band, sa, span=S, empty_from=g.rows)
    raise_delta(sa, n)
    assert band_metric_radius_codes(sa, (R, C), _xy(X, Y), budget=1 << 12, span=S) == e
    got = _grid_of(sa, "r", (R, C), n, np.uint8)
    vertex = np.ones((R, C), bool)
    vertex[::S, ::S] = False  # the roots' corners: no level's vertices
    assert np.array_equal(got[vertex], codes[vertex])
    copy_levels(sa, n, "", "db")
    got_slack = band_leaf_slack(sa, (R, C), g.t, rows, empty_from=g.rows)
    assert got_slack == slack
    if slack is not None:
        top = _saturate(sa, n, 1 << 12)
        assert top == float(np.max(d_ref, where=np.isfinite(d_ref), initial=0.0))
    assert np.array_equal(_grid_of(sa, "", (R, C), n, np.float32), d_ref)
    if not has_padding(g):
        return
    # δ_edge: metric over the replicated grid, then following δ's raise where it was δ
    Zr, ok = edge_support(Z, V, g)
    win = (g.rows, g.cols)
    de = edge_deltas(Zr, ok, g)
    et = metric_terms(X, Y, Zr, ok, window=win, base=terms, span=S)
    de, _ = metric_bounds(de, None, X, Y, Zr, ok, window=win, terms=et, span=S)
    if slack is not None:
        same = de == before
        de[same] = d_ref[same]
        saturate(de, S)
    se = ScratchArrays()
    erows = edge_rows(rows, win)
    band_vertex_errors(erows, (R, C), band=band, scratch=se, data=win, span=S)
    band_metric_terms(erows, _xy(X, Y), (R, C), band, se, pre="e", window=win, base=bt, span=S)
    raise_delta(se, n, terms="e")
    if slack is not None:
        follow_slack(se, sa, n)
        _saturate(se, n, 1 << 12)
    assert np.array_equal(_grid_of(se, "", (R, C), n, np.float32), de)


def _geo_tif(path, z, nodata=None, west=10.0, north=70.0, deg=0.01) -> str:
    H, W = z.shape
    with rasterio.open(path, "w", driver="GTiff", height=H, width=W, count=1, dtype=z.dtype,
                       crs="EPSG:4326", transform=rasterio.transform.from_origin(
                           west, north, deg, deg), nodata=nodata) as ds:
        ds.write(z, 1)
    return str(path)


def _wide_geo_tif(tmp, seed: int, rows: int, cols: int, holes: float, dtype="float32",
                  north: float = 70.0) -> str:
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, (rows, cols))
    z = (z + 500).astype(dtype)
    nodata = None
    if holes:
        z[rng.random(z.shape) < holes] = -9999
        nodata = -9999
    return _geo_tif(tmp / "dem.tif", z, nodata, north=north)


def _same_store_streamed(tmp, seed, rows, wide, tall, tile, holes, dtype, eps, band, north):
    cols = max(5, int(rows * wide))
    if tall:
        rows, cols = cols, rows
    assume(not Grid.for_shape(rows, cols, tile, roots=True).square)
    src = _wide_geo_tif(tmp, seed, rows, cols, holes, dtype, north)
    a = preprocess(src, tmp / "a.gt", tile_size=tile, codec_error=eps, root_grid=True)
    b = preprocess_streaming(src, tmp / "b.gt", tile_size=tile, codec_error=eps, band=band,
                             root_grid=True)
    t = geoterrain.open(b)
    assert not t.grid.square and t.frame.kind == "geographic"
    _assert_same_store(a, b)
    assert Path(a).read_bytes() == Path(b).read_bytes()


@pytest.mark.parametrize("case", [
    # a wide raster at 80° N with voids, 8-sample tiles, lossless, 4-row bands
    dict(seed=1, rows=50, wide=2.42, tall=False, tile=8, holes=0.05, dtype="float32",
         eps=None, band=4, north=80.0),
    # a tall int16 raster at 45° N within ε = 0.5, 4-sample tiles, 2-row bands
    dict(seed=2, rows=40, wide=3.1, tall=True, tile=4, holes=0.0, dtype="int16", eps=0.5,
         band=2, north=45.0)])
def test_a_wide_and_a_tall_geographic_raster_stream_to_the_whole_grid_store(tmp_path, case):
    """Two cases of the property below, in the default tier: the same store, the same
    bytes."""
    _same_store_streamed(tmp_path, **case)


@pytest.mark.slow  # about 3 s an example at load 10
@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(5, 90), wide=st.floats(1.3, 4.0),
       tall=st.booleans(), tile=st.sampled_from([2, 4, 8, 16, 64]),
       holes=st.sampled_from([0.0, 0.05, 0.6]), dtype=st.sampled_from(["float32", "int16"]),
       eps=st.sampled_from([None, 0.5, 2.0]), band=st.sampled_from([2, 8, 64]),
       north=st.sampled_from([0.5, 45.0, 80.0]))
def test_the_streamed_geographic_root_grid_store_is_the_whole_grid_one(
        tmp_path_factory, seed, rows, wide, tall, tile, holes, dtype, eps, band, north):
    """Wide and tall EPSG:4326 rasters on 2 × 1 / 1 × 2 roots (a lattice short of the
    extent), voids, float32 and int16, lossless and ε, tiles of 3 to 65 samples, bands
    of 2 rows to wider than a root, near the equator to 80° N: the same store, and the
    same bytes (the heights of these extents are coded in one piece)."""
    _same_store_streamed(tmp_path_factory.mktemp("gs"), seed, rows, wide, tall, tile, holes,
                         dtype, eps, band, north)


@pytest.mark.fast
def test_a_memory_limit_streams_a_geographic_root_grid_to_the_same_file(tmp_path):
    """``preprocess(root_grid=True)`` of an EPSG:4326 raster over its memory limit
    streams (no refusal) and writes the whole-grid root-grid store byte for byte."""
    src = _wide_geo_tif(tmp_path, 4, 70, 200, 0.05)
    timings: dict = {}
    a = preprocess(src, tmp_path / "a.gt", tile_size=16, root_grid=True)
    b = preprocess(src, tmp_path / "b.gt", tile_size=16, root_grid=True,
                   memory_limit=1 << 18, timings=timings)
    assert "blobs" in timings  # the streamed run's stages (the whole grid has no "blobs")
    t = geoterrain.open(b)
    assert t.grid.roots == (2, 1) and t.frame.kind == "geographic"
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("spec", [
    "sync",
    # worker pools and a LocalCluster: their start and compiles
    pytest.param("processes:2", marks=pytest.mark.slow),
    pytest.param("dask:local:2", marks=pytest.mark.slow)])
def test_the_geographic_root_grid_store_is_the_same_on_every_scheduler(tmp_path, spec):
    """A tall EPSG:4326 raster with voids, lossless and with ε (the height pass first,
    its decoded heights read by the others), after the xy pass, on worker processes and
    on a dask LocalCluster of 2 workers."""
    if spec.startswith("dask"):
        pytest.importorskip("distributed")
    src = _wide_geo_tif(tmp_path, 7, 150, 60, 0.05)
    for eps in (None, 1.0):
        a = preprocess(src, tmp_path / "a.gt", tile_size=16, codec_error=eps, root_grid=True,
                       overwrite=True)
        b = preprocess_streaming(src, tmp_path / "b.gt", tile_size=16, band=8,
                                 codec_error=eps, scheduler=spec, root_grid=True,
                                 overwrite=True)
        assert geoterrain.open(b).grid.roots == (1, 2)
        _assert_same_store(a, b)
        assert a.read_bytes() == b.read_bytes()


def test_a_geographic_mosaic_streams_to_the_root_grid_store(tmp_path):
    """A wide EPSG:4326 raster cut into four tiles (sharing a row and a column, as SRTM
    tiles do; one with its own nodata value): the list and its VRT stream to their
    whole-grid root-grid stores."""
    from geoterrain.ingest.mosaic import build_vrt
    from tests.ingest.test_mosaic import split

    rng = np.random.default_rng(9)
    z = (rng.normal(0, 20, (61, 190)).cumsum(0).cumsum(1) / 5 + 5000).astype(np.int16)
    z[rng.random(z.shape) < 0.05] = -32768
    merged = _geo_tif(tmp_path / "m.tif", z, -32768, west=-122.0, north=48.0, deg=1 / 1200)
    paths = split(Path(merged), tmp_path / "tiles", overlap=1,
                  nodatas=(-32768, -9999, -32768, -32768))
    tiles = [str(p) for p in paths]
    vrt = tmp_path / "mosaic.vrt"
    vrt.write_text(build_vrt(paths))
    for k, src in enumerate((tiles, str(vrt))):
        a = preprocess(src, tmp_path / f"a{k}.gt", tile_size=16, root_grid=True)
        b = preprocess_streaming(src, tmp_path / f"b{k}.gt", tile_size=16, band=4,
                                 root_grid=True)
        t = geoterrain.open(b)
        assert t.grid.roots == (2, 1) and t.frame.kind == "geographic"
        _assert_same_store(a, b)
        assert a.read_bytes() == b.read_bytes()


@pytest.mark.slow  # a subprocess and a 200 × 600 raster
def test_a_killed_geographic_root_grid_run_resumes_to_the_same_store(tmp_path, caplog):
    """SIGKILL of the driver once its first pass (the scene x, y over the extent) is
    recorded; ``resume`` reuses it and writes the uninterrupted run's store."""
    import logging

    from tests.preprocessing.test_streaming_root_grid import _killed_after_first_pass

    src = _wide_geo_tif(tmp_path, 5, 200, 600, 0.02)
    ref = preprocess(src, tmp_path / "ref.gt", root_grid=True)
    out = tmp_path / "out"
    out.mkdir()
    dst = out / "s.gt"
    _killed_after_first_pass(src, dst, 4, first="xy")
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        preprocess_streaming(src, dst, band=4, resume=True, root_grid=True)
    assert "resuming a killed run; passes done: xy" in caplog.text
    assert Path(ref).read_bytes() == dst.read_bytes()
    assert [x.name for x in out.iterdir()] == ["s.gt"]


def _open_under(folder) -> list[str]:
    # this process's descriptors on files under ``folder`` (Linux: /proc/self/fd)
    out = []
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):
            target = os.readlink(f"/proc/self/fd/{fd}")
            if target.startswith(str(folder)):
                out.append(target)
    return out


@pytest.mark.fast
@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="Linux's /proc/self/fd")
def test_an_array_created_again_keeps_no_second_descriptor(tmp_path):
    """A scratch array created again under its own name (bands.leaf copies level 0 back
    into C0, R0, K0) reads the new array, and close() leaves no descriptor on its file."""
    sa = ScratchArrays.shared(tmp_path / "a")
    sa.create("C0", (2, 3), np.float32)
    sa.write("C0", 0, np.ones((2, 3), np.float32))
    sa.create("C0", (2, 3), np.float32)
    assert sa.read("C0", 0, 2).sum() == 0.0  # the new, zeroed array
    assert len(_open_under(tmp_path)) == 1
    sa.close()
    assert _open_under(tmp_path) == []


@pytest.mark.fast
@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="Linux's /proc/self/fd")
def test_a_streamed_geographic_preprocess_leaves_no_descriptor_open(tmp_path):
    """Each streamed geographic preprocess (level 0's slack raised: C0, R0, K0 written
    again) closes every scratch file it opened: none is left open in this process once
    the store is written (three a run were, on files of a removed folder)."""
    src = _wide_geo_tif(tmp_path, 1, 50, 121, 0.05, north=80.0)
    out = tmp_path / "out"
    out.mkdir()
    preprocess_streaming(src, out / "b.gt", tile_size=8, band=4, root_grid=True)
    assert _open_under(out) == []
    assert geoterrain.open(out / "b.gt").frame.kind == "geographic"

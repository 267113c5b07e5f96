"""A geographic grid's streaming stages against their whole-grid twins (issue 45).

The metric terms (geoterrain.preprocessing.bands.curvature) are maxima over row bands of
the whole-grid kernels' passes, so they must be the same bits as
:func:`geoterrain.bounds.curvature.metric_terms`, for every band, on grids whose positions
come from pyproj (:class:`geoterrain.core.frame.Frame`): mid-latitudes, across the
antimeridian, down to a pole (padding rows past it clamp to the pole: slivers whose search
margin is the whole grid, deferred to the second sweep) and the whole world; and over the
edge-replicated grid of δ_edge with its base. Then what is built on them: δ raised and
saturated again, the renested radius codes, level 0's slack, the normals and the tile
table from each row's x, y, each against the whole-grid function.
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.edgepad import edge_support
from geoterrain.bounds.leafbounds import geographic_leaf_delta
from geoterrain.bounds.normals import encode_octahedral, level_normal_maps
from geoterrain.bounds.radii import vertex_radii
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.bands import curvature as bandcurv
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
from geoterrain.preprocessing.bands.normals import band_normal_codes
from geoterrain.preprocessing.bands.radii import band_metric_radius_codes
from geoterrain.preprocessing.bands.tiles import band_tile_bounds
from geoterrain.preprocessing.scratch import ScratchArrays

# (rows, cols, west, north, degrees a pixel): the extents the geographic frame must take
EXTENTS = {
    "mid": (40, 57, 10.0, 61.0, 0.02),
    "antimeridian": (50, 45, 179.5, 40.5, 0.02),
    "south_pole": (28, 70, -20.0, -80.0, 0.35),
    "world": (32, 64, -180.0, 90.0, 5.625),
    "north_pole": (20, 33, 0.0, 90.0, 1.0),
}


def _geo(rows, cols, west, north, deg, seed, holes, tile=8):
    """A padded geographic grid: scene X, Y from pyproj, heights with voids."""
    rng = np.random.default_rng(seed)
    tr = rasterio.transform.from_origin(west, north, deg, deg)
    frame = Frame.from_raster(tuple(tr)[:6], rasterio.crs.CRS.from_epsg(4326).to_wkt(), rows,
                              cols)
    g = Grid.for_shape(rows, cols, tile)
    X, Y = frame.grid_xy(g.size)
    z = rng.normal(0, 30, (rows, cols)).cumsum(0).cumsum(1) / 10
    v = rng.random((rows, cols)) >= holes
    return g, np.asarray(X), np.asarray(Y), g.pad(np.where(v, z, np.nan), np.nan), g.pad(v, False)


def _grid_of(sa, pre, N, dtype):
    """The (N, N) grid of per-level arrays ``{pre}{x}{k}``."""
    out = np.zeros((N, N), dtype)
    for k in range((N - 1).bit_length() - 1):
        h = 1 << k
        s = 2 * h
        for x, (di, dj) in zip("CRK", ((h, h), (h, 0), (0, h)), strict=True):
            out[di::s, dj::s] = sa.read(f"{pre}{x}{k}", 0, sa.shape(f"{pre}{x}{k}")[0])
    return out


def _xy(X, Y):
    return lambda a, b: (X[a:b], Y[a:b])


@settings(max_examples=12, deadline=None)
@given(extent=st.sampled_from(sorted(EXTENTS)), seed=st.integers(0, 10_000),
       holes=st.sampled_from([0.0, 0.05, 0.5]), band=st.sampled_from([2, 4, 16, 64]))
def test_banded_metric_terms_are_metric_terms(extent, seed, holes, band):
    """δ_m, r_m, the bulges and the largest margin of the original grid, and δ_edge's
    terms over the replicated grid with that base: the whole-grid bits, every band."""
    g, X, Y, Z, V = _geo(*EXTENTS[extent], seed, holes)
    N = g.size
    ref = metric_terms(X, Y, Z, V)
    sa = ScratchArrays()
    bt = band_metric_terms(rows_of(Z, V), _xy(X, Y), N, band, sa)
    assert np.array_equal(_grid_of(sa, "dm", N, float), ref[0])
    assert np.array_equal(_grid_of(sa, "rm", N, float), ref[1])
    assert np.array_equal(_grid_of(sa, "b", N, np.uint8).astype(bool), ref[2])
    assert bt.M == ref[3]
    Zr, ok = edge_support(Z, V, g)
    win = (g.rows, g.cols)
    eref = metric_terms(X, Y, Zr, ok, window=win, base=ref)
    band_metric_terms(rows_of(Zr, ok), _xy(X, Y), N, band, sa, pre="e", window=win, base=bt)
    assert np.array_equal(_grid_of(sa, "edm", N, float), eref[0])
    assert np.array_equal(_grid_of(sa, "eb", N, np.uint8).astype(bool), eref[2])


def test_slivers_at_a_pole_are_deferred_and_still_exact(monkeypatch):
    """Down to the south pole the padding's rows clamp to one point: triangles there have
    margins wider than any window. They are searched by the second sweep, and the terms
    are still the whole grid's."""
    g, X, Y, Z, V = _geo(*EXTENTS["south_pole"], 3, 0.0)
    N = g.size
    Zr, ok = edge_support(Z, V, g)
    base = metric_terms(X, Y, Z, V)
    ref = metric_terms(X, Y, Zr, ok, window=(g.rows, g.cols), base=base)
    seen = []
    real = bandcurv._deferred
    monkeypatch.setattr(bandcurv, "_deferred", lambda *a: seen.append(1) or real(*a))
    sa = ScratchArrays()
    bt = band_metric_terms(rows_of(Z, V), _xy(X, Y), N, 8, sa)
    band_metric_terms(rows_of(Zr, ok), _xy(X, Y), N, 8, sa, pre="e", window=(g.rows, g.cols),
                      base=bt)
    assert seen, "no triangle was deferred: the case no longer tests the second sweep"
    assert np.array_equal(_grid_of(sa, "edm", N, float), ref[0])


@settings(max_examples=8, deadline=None)
@given(extent=st.sampled_from(sorted(EXTENTS)), seed=st.integers(0, 10_000),
       holes=st.sampled_from([0.0, 0.1]), band=st.sampled_from([2, 8, 32]),
       on_disk=st.booleans())
def test_banded_geographic_bounds_are_the_whole_grid_bounds(tmp_path_factory, extent, seed,
                                                            holes, band, on_disk):
    """δ raised by the metric terms and saturated again, the radius codes nested on the
    raised radii, level 0's slack with δ re-saturated, and δ_edge following it: each
    the pipeline's whole-grid value (surface.vertex_bounds, levelblobs.tile_blobs)."""
    g, X, Y, Z, V = _geo(*EXTENTS[extent], seed, holes)
    N, n = g.size, g.n
    delta = vertex_errors(Z, V)
    radius = vertex_radii(X, Y, Z, V)
    terms = metric_terms(X, Y, Z, V)
    d_ref, r_ref = metric_bounds(delta, radius, X, Y, Z, V, terms=terms)
    codes, e = radius_codes(X, Y, Z, V, r_ref)
    before = d_ref.copy()
    slack = geographic_leaf_delta(d_ref, Z, V, g.t, terms[0], terms[2])
    sa = ScratchArrays(tmp_path_factory.mktemp("s") if on_disk else None)
    rows = rows_of(Z, V)
    band_vertex_errors(rows, N, band=band, scratch=sa, heights=True)
    bt = band_metric_terms(rows, _xy(X, Y), N, band, sa)
    raise_delta(sa, n)
    assert band_metric_radius_codes(sa, N, _xy(X, Y), budget=1 << 12) == e
    got = _grid_of(sa, "r", N, np.uint8)
    inner = np.ones((N, N), bool)
    inner[[0, 0, -1, -1], [0, -1, 0, -1]] = False  # the corners: not vertices, code 0
    assert np.array_equal(got[inner], codes[inner])
    copy_levels(sa, n, "", "db")
    got_slack = band_leaf_slack(sa, N, g.t, rows)
    assert got_slack == slack
    top = _saturate(sa, n, 1 << 12) if slack is not None else None
    assert np.array_equal(_grid_of(sa, "", N, np.float32), d_ref)
    if top is not None:
        assert top == float(np.max(d_ref, where=np.isfinite(d_ref), initial=0.0))
    # δ_edge: metric over the replicated grid, then following δ's raise where it was δ
    from geoterrain.bounds.delta import saturate
    from geoterrain.bounds.edgepad import edge_deltas

    Zr, ok = edge_support(Z, V, g)
    win = (g.rows, g.cols)
    de = edge_deltas(Zr, ok, g)
    et = metric_terms(X, Y, Zr, ok, window=win, base=terms)
    de, _ = metric_bounds(de, None, X, Y, Zr, ok, window=win, terms=et)
    if slack is not None:
        same = de == before
        de[same] = d_ref[same]
        saturate(de)
    se = ScratchArrays()
    erows = edge_rows(rows, win)
    band_vertex_errors(erows, N, band=band, scratch=se, data=win)
    band_metric_terms(erows, _xy(X, Y), N, band, se, pre="e", window=win, base=bt)
    raise_delta(se, n, terms="e")
    if slack is not None:
        follow_slack(se, sa, n)
        _saturate(se, n, 1 << 12)
    assert np.array_equal(_grid_of(se, "", N, np.float32), de)


@settings(max_examples=8, deadline=None)
@given(extent=st.sampled_from(sorted(EXTENTS)), seed=st.integers(0, 10_000),
       holes=st.sampled_from([0.0, 0.2]), band=st.sampled_from([2, 8, 64]))
def test_banded_normals_and_tile_table_take_each_row_s_x_y(extent, seed, holes, band):
    """Every level's normal codes and the tile table (level 0's x, y boxes) from the
    rows' scene x, y: the whole-grid maps and table."""
    g, X, Y, Z, V = _geo(*EXTENTS[extent], seed, holes)
    N = g.size
    levels = g.top_level + 1
    sa = ScratchArrays()
    zero = np.zeros(N)
    band_normal_codes(rows_of(Z, V), N, zero, zero, levels, sa, band=band, xy=_xy(X, Y))
    for L, m in enumerate(level_normal_maps(X, Y, Z, V, levels)):
        want = encode_octahedral(m, 8)
        assert np.array_equal(sa.read(f"n{L}", 0, len(want)).reshape(want.shape), want)
    got = band_tile_bounds(rows_of(Z, V), N, g.t, zero, zero, band=band, xy=_xy(X, Y))
    ref = tile_and_block_errors(Z, V, X, Y, g.t)
    assert got[0] == ref[0]
    assert np.array_equal(got[1], ref[1])


@pytest.mark.fast
def test_the_row_cache_reads_each_row_once():
    """Bands read in order share their overlap: each grid row is read once."""
    Z = np.arange(40.0).reshape(8, 5)
    V = np.ones_like(Z, bool)
    calls = []

    def rows(a, b):
        calls.append((a, b))
        return Z[a:b], V[a:b]

    cache = bandcurv.RowCache(rows, lambda a, b: (Z[a:b], Z[a:b]), 5, 0.01, (5, 5))
    g1 = cache.get(0, 4)
    g2 = cache.get(2, 7)
    assert calls == [(0, 4), (4, 7)]
    assert g1.w0 == 0 and g2.w0 == 2 and np.array_equal(g2.Z, Z[2:7])


@pytest.mark.fast
@pytest.mark.parametrize("capacity", [0, 15])
def test_the_row_cache_shifts_its_buffer_in_place(capacity):
    """Windows that overlap by more rows than they advance (a band and its halo on each
    side, as band_metric_terms reads them) hold the rows' values, invalid heights 0,
    each row read once, in buffers that are not reallocated once at capacity."""
    rng = np.random.default_rng(3)
    N, B, halo = 33, 4, 5
    Z = rng.normal(size=(N, N))
    Z[rng.random((N, N)) < 0.1] = np.nan
    X, Y = rng.normal(size=(2, N, N))
    calls = []

    def rows(a, b):
        calls.append((a, b))
        return Z[a:b], np.isfinite(Z[a:b])

    cache = bandcurv.RowCache(rows, lambda a, b: (X[a:b], Y[a:b]), N, 0.01, (N, N),
                              capacity=capacity)
    bufs = []
    for r0 in range(0, N - 1, B):
        i0, i1 = max(0, r0 - halo), min(N, r0 + B + halo + (r0 + B == N - 1))
        g = cache.get(i0, i1)
        v = np.isfinite(Z[i0:i1])
        assert g.w0 == i0 and np.array_equal(g.vb, v)
        assert np.array_equal(g.X, X[i0:i1]) and np.array_equal(g.Y, Y[i0:i1])
        assert np.array_equal(g.Z, np.where(v, Z[i0:i1], 0.0))
        bufs.append(g.X.base if g.X.base is not None else g.X)
    read = sorted(i for a, b in calls for i in range(a, b))
    assert read == list(range(N))
    if capacity:
        assert all(b is bufs[0] for b in bufs)

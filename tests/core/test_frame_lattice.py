"""A geographic root grid's frame past level 0's lattice (issue 45): pyproj's positions on
the lattice, bit for bit; past it the proxy of :meth:`Frame.xy` (each column continued by
its last step, each row likewise), finite, the same whichever points are asked with it;
the store records the lattice (schema 16) and a reader refuses a wrong one in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import CRS, Transformer

import geoterrain
from geoterrain.core.frame import Frame
from geoterrain.ingest.synth import generate, write_geotiff

pytestmark = pytest.mark.fast

WKT = CRS.from_epsg(4326).to_wkt()


def _frame(lat: float, lon: float, step: float, rows: int, cols: int) -> Frame:
    return Frame.from_raster((step, 0, lon, 0, -step, lat), WKT, rows, cols)


def _pyproj(f: Frame, i, j):
    """pyproj's scene X, Y of (i, j), point by point, without the frame's code."""
    a, _, c, _, e, fo = f.transform
    lon, lat = c + a * (np.asarray(j, float) + 0.5), fo + e * (np.asarray(i, float) + 0.5)
    tr = Transformer.from_crs(CRS.from_wkt(f.crs_wkt), CRS.from_wkt(f.aeqd_wkt),
                              always_xy=True)
    X, Y = tr.transform(lon, np.clip(lat, -90, 90))
    return np.asarray(X, float), np.asarray(Y, float)


frames = st.builds(lambda lat, lon, step, rows, cols, dr, dc: (lat, lon, step, rows, cols,
                                                               dr, dc),
                   st.floats(-70, 70), st.floats(-179, 170), st.sampled_from([1 / 1200, 0.01,
                                                                                0.2]),
                   st.integers(2, 40), st.integers(2, 40), st.integers(0, 5),
                   st.integers(0, 5))


@settings(max_examples=40, deadline=None)
@given(case=frames, seed=st.integers(0, 2**16), frac=st.booleans())
def test_pyproj_on_the_lattice_and_the_proxy_past_it(case, seed, frac):
    """On the lattice (i ≤ a, j ≤ b) the positions are pyproj's bit for bit; past it they
    are P(i', j') + d_i·(P(a, j') − P(a − 1, j')) + d_j·(P(i', b) − P(i', b − 1)) from
    pyproj's P (within float64 rounding), finite, and every column (row) past the last
    row (column) moves by its last step, monotone."""
    lat, lon, step, rows, cols, dr, dc = case
    R, C = rows + dr, cols + dc
    f = _frame(lat, lon, step, rows, cols).with_lattice((R, C))
    a, b = R - 1, C - 1
    rng = np.random.default_rng(seed)
    n = 300
    i = rng.integers(0, 3 * R, n).astype(float)
    j = rng.integers(0, 3 * C, n).astype(float)
    if frac:  # fractional indices (a water mesh's, an occlusion box's): the direct path
        i[::3] += rng.random(len(i[::3]))
    X, Y = f.xy(i, j)
    assert np.isfinite(X).all() and np.isfinite(Y).all()
    on = (i <= a) & (j <= b)
    PX, PY = _pyproj(f, i[on], j[on])
    np.testing.assert_array_equal(X[on], PX)
    np.testing.assert_array_equal(Y[on], PY)
    ic, jc = np.minimum(i, a), np.minimum(j, b)
    di, dj = np.maximum(i - a, 0), np.maximum(j - b, 0)
    ra, rb = _pyproj(f, np.full(n, a), jc), _pyproj(f, np.full(n, a - 1), jc)
    ca, cb = _pyproj(f, ic, np.full(n, b)), _pyproj(f, ic, np.full(n, b - 1))
    for k, V in enumerate((X, Y)):
        p = np.where(di > 0, ra[k], ca[k])
        want = p + di * (ra[k] - rb[k]) + dj * (ca[k] - cb[k])
        span = np.abs(ra[k] - rb[k]).max() + np.abs(ca[k] - cb[k]).max()
        np.testing.assert_allclose(V[~on], want[~on], rtol=0,
                                   atol=1e-9 * (1 + np.abs(want).max()) + 1e-9 * span)
    # along a column past the last row, Y steps by the last step (monotone); along a row
    # past the last column, X likewise
    col = f.xy(np.arange(a - 1, a + 6, dtype=float), np.full(7, float(min(b, 1))))
    row = f.xy(np.full(7, float(min(a, 1))), np.arange(b - 1, b + 6, dtype=float))
    dy, dx = np.diff(col[1]), np.diff(row[0])
    assert (np.sign(dy) == np.sign(dy[0])).all() and dy[0] != 0
    assert (np.sign(dx) == np.sign(dx[0])).all() and dx[0] != 0
    np.testing.assert_allclose(dy, dy[0], rtol=1e-9, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(case=frames, seed=st.integers(0, 2**16))
def test_a_position_is_the_same_whatever_is_asked_with_it(case, seed):
    """The xy pass asks band by band (broadcast rows × columns), the tile pool tile by
    tile, a mesh vertex by vertex (a fractional one sends its batch by the direct path):
    the same (i, j) gets the same bits in each."""
    lat, lon, step, rows, cols, dr, dc = case
    R, C = rows + dr, cols + dc
    f = _frame(lat, lon, step, rows, cols).with_lattice((R, C))
    ER, EC = 2 * R + 1, 2 * C + 1
    X, Y = f.grid_xy((ER, EC))
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, ER, 50), rng.integers(0, EC, 50)
    for ii, jj in ((i, j), (i.astype(float), j.astype(float))):
        x, y = f.xy(ii, jj)
        np.testing.assert_array_equal(x, X[i, j])
        np.testing.assert_array_equal(y, Y[i, j])
    # with a fractional index in the batch (the direct path for every point past the lattice)
    x, y = f.xy(np.append(i, 0.5), np.append(j, 0.0))
    np.testing.assert_array_equal(x[:-1], X[i, j])
    np.testing.assert_array_equal(y[:-1], Y[i, j])
    # a band of rows against the columns (the xy pass)
    r0 = int(rng.integers(0, ER))
    bx, by = f.xy(np.arange(r0, min(r0 + 7, ER))[:, None], np.arange(EC)[None, :])
    np.testing.assert_array_equal(bx, X[r0:r0 + 7])
    np.testing.assert_array_equal(by, Y[r0:r0 + 7])


def test_the_frame_s_json_keeps_the_lattice_and_omits_none():
    f = _frame(61.0, 24.0, 1 / 1200, 50, 121)
    assert "lattice" not in f.to_json()
    assert Frame.from_json(json.loads(json.dumps(f.to_json()))) == f
    g = f.with_lattice((57, 121))
    assert g.to_json()["lattice"] == [57, 121]
    assert Frame.from_json(json.loads(json.dumps(g.to_json()))) == g
    assert Frame.pixel(5, 5).with_lattice((9, 9)) == Frame.pixel(5, 5)  # affine: no proxy
    with pytest.raises(ValueError, match="does not hold"):
        f.with_lattice((49, 121))


def test_a_store_past_its_lattice_records_it_and_only_that_one(tmp_path):
    """A geographic root grid whose extent passes its lattice: schema 22 and the frame's
    lattice (the grid's level-0 shape); the same raster projected, and a geographic one
    that fills its roots, keep schema 21 / 20 and no lattice."""
    from geoterrain.store.reader import StoreReader
    from geoterrain.store.schema import LATTICE_SCHEMA_VERSION, ROOTS_SCHEMA_VERSION, SCHEMA_VERSION

    z = generate("fbm", 129, seed=4)
    geo = dict(crs="EPSG:4326", origin=(24.0, 61.0), spacing=1 / 1200)
    cases = {"wide": (z[:40, :117], geo, LATTICE_SCHEMA_VERSION, (41, 121)),
             "wide-utm": (z[:40, :117], {}, ROOTS_SCHEMA_VERSION, None),
             "full": (z[:65, :129], geo, ROOTS_SCHEMA_VERSION, None),
             "one root": (z[:100, :100], geo, LATTICE_SCHEMA_VERSION, (105, 105)),
             "square": (z[:100, :100], geo, SCHEMA_VERSION, None)}
    for name, (a, kw, version, lattice) in cases.items():
        src = write_geotiff(tmp_path / f"{name}.tif", np.ascontiguousarray(a), **kw)
        p = geoterrain.preprocess(src, tmp_path / f"{name}.geoterrain", tile_size=8,
                                  root_grid=name != "square")
        t = geoterrain.open(p)
        assert StoreReader(p).metadata["schema_version"] == version, name
        assert t.frame.lattice == lattice, name
        if lattice is not None:
            assert t.grid.shape == lattice and t.grid.extent != t.grid.shape


def test_the_tile_pool_reads_the_preprocess_s_positions(tmp_path):
    """Every reader takes its positions from Frame.xy: the tile pool's x, y of each tile
    (what the static mesh, its clip and the views draw) are the whole grid's (what the
    preprocess computed the bounds on) bit for bit, and past the lattice they are the
    proxies, not pyproj's."""
    import dataclasses

    z = generate("fbm", 129, seed=9)[:40, :117].copy()
    src = write_geotiff(tmp_path / "w.tif", z, crs="EPSG:4326", origin=(24.0, 61.0),
                        spacing=1 / 1200)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "w.geoterrain", tile_size=8))
    g = t.grid
    assert t.frame.lattice == g.shape and g.extent != g.shape
    X, Y = t.frame.grid_xy(g.extent)
    PX, PY = dataclasses.replace(t.frame, lattice=None).grid_xy(g.extent)
    past = 0
    for L in g.levels:
        for ty in range(g.tiles(L)[1]):
            for tx in range(g.tiles(L)[0]):
                x, y = t.tile_xy(L, tx, ty)
                ii, jj = np.meshgrid(g.tile_rows(L, ty), g.tile_cols(L, tx), indexing="ij")
                np.testing.assert_array_equal(x, X[ii, jj])
                np.testing.assert_array_equal(y, Y[ii, jj])
                out = (ii >= g.shape[0]) | (jj >= g.shape[1])
                past += int(out.sum())
                assert not (np.array_equal(x[out], PX[ii, jj][out])
                            and np.array_equal(y[out], PY[ii, jj][out])) or not out.any()
    assert past > 0


@pytest.mark.parametrize("roots", [False, True])
def test_an_affine_tile_s_positions_are_xy_of_its_meshgrid(tmp_path, roots):
    """A projected frame's tile positions (from the rows' column and the columns' row,
    broadcast) are Frame.xy of the tile's meshgrid bit for bit, at every level, each a
    fresh writable (T, T) float64 array (callers write into what they are handed)."""
    z = generate("fbm", 129, seed=4)[:40, :117].copy()
    src = write_geotiff(tmp_path / "p.tif", z, origin=(512345.25, 5012345.75),
                        spacing=(7.3, 11.9))
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "p.geoterrain", tile_size=8,
                                              root_grid=roots))
    g, T = t.grid, t.grid.tile_samples
    assert t.frame.kind != "geographic"
    for L in g.levels:
        for ty in range(g.tiles(L)[1]):
            for tx in range(g.tiles(L)[0]):
                x, y = t.tile_xy(L, tx, ty)
                ii, jj = np.meshgrid(g.tile_rows(L, ty), g.tile_cols(L, tx), indexing="ij")
                want = t.frame.xy(ii, jj)
                for a, b in zip((x, y), want, strict=True):
                    assert a.shape == (T, T) and a.dtype == np.float64
                    assert a.tobytes() == b.tobytes()
                    assert a.flags.writeable and a.flags.c_contiguous and a.base is None
    t.close()


@pytest.mark.parametrize("band", [2, 8, 64])
def test_the_xy_pass_writes_the_whole_grid_s_positions(tmp_path, band):
    """The streamed preprocess's xy pass (band by band, into the scratch arrays every
    later pass reads) writes grid_xy's values bit for bit, proxies past the lattice."""
    import os

    from geoterrain.core.grid import Grid
    from geoterrain.preprocessing.passes import XY, Job, _xy_pass
    from geoterrain.preprocessing.scratch import ScratchArrays

    g = Grid.for_shape(40, 117, tile_size=8, roots=True)
    f = _frame(61.0, 24.0, 1 / 1200, 40, 117).with_lattice(g.shape)
    assert g.extent != g.shape
    _xy_pass(Job(None, g.to_json(), f.to_json(), None, band, str(tmp_path), True))
    sx = ScratchArrays.shared(os.path.join(tmp_path, XY))
    try:
        X, Y = f.grid_xy(g.extent)
        np.testing.assert_array_equal(sx.read("X", 0, g.extent[0]), X)
        np.testing.assert_array_equal(sx.read("Y", 0, g.extent[0]), Y)
    finally:
        sx.close()

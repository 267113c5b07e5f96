"""The whole-grid preprocess and the reader on a rectangular root grid (issue 45; the
default layout, ``root_grid=False`` / ``--square-grid`` for the square): the store's
tiles, heights and δ against the raster and an independent reference, the reader's tile
arithmetic, the layout each way of asking gives, and the one-line refusal of the
square-only grid figures. The meshes of a root grid are measured in
tests/test_stress.py."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import write_tif
from geoterrain.core.grid import Grid, RootGridError
from geoterrain.ingest.synth import generate
from geoterrain.lod import STRATEGIES
from geoterrain.lod.kernels import _coarsest_tile
from geoterrain.store.reader import StoreReader
from geoterrain.store.schema import ROOTS_SCHEMA_VERSION, SCHEMA_VERSION

pytestmark = pytest.mark.fast


def fbm(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    z = generate("fbm", max(rows, cols), seed=seed)[:rows, :cols]
    return np.rint(500.0 * (z - z.min()) / max(float(np.ptp(z)), 1e-12))


def roots_store(tmp_path, z, name="r", tile_size=16, **pre):
    src = write_tif(tmp_path / f"{name}.tif", z, dtype="int16")
    return geoterrain.preprocess(src, tmp_path / f"{name}.geoterrain", tile_size=tile_size,
                                 root_grid=True, **pre)


@pytest.fixture(scope="module")
def wide(tmp_path_factory):
    """A 50 × 121 raster (a void inside) on 2 × 1 roots of 8-sample tiles."""
    d = tmp_path_factory.mktemp("roots")
    z = fbm(50, 121, seed=4).astype(np.int16)
    z[20:24, 30:41] = -9999
    src = write_tif(d / "w.tif", z, dtype="int16", nodata=-9999)
    store = geoterrain.preprocess(src, d / "w.geoterrain", tile_size=8, root_grid=True)
    return geoterrain.open(store), z


def test_the_store_is_a_root_grid_with_every_data_tile(wide):
    t, z = wide
    g = t.grid
    assert (g.layout, g.roots, g.shape) == ("roots", (2, 1), (57, 121))
    assert StoreReader(t.path).metadata["schema_version"] == ROOTS_SCHEMA_VERSION
    valid = z != -9999
    want = set()
    for L in g.levels:  # brute force: tiles of the grid whose footprint holds data
        s = g.tile_span(L)
        tx, ty = g.tiles(L)
        for y in range(ty):
            for x in range(tx):
                if valid[y * s:(y + 1) * s + 1, x * s:(x + 1) * s + 1].any():
                    want.add((L, x, y))
    assert set(t.tile_info) == want


def test_heights_decode_to_the_raster_at_every_level(wide):
    t, z = wide
    valid = z != -9999
    for L in t.grid.levels:
        h, v = t.level_heights(L)
        s = 1 << L
        zl, vl = z[::s, ::s], valid[::s, ::s]
        assert h.shape == t.grid.level_shape(L)
        assert np.array_equal(v[:zl.shape[0], :zl.shape[1]], vl)
        assert np.array_equal(h[:zl.shape[0], :zl.shape[1]][vl], zl[vl].astype(np.float64))
        assert not v[zl.shape[0]:].any() and not v[:, zl.shape[1]:].any()


def test_delta_bounds_an_independent_reference(wide):
    # δ as stored (log8 codes rounded up) against the numpy reference on the roots'
    # extent (testing.reference: one pass per depth, not the production kernels),
    # saturated by the reference's own pass
    from geoterrain.testing.reference import saturate, vertex_errors_reference

    t, z = wide
    g = t.grid
    R, C = g.extent
    zz = np.zeros((R, C))
    ok = np.zeros((R, C), bool)
    ok[:g.rows, :g.cols] = z != -9999
    zz[:g.rows, :g.cols] = t.frame.z(z.astype(np.float64))
    ref = saturate(vertex_errors_reference(zz, ok, span=1 << g.n), 1 << g.n)
    i, j = (a.ravel() for a in np.indices((g.rows, g.cols)))
    got = t.gather(i, j, ("delta",))["delta"]
    want = ref[i, j]
    assert np.array_equal(np.isinf(got), np.isinf(want))
    fin = np.isfinite(want)
    assert (got[fin] >= want[fin]).all()
    assert (got[fin] <= 1.1 * want[fin] + 1e-3).all()  # one code step at most


def test_a_square_raster_keeps_the_square_store(tmp_path):
    src = write_tif(tmp_path / "s.tif", fbm(65, 65, seed=1), dtype="int16")
    a, b = (geoterrain.preprocess(src, tmp_path / f"{k}.geoterrain", tile_size=16,
                                  root_grid=k == "a") for k in "ab")
    assert geoterrain.open(a).grid.square and a.read_bytes() == b.read_bytes()




def test_the_root_grid_is_the_default_and_the_square_an_option(tmp_path):
    """No argument, ``root_grid=True`` and ``--root-grid`` write the same root-grid store
    (schema 21); ``root_grid=False`` and ``--square-grid`` the square (schema 20), as the
    stores before root grids were."""
    from click.testing import CliRunner

    from geoterrain.cli.main import cli

    src = write_tif(tmp_path / "w.tif", fbm(40, 100, seed=3), dtype="int16")
    d = geoterrain.preprocess(src, tmp_path / "d.gt", tile_size=16)
    r = geoterrain.preprocess(src, tmp_path / "r.gt", tile_size=16, root_grid=True)
    s = geoterrain.preprocess(src, tmp_path / "s.gt", tile_size=16, root_grid=False)
    for name, args in {"cd.gt": [], "cr.gt": ["--root-grid"], "cs.gt": ["--square-grid"]}.items():
        res = CliRunner().invoke(cli, ["-q", "preprocess", str(src), "-o", str(tmp_path / name),
                                       "--tile-size", "16", *args], catch_exceptions=False)
        assert res.exit_code == 0, res.output
    g = geoterrain.open(d).grid
    assert (g.layout, g.roots, g.shape) == ("roots", (2, 1), (49, 113))
    assert geoterrain.open(s).grid == Grid.for_shape(40, 100, 16)  # 129², one top tile
    for a, b in ((d, r), (d, tmp_path / "cd.gt"), (d, tmp_path / "cr.gt"),
                 (s, tmp_path / "cs.gt")):
        assert a.read_bytes() == b.read_bytes(), (a, b)
    assert StoreReader(d).metadata["schema_version"] == ROOTS_SCHEMA_VERSION
    assert StoreReader(s).metadata["schema_version"] == SCHEMA_VERSION


def test_a_geographic_root_grid_is_built(tmp_path):
    # the metric bounds of a geographic grid on the roots' extent (their invariants:
    # tests/bounds/test_root_curvature.py; the meshes: tests/test_stress.py)
    src = write_tif(tmp_path / "g.tif", fbm(33, 65), crs="EPSG:4326", origin=(10.0, 45.0),
                    spacing=0.001, dtype="int16")
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "g.geoterrain", tile_size=16,
                                              root_grid=True))
    assert (t.frame.kind, t.grid.layout, t.grid.roots) == ("geographic", "roots", (2, 1))
    assert StoreReader(t.path).metadata["schema_version"] == ROOTS_SCHEMA_VERSION


def test_the_reader_sees_every_root(wide):
    t, z = wide
    lo, hi = t.scene_box()
    X, Y, Z = t.scene_xyz()
    ok = np.isfinite(Z)
    assert lo[0] <= X.min() and hi[0] >= X.max() and lo[1] <= Y.min() and hi[1] >= Y.max()
    assert lo[2] <= np.nanmin(Z) and hi[2] >= np.nanmax(Z)
    assert np.array_equal(ok, z != -9999)
    assert t.info()["padded"] == [57, 121]
    assert t.block_errors().shape[:2] == (t.grid.tiles(0)[1], t.grid.tiles(0)[0])


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 300), st.integers(3, 300), st.sampled_from([2, 4, 8, 16]))
def test_the_tile_table_and_the_kernels_find_each_samples_coarsest_tile(rows, cols, ts):
    g = Grid.for_shape(rows, cols, ts, roots=True)
    keys = np.array([(L, x, y) for L in g.levels for y in range(g.tiles(L)[1])
                     for x in range(g.tiles(L)[0])], np.int64)
    idx = g.table_index(keys)
    assert np.array_equal(idx, np.arange(g.offsets()[-1]))
    assert all(g.key_of(int(k)) == tuple(key) for k, key in zip(idx, keys.tolist(), strict=True))
    base, top, t = g.walk_table(), g.top_level, g.t
    R, C = g.extent
    for i in range(0, R, max(1, R // 13)):
        for j in range(0, C, max(1, C // 13)):
            L, e, a, b = _coarsest_tile(i, j, top, t, base)
            low = (i | j) & -(i | j) if i | j else 1 << 62  # brute force: the level,
            want_L = min(top, (low.bit_length() - 1))  # then any tile holding the sample
            s, (tx, ty) = g.tile_span(want_L), g.tiles(want_L)
            # the tiles whose closed box holds (i, j): the one it lies in, and the one
            # before where it lies on their shared border
            holders = [(x, y) for y in {i // s, i // s - (i % s == 0)} if 0 <= y < ty
                       for x in {j // s, j // s - (j % s == 0)} if 0 <= x < tx]
            assert L == want_L
            if not holders:
                assert e == -1
                continue
            LL, x, y = g.key_of(int(e))
            assert LL == L and (x, y) in holders
            assert (a, b) == ((i >> L) - (y << t), (j >> L) - (x << t))


def test_every_strategy_draws(wide):
    # the meshes' guarantees on root grids are measured in tests/test_stress.py
    t, _ = wide
    view = geoterrain.View((0.0, -900.0, 700.0), (0.0, 0.0, 0.0), size=(160, 90))
    for name in STRATEGIES:
        assert t.select(view, 2.0, name).stats["triangles"] > 0, name
    assert t.static_selection(1.0, mesher="tin").stats["triangles"] > 0


def test_a_square_only_computation_refuses_a_root_grid_in_one_line(wide):
    # every consumer reads a root grid (edits, the globe, every strategy); what still
    # asks the grid for a square's figures (N, tiles a side) gets one line naming the
    # root grid's own
    t, _ = wide
    for what, call in {"the padded size N": lambda: t.grid.size,
                       "tiles per side": lambda: t.grid.tiles_per_side(0),
                       "the level size": lambda: t.grid.level_size(1)}.items():
        with pytest.raises(RootGridError, match="needs a square grid") as e:
            call()
        assert what in str(e.value) and "\n" not in str(e.value), what
        assert "tiles(L)" in str(e.value) and "2 × 1 root tiles" in str(e.value)

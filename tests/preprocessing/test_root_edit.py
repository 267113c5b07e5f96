"""Editing a root-grid store (issue 45 with issue 52's invariant): the edited store is
the root-grid store preprocessed from the edited DEM, on 2 × 1 and 1 × 2 roots, windows
across the roots' shared edge, at the data's edge and over voids; a killed edit leaves
the old store.

The oracle is the square tests' (tests/preprocessing/editcheck.py): every blob, tile row
and metadata entry compared, the height blobs allowed other bytes only where the fresh
preprocess chose the other predictor (then the same decoded codes).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import InputError
from geoterrain.preprocessing.edit import Patch, edit_terrain
from tests.preprocessing.editcheck import (
    apply_by_hand,
    assert_same_store,
    integer_dem,
    write_dem,
)
from tests.preprocessing.test_edit import _KILLED

NODATA = -9999.0


def _root_store(path, z, tile, geographic=False):
    store = geoterrain.preprocess(write_dem(path, z, NODATA, geographic), tile_size=tile,
                                  root_grid=True)
    with geoterrain.open(store) as t:
        assert not t.grid.square
    return store


@st.composite
def root_edits(draw):
    """A DEM of 2 × 1 (``wide``) or 1 × 2 roots of span ``s`` = tile · 2^k, and a window
    across the roots' shared edge, at the data's edge (past it: clipped) or anywhere; on a
    projected or a geographic frame."""
    tile = draw(st.sampled_from([4, 8]))
    s = tile << draw(st.integers(1, 2))
    long_side = draw(st.integers(s + 2, 2 * s + 1))  # more than one root, at most two
    short_side = draw(st.integers(5, s + 1))
    wide = draw(st.booleans())
    rows, cols = (short_side, long_side) if wide else (long_side, short_side)
    holes = draw(st.sampled_from([0.0, 0.03, 0.3]))
    h, w = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    where = draw(st.sampled_from(["seam", "seam", "edge", "anywhere"]))
    row = draw(st.integers(-h + 1, rows - 1))
    col = draw(st.integers(-w + 1, cols - 1))
    if where == "seam":  # the window holds the shared edge (column or row s)
        if wide:
            col = draw(st.integers(s - w + 1, s))
        else:
            row = draw(st.integers(s - h + 1, s))
    elif where == "edge":  # over the last row or column, or past it
        if draw(st.booleans()):
            row = draw(st.integers(rows - h, rows - 1))
        else:
            col = draw(st.integers(cols - w, cols - 1))
    mode = draw(st.sampled_from(["replace", "add", "min", "max"]))
    kind = draw(st.sampled_from(["const", "rough", "holes"]))
    return (rows, cols, tile, holes, row, col, h, w, mode, kind, draw(st.integers(0, 999)),
            draw(st.booleans()))


def _patch(kind, h, w, seed, mode):
    rng = np.random.default_rng(seed)
    if kind == "const":
        p = np.full((h, w), -37.0 if mode in ("add", "min") else 640.0)
    else:
        p = np.rint(rng.normal(0 if mode == "add" else 500, 40, (h, w)))
    if kind == "holes":
        p[rng.random((h, w)) < 0.3] = np.nan
    return p


@settings(max_examples=8, deadline=None)
@given(e=root_edits())
def test_edited_root_grid_store_is_the_preprocessed_edited_dem(tmp_path_factory, e):
    rows, cols, tile, holes, row, col, h, w, mode, kind, seed, geographic = e
    z = integer_dem(seed, rows, cols, holes)
    p = _patch(kind, h, w, seed, mode)
    tmp = tmp_path_factory.mktemp("red")
    (tmp / "a").mkdir()
    (tmp / "b").mkdir()
    store = _root_store(tmp / "a" / "dem.tif", z, tile, geographic)
    try:
        with geoterrain.open(store) as t:
            res = edit_terrain(t, Patch(row, col, p), mode)
    except InputError as exc:  # the patch misses the DEM
        assert "outside" in str(exc)
        return
    fresh = _root_store(tmp / "b" / "dem.tif", apply_by_hand(z, row, col, p, mode), tile,
                        geographic)
    assert_same_store(store, fresh)
    if res.window is not None:
        assert res.rows > 0
        with geoterrain.open(store) as t:  # what the edit wrote reads back
            hh, vv = t.level_heights(0)
            want = apply_by_hand(z, row, col, p, mode)
            assert np.array_equal(vv[:rows, :cols], ~np.isnan(want))
            assert np.array_equal(hh[:rows, :cols][vv[:rows, :cols]], want[~np.isnan(want)])


@pytest.mark.fast
def test_a_window_across_the_seam_updates_both_roots(tmp_path):
    """A 2 × 1 root grid: a window over the shared column rewrites both roots' blobs and
    the heights read back on both sides (Terrain.edit, which refreshes the reader)."""
    from geoterrain.store.database import StoreReader

    z = integer_dem(3, 40, 120)
    store = _root_store(tmp_path / "dem.tif", z, 16)

    def tops(top):
        r = StoreReader(store)
        try:
            return {(x, kind): r.get_blob((top, x, 0), kind) for x in (0, 1)
                    for kind in ("heights", "delta")}
        finally:
            r.close()

    with geoterrain.open(store) as t:
        s, top = 1 << t.grid.n, t.grid.top_level
        assert t.grid.roots == (2, 1) and s == 64 and top == 2
        before = tops(top)
        # rows 10 … 14, columns 61 … 67: sample (12, 64) is on both roots' shared edge
        res = t.edit((10, s - 3), np.full((5, 7), 900.0))
        assert res.changed == 35
        after = tops(top)
        assert all(after[k] != before[k] for k in before), [k for k in before
                                                            if after[k] == before[k]]
        h, _ = t.level_heights(0)
        assert np.all(h[10:15, s - 3:s + 4] == 900.0)
        assert np.all(t.tile(top, 0, 0).heights[3, 16] == 900.0)  # the shared sample
        assert np.all(t.tile(top, 1, 0).heights[3, 0] == 900.0)
        assert t.meta["edits"]["last"][-1]["window"] == [10, s - 3, 5, 7]

@pytest.mark.slow  # a child process: about 5 s
def test_killed_edit_leaves_the_old_root_grid_store(tmp_path):
    """SIGKILL at the commit of an edit of a 2 × 1 root grid (pages already in the file):
    the next open rolls it back, byte for byte (the square's test, on roots)."""
    z = integer_dem(7, 40, 120)
    store = _root_store(tmp_path / "dem.tif", z, 16)
    before = store.read_bytes()
    ready = tmp_path / "ready"
    proc = subprocess.Popen([sys.executable, "-c", _KILLED, str(store), str(ready)],
                            cwd=os.getcwd())
    try:
        for _ in range(600):
            if ready.exists() or proc.poll() is not None:
                break
            time.sleep(0.1)
        assert ready.exists(), "the edit never reached its commit"
        assert store.read_bytes() != before
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    with geoterrain.open(store) as t:
        assert t.meta.get("edits") is None
        assert t.tile(0, 0, 0).heights[5, 6] == z[5, 6]
    assert store.read_bytes() == before


@pytest.mark.fast
def test_lossy_root_grid_store_keeps_its_bound_across_the_seam(tmp_path):
    """A root-grid store coded within ε (residual bins: the pyramid coded again over the
    roots' extent) takes any height across the roots' shared edge, within ε of it."""
    z = integer_dem(4, 33, 60) + 0.37
    store = geoterrain.preprocess(write_dem(tmp_path / "dem.tif", z), tile_size=8,
                                  codec_error=0.5, root_grid=True)
    with geoterrain.open(store) as t:
        assert t.grid.roots == (2, 1) and t.quantizer.bins > 1
        before, _ = t.level_heights(0)
        res = t.edit((10, 28), np.full((5, 9), 432.123))
        assert res.how == "whole grid"
        h, v = t.level_heights(0)
        assert v[10:15, 28:37].all()
        assert np.abs(h[10:15, 28:37] - 432.123).max() <= 0.5 + 1e-9
        # the rest: the store's decoded heights (the edit's input, the DEM being gone)
        # coded again within ε, as on the square
        ok = np.ones(z.shape, bool)
        ok[10:15, 28:37] = False
        assert np.abs(h[:33, :60][ok] - before[:33, :60][ok]).max() <= 0.5 + 1e-9


@pytest.mark.parametrize("row, col", [(0, 52), (8, 0), (8, 52)])
def test_a_window_on_the_data_s_last_row_or_column_reads_the_last_tile(tmp_path, row, col):
    """A 9 × 53 raster on its default root grid of 4-sample tiles: its last row and column
    are the far border of the last tiles (no tile starts there). A one-sample edit there
    changes the store as a preprocess of the edited DEM (found by test_edit.py's property
    once root grids became the default: the window read nothing there, and the edit was
    dropped)."""
    from tests.preprocessing.test_edit import _stores

    z = integer_dem(0, 9, 53, 0.0)
    store, fresh, res = _stores(tmp_path, z, 4, np.full((1, 1), -37.0), row, col, "add",
                                "auto")
    assert geoterrain.open(store).grid.layout == "roots"
    assert res.changed == 1
    assert_same_store(store, fresh)

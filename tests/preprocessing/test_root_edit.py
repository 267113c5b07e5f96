"""Editing a root-grid store (issue 45 with issue 52's invariant): the edited store is
the root-grid store preprocessed from the edited DEM, on 2 × 1 and 1 × 2 roots, windows
across the roots' shared edge, at the data's edge and over voids; a killed edit leaves
the old store.

The oracle is the square tests' (tests/preprocessing/editcheck.py): every blob, tile row
and metadata entry compared, the height blobs allowed other bytes only where the fresh
preprocess chose the other predictor (then the same decoded codes).
"""

from __future__ import annotations

import shutil
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import InputError
from geoterrain.preprocessing.edit import Patch, edit_terrain
from tests.preprocessing.editcheck import (
    SLOW_COMMIT,
    apply_by_hand,
    assert_same_store,
    integer_dem,
    paused_at_commit,
    random_patch,
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


@settings(max_examples=8, deadline=None)
@given(e=root_edits())
def test_edited_root_grid_store_is_the_preprocessed_edited_dem(tmp_path_factory, e):
    rows, cols, tile, holes, row, col, h, w, mode, kind, seed, geographic = e
    z = integer_dem(seed, rows, cols, holes)
    p = random_patch(kind, h, w, seed, mode)
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
    from geoterrain.store.reader import StoreReader

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
    with paused_at_commit(_KILLED, ready, str(store), str(ready)):
        assert store.read_bytes() != before
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


# ------------------------------------------------------------------ the edit by tiles


def _filled_roots(seed, tile, k, wide, voids):
    """A DEM that fills 2 × 1 (``wide``) or 1 × 2 roots of side tile · 2^k (no padding:
    the edit by tiles takes it), with ``voids`` ("none", "spots": a few samples,
    "block": a 3 × 3 void)."""
    s = tile << k
    rows, cols = (s + 1, 2 * s + 1) if wide else (2 * s + 1, s + 1)
    z = integer_dem(seed, rows, cols, 0.003 if voids == "spots" else 0.0)
    if voids == "block":
        rng = np.random.default_rng(seed)
        i, j = int(rng.integers(0, rows - 3)), int(rng.integers(0, cols - 3))
        z[i:i + 3, j:j + 3] = np.nan
    return z, s


@st.composite
def tile_root_edits(draw):
    """An edit of filled roots: a window across the roots' shared edge, with a corner on
    a tile border, over the data's last row or column (the extent's edge: these roots
    leave no padding), over a void, or anywhere."""
    tile = draw(st.sampled_from([4, 8]))
    k = draw(st.integers(1, 2))
    wide = draw(st.booleans())
    voids = draw(st.sampled_from(["none", "none", "spots", "block"]))
    seed = draw(st.integers(0, 999))
    z, s = _filled_roots(seed, tile, k, wide, voids)
    rows, cols = z.shape
    h, w = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    where = draw(st.sampled_from(["seam", "seam", "border", "edge", "void", "anywhere"]))
    row = draw(st.integers(-h + 1, rows - 1))
    col = draw(st.integers(-w + 1, cols - 1))
    if where == "seam":
        if wide:
            col = draw(st.integers(s - w + 1, s))
        else:
            row = draw(st.integers(s - h + 1, s))
    elif where == "border":
        row, col = row - row % tile, col - col % tile
    elif where == "edge":
        if draw(st.booleans()):
            row = draw(st.integers(rows - h, rows - 1))
        else:
            col = draw(st.integers(cols - w, cols - 1))
    elif where == "void" and np.isnan(z).any():
        ii, jj = np.nonzero(np.isnan(z))
        q = draw(st.integers(0, len(ii) - 1))
        row, col = int(ii[q]) - h // 2, int(jj[q]) - w // 2
    mode = draw(st.sampled_from(["replace", "add", "min", "max"]))
    kind = draw(st.sampled_from(["const", "rough", "holes"]))
    return z, tile, row, col, h, w, mode, kind, seed, voids


# the reasons a square store's edit takes the whole grid too (a store-wide number moves,
# or nodata whose reach the tiles cannot bound): the root grid's by tiles says the same
_STORE_WIDE = ("code scale", "largest vertex error", "stand-in height", "nodata")


@pytest.mark.slow  # 12 examples, two preprocesses each: about 30 s
@settings(max_examples=12, deadline=None)
@given(e=tile_root_edits())
def test_root_grid_edit_by_tiles_is_the_preprocessed_edited_dem(tmp_path_factory, e):
    """Issue 45 × 52: on filled 2 × 1 and 1 × 2 roots the edit takes the tiles' path
    (asserted through what it reports) and the store it leaves is the root-grid store
    preprocessed from the edited DEM: every blob, tile row and metadata entry (the
    square tests' oracle)."""
    z, tile, row, col, h, w, mode, kind, seed, voids = e
    p = random_patch(kind, h, w, seed, mode)
    tmp = tmp_path_factory.mktemp("rtl")
    (tmp / "a").mkdir()
    (tmp / "b").mkdir()
    store = _root_store(tmp / "a" / "dem.tif", z, tile)
    try:
        with geoterrain.open(store) as t:
            res = edit_terrain(t, Patch(row, col, p), mode)
    except InputError as exc:  # the patch misses the DEM
        assert "outside" in str(exc)
        return
    if res.window is not None:
        if voids == "none" and not any(w in res.why for w in _STORE_WIDE):
            assert res.how == "tiles", res.why
        assert res.how == "tiles" or any(w in res.why for w in _STORE_WIDE), res.why
    fresh = _root_store(tmp / "b" / "dem.tif", apply_by_hand(z, row, col, p, mode), tile)
    assert_same_store(store, fresh)


@pytest.mark.slow  # 16 edits of 8 stores: about 40 s
@pytest.mark.parametrize("wide", [True, False])
def test_most_root_grid_edits_take_the_tiles(tmp_path, wide):
    """Windows across the shared edge of filled roots, with and without voids: the edit
    takes the tiles' path for most (the others name a store-wide number or nodata) and
    writes what the whole grid's edit writes."""
    took = []
    rng = np.random.default_rng(7 if wide else 8)
    for k in range(8):
        z, s = _filled_roots(int(rng.integers(1000)), 8, 2, wide, ["none", "spots"][k % 2])
        h, w = int(rng.integers(2, 14)), int(rng.integers(2, 14))
        row, col = int(rng.integers(0, z.shape[0] - h)), int(rng.integers(0, z.shape[1] - w))
        if wide:
            col = s - w // 2
        else:
            row = s - h // 2
        mode = str(rng.choice(["replace", "add", "min", "max"]))
        p = np.rint(rng.normal(0 if mode == "add" else float(np.nanmedian(z)), 12, (h, w)))
        d = tmp_path / f"c{k}"
        d.mkdir()
        a = _root_store(d / "dem.tif", z, 8)
        b = shutil.copy(a, d / "b.geoterrain")
        with geoterrain.open(a) as t:
            ra = edit_terrain(t, Patch(row, col, p), mode)
        with geoterrain.open(b) as t:
            edit_terrain(t, Patch(row, col, p), mode, how="whole grid")
        assert_same_store(a, b)
        if ra.window is not None:
            took.append(ra.how == "tiles" or ra.why)
    assert all(v is True or any(w in v for w in _STORE_WIDE) for v in took), took
    assert sum(v is True for v in took) >= len(took) // 2, took


@pytest.mark.fast
@pytest.mark.parametrize("wide", [True, False])
def test_a_window_across_the_seam_is_edited_by_tiles(tmp_path, wide):
    """A 7 × 5 window over the shared edge of 2 × 1 (or 1 × 2) roots of 32 samples:
    the tiles' path (``how="tiles"`` refuses otherwise), both roots' height, δ and r
    blobs rewritten, and the store a root-grid preprocess of the edited DEM gives."""
    from geoterrain.store.reader import StoreReader

    z, s = _filled_roots(11, 8, 2, wide, "none")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    store = _root_store(tmp_path / "a" / "dem.tif", z, 8)
    row, col = (10, s - 3) if wide else (s - 3, 10)
    h, w = (5, 7) if wide else (7, 5)
    # 60 m above the median: the roots' centres' δ and r codes move too (the vertex
    # levels up to each root's top are recomputed), not δ's code scale
    p = np.full((h, w), float(np.median(z)) + 60.0)
    roots = [(2, 0, 0), (2, 1, 0)] if wide else [(2, 0, 0), (2, 0, 1)]

    def blobs():
        r = StoreReader(store)
        try:
            return {(k, kind): r.get_blob(k, kind) for k in roots
                    for kind in ("heights", "delta", "radius")}
        finally:
            r.close()

    before = blobs()
    with geoterrain.open(store) as t:
        assert t.grid.roots == ((2, 1) if wide else (1, 2)) and t.grid.top_level == 2
        res = edit_terrain(t, Patch(row, col, p), "replace", how="tiles")
    assert res.how == "tiles" and res.changed > 0
    after = blobs()
    assert all(after[k] != before[k] for k in before), [k for k in before
                                                        if after[k] == before[k]]
    fresh = _root_store(tmp_path / "b" / "dem.tif", apply_by_hand(z, row, col, p, "replace"),
                        8)
    assert_same_store(store, fresh)


_KILLED_TILES = SLOW_COMMIT + textwrap.dedent("""
    import geoterrain.preprocessing.edit.local as local
    real_plan = local.local_plan
    def plan(*a):  # which path the edit took, for the test
        p, why = real_plan(*a)
        open(sys.argv[3], "w").write("tiles" if p is not None else why)
        return p, why
    local.local_plan = plan
    t = geoterrain.open(sys.argv[1])
    t.edit((3, 30), np.full((20, 9), float(sys.argv[4])))
""")



@pytest.mark.slow  # a child process: about 5 s
def test_killed_edit_by_tiles_leaves_the_old_root_grid_store(tmp_path):
    """SIGKILL at the commit of an edit by tiles (asserted) across the shared edge of
    2 × 1 filled roots: the next open rolls it back, byte for byte."""
    z, s = _filled_roots(7, 8, 2, True, "none")
    store = _root_store(tmp_path / "dem.tif", z, 8)
    before = store.read_bytes()
    ready, took = tmp_path / "ready", tmp_path / "took"
    with paused_at_commit(_KILLED_TILES, ready, str(store), str(ready), str(took),
                          str(float(np.median(z)) + 5.0)):
        assert took.read_text() == "tiles"
        assert store.read_bytes() != before
    with geoterrain.open(store) as t:
        assert t.meta.get("edits") is None
        assert t.tile(0, 4, 0).heights[5, 3] == z[5, 35]
    assert store.read_bytes() == before


@pytest.mark.fast
def test_padded_roots_go_to_the_whole_grid_and_say_why(tmp_path):
    """Roots their raster does not fill (40 × 120 on 2 × 1 roots of 64): like a padded
    square, the edit takes the whole grid (its static mesh's δ_edge is not computed by
    tiles) and says so; ``how="tiles"`` refuses in one line."""
    from geoterrain.exceptions import UsageError

    z = integer_dem(5, 40, 120)
    store = _root_store(tmp_path / "dem.tif", z, 16)
    with geoterrain.open(store) as t:
        with pytest.raises(UsageError, match="padded grid"):
            edit_terrain(t, Patch(30, 60, np.full((4, 4), 700.0)), "max", how="tiles")
        res = edit_terrain(t, Patch(30, 60, np.full((4, 4), 700.0)), "max")
    assert res.how == "whole grid" and "padded grid" in res.why


@pytest.mark.fast
@pytest.mark.parametrize("layout", ["square", "wide", "tall"])
def test_a_window_starting_on_the_last_row_or_column_is_edited(tmp_path, layout):
    """A window whose first row (or column) is the grid's last, on a store that the
    raster fills (a 33² square, 2 × 1 and 1 × 2 roots): the samples there are the last
    tiles' last row (column), read and changed (the edit once read none there and wrote
    nothing)."""
    if layout == "square":
        z = integer_dem(2, 33, 33)
    else:
        z, _ = _filled_roots(2, 8, 2, layout == "wide", "none")
    rows, cols = z.shape
    for k, (row, col, h, w) in enumerate([(rows - 1, 3, 1, 4), (5, cols - 1, 3, 1),
                                          (rows - 1, cols - 1, 1, 1)]):
        d = tmp_path / f"{k}"
        (d / "a").mkdir(parents=True)
        (d / "b").mkdir()
        store = geoterrain.preprocess(write_dem(d / "a" / "dem.tif", z, NODATA), tile_size=8,
                                      root_grid=layout != "square")
        p = np.full((h, w), 4.0)
        with geoterrain.open(store) as t:
            res = edit_terrain(t, Patch(row, col, p), "add")
        assert res.changed == h * w and res.window == (row, col, h, w)
        fresh = geoterrain.preprocess(
            write_dem(d / "b" / "dem.tif", apply_by_hand(z, row, col, p, "add"), NODATA),
            tile_size=8, root_grid=layout != "square")
        assert_same_store(store, fresh)


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


@pytest.mark.fast
def test_a_root_the_edit_does_not_reach_keeps_its_blob(tmp_path):
    """An edit of one root only, the other root's samples all valid: the other root is
    not coded again (its blob kept, local._Job._top_level), and the store is the one a
    preprocess of the edited DEM gives."""
    import geoterrain.preprocessing.edit.local as local

    z, s = _filled_roots(5, 8, 2, True, "none")  # 33 × 65 on 2 × 1 roots, top level 2
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    store = _root_store(tmp_path / "a" / "dem.tif", z, 8)
    p = np.full((3, 3), 9.0)
    coded = []
    real = local.encode_root

    def spy(*a, **k):
        coded.append(1)
        return real(*a, **k)

    local.encode_root = spy
    try:
        with geoterrain.open(store) as t:
            res = edit_terrain(t, Patch(0, s - 5, p), "add", how="tiles")
    finally:
        local.encode_root = real
    assert res.how == "tiles" and len(coded) == 1
    fresh = _root_store(tmp_path / "b" / "dem.tif", apply_by_hand(z, 0, s - 5, p, "add"), 8)
    assert_same_store(store, fresh)


@pytest.mark.fast
def test_a_root_whose_fill_reads_the_edit_is_coded_again(tmp_path):
    """The rule's other half: the corner the two roots share void, the right root's fill
    there extrapolates from the left root's top-level samples along the top row
    (codec.predict.fill_outward), so an edit of the left root only, at (0, s - 4), changes
    the right root's blob, and _top_level codes it again (a rule that kept every root the
    edit does not reach would keep the old blob)."""
    from geoterrain.codec.quantize import valid_codes
    from geoterrain.preprocessing.edit.canvas import Canvas
    from geoterrain.preprocessing.edit.local import _Job

    z, s = _filled_roots(5, 8, 2, True, "none")
    z[0, s] = np.nan
    store = _root_store(tmp_path / "dem.tif", z, 8)
    with geoterrain.open(store) as t:
        h = np.asarray(z[0:3, s - 5:s - 2], np.float64) + 9.0
        job = _Job(t, Canvas(t, 0, s - 5, h, np.ones(h.shape, bool)))
        zero = int(valid_codes(np.zeros((1, 1)), np.ones((1, 1), bool), t.quantizer)[0, 0])
        roots = job._top_level(zero)
        old = job.reader.get_blob((2, 1, 0), "heights")
    assert not roots[(1, 0)][1].all()
    assert roots[(1, 0)][2] is not None and roots[(1, 0)][2] != old

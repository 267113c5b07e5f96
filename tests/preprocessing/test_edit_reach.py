"""Which δ and r blobs an edit by tiles codes again (issue 52:
:func:`geoterrain.preprocessing.edit.localblobs.blob_reach`): every blob whose bytes the
edit changes is among them, on squares and root grids, windows on tile borders; and a
blob left out whose bytes change leaves a store that is not the whole grid's edit (the
oracle sees the skip).

Truth: the δ and r blobs that differ between the store and the same store edited over
the whole grid (:mod:`geoterrain.preprocessing.edit.whole`, itself tested against a
preprocess of the edited DEM).
"""

from __future__ import annotations

import shutil
import sqlite3
from contextlib import contextmanager
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.preprocessing.edit import Patch, edit_terrain, localblobs
from tests.preprocessing.editcheck import assert_same_store, integer_dem, random_patch, write_dem
from tests.preprocessing.test_root_edit import _filled_roots
from tests.store.storesql import all_blobs

BOUNDS = ("delta", "radius")


@contextmanager
def _reach(drop=None):
    """What each edit's :func:`blob_reach` returned (a list), ``drop`` (a tile key) left
    out of it."""
    seen: list = []
    real = localblobs.blob_reach

    def spy(*a, **k):
        out = real(*a, **k)
        seen.append(dict(out))
        if drop is not None:
            out.pop(drop, None)
        return out

    with mock.patch.object(localblobs, "blob_reach", spy):
        yield seen


def _blobs(path) -> dict:
    con = sqlite3.connect(path)
    try:
        return all_blobs(con)
    finally:
        con.close()


def _changed(before, after) -> set:
    """The (level, x, y, kind) of the δ and r blobs whose bytes differ."""
    a, b = _blobs(before), _blobs(after)
    return {k for k in set(a) | set(b) if k[3] in BOUNDS and a.get(k) != b.get(k)}


def _edited(tmp, z, tile, roots, row, col, p, mode, drop=None):
    """(store before, edited by tiles, edited over the whole grid, the reach, how)."""
    tmp.mkdir(exist_ok=True)
    old = geoterrain.preprocess(write_dem(tmp / "dem.tif", z), tile_size=tile,
                                root_grid=roots)
    a = shutil.copy(old, tmp / "a.geoterrain")
    b = shutil.copy(old, tmp / "b.geoterrain")
    with _reach(drop) as seen, geoterrain.open(a) as t:
        res = edit_terrain(t, Patch(row, col, p), mode)
    with geoterrain.open(b) as t:
        edit_terrain(t, Patch(row, col, p), mode, how="whole grid")
    return old, a, b, (seen[-1] if seen else {}), res.how


@st.composite
def reach_edits(draw):
    """A rough integer DEM on a square or on 2 × 1 / 1 × 2 filled roots, a window
    anywhere or with a corner on a tile border, any mode."""
    tile = draw(st.sampled_from([4, 8]))
    seed = draw(st.integers(0, 999))
    roots = draw(st.booleans())
    if roots:
        z, _ = _filled_roots(seed, tile, draw(st.integers(1, 2)), draw(st.booleans()), "none")
    else:
        size = draw(st.sampled_from([33, 65]))
        z = integer_dem(seed, size, size)
    rows, cols = z.shape
    h, w = draw(st.integers(1, 20)), draw(st.integers(1, 20))
    row, col = draw(st.integers(0, rows - 1)), draw(st.integers(0, cols - 1))
    if draw(st.booleans()):
        row, col = row - row % tile, col - col % tile
    mode = draw(st.sampled_from(["replace", "add", "min", "max"]))
    kind = draw(st.sampled_from(["const", "rough", "deep"]))
    if kind == "deep":  # far from the data: coarse vertices' codes change too
        p = np.full((h, w), {"add": -150.0, "min": 300.0, "max": 700.0}.get(mode, 350.0))
    else:
        p = random_patch(kind, h, w, seed, mode)
    return z, tile, roots, row, col, p, mode


@settings(max_examples=12, deadline=None)
@given(e=reach_edits())
def test_every_blob_an_edit_changes_is_reached(tmp_path_factory, e):
    """Each δ and r blob whose bytes the whole grid's edit changes is one the edit by
    tiles codes again (its tile and kind in the reach), and both leave the same store."""
    z, tile, roots, row, col, p, mode = e
    old, a, b, reach, how = _edited(tmp_path_factory.mktemp("reach"), z, tile, roots, row,
                                    col, p, mode)
    assert_same_store(a, b)
    if how != "tiles":  # a store-wide number moved: no reach to check
        return
    missed = sorted(k for k in _changed(old, b) if k[3] not in reach.get(k[:3], ((),))[0])
    assert missed == [], missed


@pytest.mark.fast
def test_a_skipped_blob_is_seen(tmp_path):
    """Mutation: the edit by tiles with one reached tile left out, a finer tile whose PRED
    δ reads a coarse vertex whose code changed (schema 14), leaves another store than the
    whole grid's edit; with it, the same store."""
    z = integer_dem(2, 65, 65)
    p = np.full((20, 20), -200.0)
    old, a, b, reach, how = _edited(tmp_path / "ok", z, 8, False, 20, 20, p, "add")
    assert how == "tiles"
    assert_same_store(a, b)
    changed = _changed(old, b)
    # tiles reached only through a coarser vertex (no row of their own), their δ changed
    finer = sorted(k for k, (kinds, row) in reach.items()
                   if not row and "delta" in kinds and (*k, "delta") in changed)
    assert finer, sorted(reach.items())
    _, a2, b2, _, how = _edited(tmp_path / "skip", z, 8, False, 20, 20, p, "add",
                                drop=finer[0])
    assert how == "tiles"
    with pytest.raises(AssertionError):
        assert_same_store(a2, b2)


@pytest.mark.fast
@pytest.mark.parametrize("tile", [4, 8, 16])
def test_the_window_s_outer_tiles(tmp_path, tile):
    """The edit's window reads the level-0 tiles beyond 8 samples of the edit on level
    1's lattice only (localbounds.Bounds._window; whole where tiles have under 8 samples
    a side): small windows in the middle, on a tile border and at the data's last column
    give the whole grid's store, on a square and on 1 × 2 roots (a failing case once:
    4-sample tiles, a 1 × 1 window on the last column, when the tiles beyond one tile of
    the edit were read so)."""
    size = {4: 17, 8: 65, 16: 257}[tile]  # the block table covers every level
    mid = size // 2 // tile * tile
    for n, (roots, row, col, h) in enumerate([(False, mid - 3, mid + 1, 1),
                                              (False, mid, mid, 3),
                                              (True, 0, 8 * tile // 4, 1),
                                              (True, 5 * tile // 4, 2 * tile, 2)]):
        if roots:
            z, _ = _filled_roots(1, tile, 1, False, "none")
            row, col = min(row, z.shape[0] - h), min(col, z.shape[1] - 1)
        else:
            z = integer_dem(n, size, size)
        p = np.full((h, h), -2.0)
        _, a, b, _, how = _edited(tmp_path / f"c{n}", z, tile, roots, row, col, p, "add")
        assert how == "tiles"
        assert_same_store(a, b)


def _reach_by_vertex(g, vi, vj, fd, fr, derived) -> dict:
    """:func:`blob_reach` without ``edited``, one vertex and one level at a time (the rules
    of its docstring, written out): the oracle of its whole-array form."""
    need: dict = {}
    top = g.top_level
    for i, j, d, r in zip(vi.tolist(), vj.tolist(), fd.tolist(), fr.tolist(), strict=True):
        m = i | j
        if not m:
            continue  # the grid's corner (0, 0): a root's corner, no vertex (δ 0)
        k = min((m & -m).bit_length() - 1, top)  # the level it is new at (the top's: top)
        for L in range(top + 1):
            span, (nx, ny) = g.tile_span(L), g.tiles(L)
            if k < L:
                continue  # not on the level's lattice
            new = k == L
            if L == 0 and derived and top > 0:  # RING: the border's new vertices
                ring = new and (i % span == 0 or j % span == 0)
                reads = (ring and d, ring and r)
            elif L > 0 and derived:  # MIDS: no cell centre
                reads = (d, new and not ((i >> L) & 1 and (j >> L) & 1) and r)
            else:
                reads = (d, r)
            flags = (*reads, new and (d or r))
            for ty in range(ny):
                for tx in range(nx):
                    if ty * span <= i <= ty * span + span and tx * span <= j <= tx * span + span:
                        for n, f in enumerate(flags):
                            if f:
                                need.setdefault((L, tx, ty), [False, False, False])[n] = True
    return {key: (tuple(kind for kind, f in zip(BOUNDS, v[:2], strict=True) if f), v[2])
            for key, v in need.items()}


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(shape=st.sampled_from([(33, 33, False), (17, 17, False), (33, 65, True),
                              (65, 33, True), (65, 129, True)]),
       seed=st.integers(0, 2**32 - 1), n=st.integers(0, 60), derived=st.booleans())
def test_blob_reach_is_each_vertex_s_tiles(shape, seed, n, derived):
    """Every level's tiles of every vertex at once (the whole-array form) name what one
    vertex and one level at a time name, on squares and root grids: vertices on tile
    borders and corners, at every level, the grid's corner (0, 0) among them (no vertex:
    it reaches nothing)."""
    from geoterrain.core.grid import Grid

    rows, cols, roots = shape
    g = Grid.for_shape(rows, cols, tile_size=8, roots=roots)  # roots the raster fills
    R, C = g.extent
    rng = np.random.default_rng(seed)
    vi = rng.integers(0, R, n)
    vj = rng.integers(0, C, n)
    snap = rng.random(n) < 0.5  # half on a coarse lattice (tile borders, corners)
    step = 1 << rng.integers(1, g.t + g.top_level + 1, n)
    vi[snap] = np.minimum(vi[snap] // step[snap] * step[snap], R - 1)
    vj[snap] = np.minimum(vj[snap] // step[snap] * step[snap], C - 1)
    fd, fr = rng.random(n) < 0.6, rng.random(n) < 0.6
    got = localblobs.blob_reach(g, vi, vj, fd, fr, derived)
    assert got == _reach_by_vertex(g, vi, vj, fd, fr, derived)

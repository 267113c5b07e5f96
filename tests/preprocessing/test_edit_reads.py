"""What an edit by tiles reads (issue 52, the root grid's next edits): the window's stored
codes from coarser tiles farther out, the canvas's rectangles cut from the window, the
coarse vertices an edit leaves as they are (their codes, and another root's, not read).

Each rule is checked against its invariant directly (every code the window's kernels
read is there and is the stored one; a cut rectangle is the assembled one) and, with the
rule broken on purpose, against the store a whole-grid edit leaves.
"""

from __future__ import annotations

import shutil
from unittest import mock

import numpy as np
import pytest

import geoterrain
from geoterrain.preprocessing.edit import Patch, edit_terrain, localbounds
from geoterrain.preprocessing.edit.canvas import Canvas
from geoterrain.preprocessing.edit.local import _Job
from tests.preprocessing.editcheck import assert_same_store, integer_dem, write_dem
from tests.preprocessing.test_root_edit import _filled_roots

_child = localbounds._child


def _job(t, row, col, h, w, dz):
    from geoterrain.preprocessing.edit import window_heights

    z, v = window_heights(t, row, col, row + h, col + w)
    return _Job(t, Canvas(t, row, col, np.where(v, z + dz, np.nan), v))


@pytest.fixture(scope="module")
def store64(tmp_path_factory):
    """A 513² integer store of 65-sample tiles (levels 0-3: the window reads levels 1-3)."""
    tmp = tmp_path_factory.mktemp("s64")
    return geoterrain.preprocess(write_dem(tmp / "dem.tif", integer_dem(4, 513, 513)),
                                 tile_size=64)


@pytest.mark.fast
@pytest.mark.parametrize("at", [(224, 230, 5, 7), (256, 256, 65, 65), (190, 300, 1, 1),
                                (200, 245, 5, 7), (262, 130, 3, 3)])
def test_the_window_holds_every_code_its_kernels_read(store64, at):
    """Every fine vertex's position and its children's (those _saturate_rect and
    nest_codes_rect read) is known in the window, with the stored code there (the
    level-0 tiles' decoded δ and r); the tiles far out were read from levels 2 and 3
    (so the rule is exercised). Windows 5 and 6 samples from a tile border: read whole
    only within 4 samples, a tile 5 away would miss the h = 2 edge midpoints' centres."""
    with geoterrain.open(store64) as t:
        b = localbounds.Bounds(_job(t, *at, -7.0))
        b._vertices()
        b._window()
        for i, j, h in b.fine.tolist():
            pts = [(i, j)]
            if ((i // h) % 2 == 1 and (j // h) % 2 == 1) or h > 1:
                pts += [_child(i, j, h, q) for q in range(4)]
            for a, c in pts:
                if 0 <= a < b.R and 0 <= c < b.C:
                    assert b.known[a - b.oi, c - b.oj], (i, j, h, a, c)
        S = b.S
        for ty in range(b.oi // S, b.i1 // S):
            for tx in range(b.oj // S, b.j1 // S):
                sl = np.s_[ty * S - b.oi:ty * S - b.oi + S + 1,
                           tx * S - b.oj:tx * S - b.oj + S + 1]
                k = b.known[sl]
                d = localbounds._codes(b.t8, t.tile_delta(0, tx, ty))
                r = localbounds._codes(b.rt, t.tile_radius(0, tx, ty))
                assert (b.dc_old[sl][k] == d[k]).all() and (b.rc_old[sl][k] == r[k]).all()
        # some tile on level 2's or 3's lattice only (a multiple of 4 apart, not of 2)
        thin = [(ty, tx) for ty in range(b.oi // S, b.i1 // S)
                for tx in range(b.oj // S, b.j1 // S)
                if not b.known[ty * S - b.oi + 2, tx * S - b.oj]]
        assert thin


@pytest.mark.fast
def test_a_rectangle_inside_the_window_is_the_assembled_one(store64):
    """Canvas.rect cuts a rectangle inside the largest one assembled (the window) from it:
    the same samples as assembled tile by tile, before and after the edit, which differ
    inside the edit (a cache keyed without ``new`` would mix them)."""
    with geoterrain.open(store64) as t:
        c = _job(t, 200, 210, 30, 40, 11.0).c
        big = c.rect(100, 120, 400, 380)
        old_big = c.rect(100, 120, 400, 380, new=False)
        assert (big[0] != old_big[0]).any()
        for new in (True, False):
            for box in [(190, 200, 260, 260), (100, 120, 400, 380), (150, 300, 151, 301)]:
                got = c.rect(*box, new=new)
                want = c._assemble(*box, new)
                assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))
            got = c.rect(0, 0, 120, 150, new=new)  # past it: assembled
            assert all(np.array_equal(g, w) for g, w in
                       zip(got, c._assemble(0, 0, 120, 150, new), strict=True))


def _edit_both(tmp, z, tile, roots, row, col, p, mode):
    tmp.mkdir(exist_ok=True)
    old = geoterrain.preprocess(write_dem(tmp / "dem.tif", z), tile_size=tile,
                                root_grid=roots)
    a = shutil.copy(old, tmp / "a.geoterrain")
    b = shutil.copy(old, tmp / "b.geoterrain")
    with geoterrain.open(a) as t:
        res = edit_terrain(t, Patch(row, col, p), mode, how="tiles")
    with geoterrain.open(b) as t:
        edit_terrain(t, Patch(row, col, p), mode, how="whole grid")
    return a, b, res.how


@pytest.mark.fast
def test_coarse_vertices_left_out_are_those_the_edit_keeps(tmp_path):
    """An edit of one root near the roots' shared edge whose change climbs, through a
    vertex on the shared edge (whose children lie in both roots), to a vertex of the
    other root: the edit by tiles leaves the whole grid's store. Broken on purpose, the
    rule that leaves out a coarse vertex none of whose children changed (the shared
    edge's changes not seen by their parents, as a rule that kept every vertex of a root
    the edit does not reach would) leaves another store."""
    z, s = _filled_roots(3, 8, 2, True, "none")  # 33 × 65 on 2 × 1 roots
    p = np.full((12, 12), -25.0)
    a, b, how = _edit_both(tmp_path / "ok", z, 8, True, 10, s - 14, p, "add")
    assert how == "tiles"
    assert_same_store(a, b)
    real = localbounds.Bounds._kid_changed

    def blind(self, i, j):
        return False if j == s else real(self, i, j)

    with mock.patch.object(localbounds.Bounds, "_kid_changed", blind):
        a2, b2, how = _edit_both(tmp_path / "broken", z, 8, True, 10, s - 14, p, "add")
    assert how == "tiles"
    with pytest.raises(AssertionError):
        assert_same_store(a2, b2)


@pytest.mark.fast
def test_a_second_edit_sees_the_first(tmp_path):
    """Two edits of one open store, the second over the first's window (its canvas, window
    and the terrain's decoded tiles made again from the first's result): the store a
    preprocess of the twice-edited DEM gives."""
    from tests.preprocessing.editcheck import apply_by_hand

    z = integer_dem(6, 65, 65)
    store = geoterrain.preprocess(write_dem(tmp_path / "dem.tif", z), tile_size=8)
    p1, p2 = np.full((9, 9), -30.0), np.full((6, 6), 12.0)
    with geoterrain.open(store) as t:
        assert t.edit((20, 22), p1, mode="add").how == "tiles"
        assert t.edit((24, 25), p2, mode="add").how == "tiles"
    z2 = apply_by_hand(apply_by_hand(z, 20, 22, p1, "add"), 24, 25, p2, "add")
    (tmp_path / "f").mkdir()
    fresh = geoterrain.preprocess(write_dem(tmp_path / "f" / "dem.tif", z2), tile_size=8)
    assert_same_store(store, fresh)

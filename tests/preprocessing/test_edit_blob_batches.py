"""An edit codes the δ and r blobs of several tiles in one call
(``localblobs._level_blobs_of``): the bytes and maxima of one call a tile."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.log8codes import log8_table
from geoterrain.bounds.tileblobs import BoundsCoding, OwnHeights, level_blobs
from geoterrain.preprocessing.edit.localblobs import _codes, _level_blobs_of

pytestmark = pytest.mark.fast


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), t=st.integers(2, 4), n=st.integers(1, 5),
       where=st.sampled_from(["top", "zero", "mid"]), derived=st.booleans(),
       kinds=st.sampled_from([("delta", "radius"), ("delta",), ("radius",), ()]),
       exact=st.booleans(), void=st.floats(0, 0.3))
def test_tiles_coded_together_are_coded_as_one_at_a_time(seed, t, n, where, derived, kinds,
                                                         exact, void):
    """Random codes (PRED and CENTRES shapes: a tile's off-centre new vertices all 0 half
    the time), random heights with voids, every level kind (the top, level 0 with rings,
    a level between with MIDS) and blob kinds, codes taken as they are or coded again."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    ed, er = int(rng.integers(-10, 5)), int(rng.integers(-4, 8))
    t8, rt = log8_table(ed).astype(np.float64), log8_table(er).astype(np.float64)
    top, zero = where == "top", where == "zero"
    ring, mids = derived and zero, derived and not zero
    if ring and top:
        return
    tiles = []
    for q in range(n):
        d = rng.integers(0, 256 if rng.random() < 0.5 else 40, (T, T)).astype(np.uint8)
        if rng.random() < 0.5:  # CENTRES: the new vertices off the cell centres 0
            keep = np.zeros((T, T), bool)
            keep[1::2, 1::2] = True
            keep[::2, ::2] = True
            d[~keep] = 0
        r = rng.integers(0, 256, (T, T)).astype(np.uint8)
        z = rng.normal(500, 50, (T, T))
        v = rng.random((T, T)) >= void
        tiles.append(((0, q, 0), True, d, r, OwnHeights(np.where(v, z, np.nan), v, 480.0)))
    got, dm, rm = _level_blobs_of(tiles, t, top, kinds, ring, mids, ed, er, exact, t8, rt, 3)
    for q, (_, _, d, r, own) in enumerate(tiles):
        coding = BoundsCoding.of_codes(d, ed, r, er) if exact else \
            BoundsCoding(t8[d], None, ed, r_codes=(_codes(rt, rt[r]), er))
        one, dm1, rm1 = level_blobs(coding, np.zeros((T, T, 2), np.uint8), t, 0,
                                    0 if top else 1, [(0, 0)], kinds, ring=ring, mids=mids,
                                    own=own, zlevel=3)
        for kind in kinds:
            assert got[kind][(0, 2 * q, 0)] == one[kind][(0, 0, 0)], (q, kind)
        assert dm[q] == dm1[0] and rm[q] == rm1[0]

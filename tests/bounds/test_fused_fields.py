"""δ's centre sweep making the tile bounds' level fields on the way
(delta.vertex_errors_fields, issue 51 item 5): δ bit for bit :func:`vertex_errors`'s, each
level's (bm, hl, vl) bit for bit tilebounds._level_blocks_nb's, and the tile table and
GeoMipMapping blocks of tile_and_block_errors the same with the fields as without."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import vertex_errors, vertex_errors_fields
from geoterrain.bounds.tilebounds import _level_blocks_nb, tile_and_block_errors

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint8)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 7), t=st.integers(1, 6), roots=st.sampled_from([None, (2, 1), (1, 2),
                                                                        (3, 2)]),
       seed=st.integers(0, 2**32 - 1), rough=st.booleans(), flat=st.booleans())
def test_fields_made_in_the_delta_sweep_are_the_fields_own(n, t, roots, seed, rough, flat):
    span = 1 << n
    ry, rx = (1, 1) if roots is None else roots
    R, C = ry * span + 1, rx * span + 1
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 1e3 if rough else 2, (R, C)).cumsum(axis=1).cumsum(axis=0)
    if flat:  # exact planes and ties: every error 0 or a rounding
        z = np.round(z) * 0 + np.add.outer(np.arange(R) * 0.1, np.arange(C) * 0.3)
    ok = np.ones((R, C), bool)
    sp = None if roots is None else span
    d, fields = vertex_errors_fields(z, ok, sp, t)
    assert np.array_equal(_bits(d), _bits(vertex_errors(z, ok, sp)))
    te = min(t, n)
    cpt = 1 << te
    want_levels = list(range(2, min(te, n - te) + 1))
    assert (fields is None) == (not want_levels)
    if fields is None:
        return
    assert sorted(fields) == want_levels
    nbr, nbc = (R - 1) // cpt, (C - 1) // cpt
    for L, (bm, hl, vl) in fields.items():
        wbm, whl = np.full((nbr, nbc), -1.0), np.full((nbr + 1, nbc), -1.0)
        wvl = np.full((nbr, nbc + 1), -1.0)
        mixed = np.zeros(((R - 1) >> L, (C - 1) >> L), bool)
        _level_blocks_nb(z, ok.view(np.uint8), 1 << L, cpt, True, wbm, whl, wvl, mixed)
        assert np.array_equal(_bits(bm), _bits(wbm)), L
        assert np.array_equal(_bits(hl), _bits(whl)), L
        assert np.array_equal(_bits(vl), _bits(wvl)), L
    ii, jj = np.indices((R, C)).astype(float)
    a, ab = tile_and_block_errors(z, ok, jj, -ii, t, sp)
    b, bb = tile_and_block_errors(z, ok, jj, -ii, t, sp, fields=fields)
    assert list(a) == list(b)
    assert np.array_equal(_bits(np.array([tuple(v) for v in a.values()])),
                          _bits(np.array([tuple(v) for v in b.values()])))
    assert np.array_equal(_bits(ab), _bits(bb))


def test_a_grid_with_a_void_keeps_the_fields_own_kernel():
    z = np.random.default_rng(3).normal(size=(65, 65))
    ok = np.ones(z.shape, bool)
    ok[10, 20] = False
    d, fields = vertex_errors_fields(z, ok, None, 3)
    assert fields is None
    assert np.array_equal(_bits(d), _bits(vertex_errors(z, ok)))

"""The tile table's level fields reduced where they are made, a band of blocks at a time
(tilebounds._level_blocks_nb), against the whole field E of _level_field_nb reduced
afterwards (closed blocks, tile border lines): the same maxima, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.tilebounds import _level_blocks_nb, _level_field_nb, closed_blocks

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@settings(max_examples=60, deadline=None)
@given(te=st.integers(1, 4), L=st.integers(1, 6), roots=st.sampled_from([(1, 1), (2, 1), (1, 2),
                                                                         (3, 2)]),
       p=st.sampled_from([1.0, 0.97, 0.7, 0.0]), seed=st.integers(0, 2**32 - 1),
       rough=st.booleans())
def test_banded_level_maxima_are_the_whole_field_s(te, L, roots, p, seed, rough):
    cpt = 1 << te
    s = 1 << L
    span = max(cpt, s) * 2  # cells larger than blocks too (s > cpt: a top level beyond t)
    rx, ry = roots
    R, C = ry * span + 1, rx * span + 1
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 1e3 if rough else 2, (R, C)).cumsum(axis=1) * rng.random()
    valid = rng.random((R, C)) < p
    if p == 1.0 and rng.random() < 0.5:  # a void block
        i, j = rng.integers(0, R - 1), rng.integers(0, C - 1)
        valid[i:i + 3 * s // 2, j:j + s] = False
    z = np.where(valid, z, 0.0)
    vb = valid.view(np.uint8)
    all_valid = bool(valid.all())
    E = np.zeros((R, C))
    want_mixed = _level_field_nb(z, vb, s, E, all_valid)
    nbr, nbc = (R - 1) // cpt, (C - 1) // cpt
    bm, hl = np.full((nbr, nbc), -1.0), np.full((nbr + 1, nbc), -1.0)
    vl, mixed = np.full((nbr, nbc + 1), -1.0), np.zeros(want_mixed.shape, bool)
    _level_blocks_nb(z, vb, s, cpt, all_valid, bm, hl, vl, mixed)
    assert np.array_equal(mixed, want_mixed)
    assert np.array_equal(bm, closed_blocks(E, cpt, np.maximum))
    want_hl = np.maximum(np.maximum.reduce(E[::cpt, :-1].reshape(nbr + 1, nbc, cpt), axis=2),
                         E[::cpt, cpt::cpt])
    want_vl = np.maximum(np.maximum.reduce(E[:-1, ::cpt].reshape(nbr, cpt, nbc + 1), axis=1),
                         E[cpt::cpt, ::cpt])
    assert np.array_equal(hl, want_hl)
    assert np.array_equal(vl, want_vl)

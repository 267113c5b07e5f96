"""The codec's prediction U(.) (geoterrain.predict): its three forms give the same integers."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.predict import _pred, cubic_child, fill_level, linear_child, predict


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(2, 20), te=st.integers(2, 4),
       cubic=st.booleans(), scale=st.sampled_from([1, 1000, 2**40]))
def test_the_whole_grid_prediction_is_the_compiled_one(seed, m, te, cubic, scale):
    """predict (numpy, the predictor choice) and _pred (compiled: the fill and the
    encoder's residuals) agree at every new sample of a level."""
    f = np.random.default_rng(seed).integers(-scale, scale, (2 * m - 1, 2 * m - 1))
    period = (1 << te) if cubic else None
    pa, pb, pc = predict(f, period)
    P = period or 0
    for i in range(2 * m - 1):
        for j in range(2 * m - 1):
            if i & 1 or j & 1:
                want = (pa if i % 2 == 0 else pb if j % 2 == 0 else pc)[i // 2, j // 2]
                assert _pred(f, 1, i, j, P) == want, (i, j)


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), te=st.integers(2, 5), cubic=st.booleans(),
       py=st.integers(0, 1), px=st.integers(0, 1))
def test_a_child_tile_decodes_by_its_levels_fill_rule(seed, te, cubic, py, px):
    """With zero residuals the decoder's child tile (cubic_child / linear_child) is the
    encoder's fill of its level (fill_level): the same predictions, cell centres from the
    row midpoints of the same tile, cubic only where the tile holds all four."""
    h = 1 << (te - 1)
    t = 2 * h + 1
    # a level of 2 × 2 child tiles under one parent tile, every new sample filled
    d = np.zeros((2 * t - 1, 2 * t - 1), np.int64)
    d[::2, ::2] = np.random.default_rng(seed).integers(-5000, 5000, (t, t))
    coarse = np.zeros(d.shape, bool)
    coarse[::2, ::2] = True
    fill_level(d, coarse, 1, (1 << te) if cubic else 0)
    parent = np.ascontiguousarray(d[::2, ::2])
    zero = np.zeros(3 * h * h + 2 * h, np.int64)
    out = np.empty((t, t), np.int64)
    if cubic:
        cubic_child(parent, py * h, px * h, h, zero, out)
    else:
        linear_child(np.ascontiguousarray(parent[py * h:py * h + h + 1,
                                                 px * h:px * h + h + 1]), h, zero, out)
    np.testing.assert_array_equal(out, d[py * 2 * h:py * 2 * h + t, px * 2 * h:px * 2 * h + t])

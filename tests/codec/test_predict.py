"""The codec's prediction U(.) (geoterrain.codec.predict): its three forms give the same
integers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.codec.predict import (
    _pred,
    cubic_child,
    fill_level,
    fill_outward,
    linear_child,
    predict,
)

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


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


def _fill_reference(f, known):
    """fill_outward's rule, written out independently: rings by repeated dilation of the
    known set (not a queue); a first-ring sample takes the mean of the extrapolations
    2a - b along rows and columns where a and b are known, else of its known
    neighbours; a farther one the mean of its neighbours filled one ring earlier."""
    f = f.copy()
    done = known.copy()
    n0, n1 = f.shape
    ring = 0
    while not done.all() and done.any():
        ring += 1
        new = {}
        for i, j in zip(*np.nonzero(~done), strict=True):
            near, ext = [], []
            for di, dj in ((-1, 0), (0, -1), (0, 1), (1, 0)):
                a, b = (i + di, j + dj), (i + 2 * di, j + 2 * dj)
                if 0 <= a[0] < n0 and 0 <= a[1] < n1 and done[a]:
                    near.append(int(f[a]))
                    if ring == 1 and 0 <= b[0] < n0 and 0 <= b[1] < n1 and known[b]:
                        ext.append(2 * int(f[a]) - int(f[b]))
            if near:
                vals = ext or near
                new[i, j] = sum(vals) // len(vals)
        for key, value in new.items():
            f[key] = value
            done[key] = True
    return f


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n0=st.integers(1, 12), n1=st.integers(1, 12),
       p=st.sampled_from([0.0, 0.05, 0.3, 0.7, 1.0]), scale=st.sampled_from([1, 1000, 2**40]))
def test_the_outward_fill_is_its_rule(seed, n0, n1, p, scale):
    """fill_outward against the rule written out independently; the known samples keep
    their codes; past the first ring the fill stays within the range of the known
    samples and the first ring; and it commutes with transposing and flipping the grid
    (the order inside a ring does not matter)."""
    rng = np.random.default_rng(seed)
    f = rng.integers(-scale, scale, (n0, n1))
    known = rng.random((n0, n1)) < p
    got = f.copy()
    fill_outward(got, known)
    assert np.array_equal(got, _fill_reference(f, known))
    assert np.array_equal(got[known], f[known])
    if known.any() and not known.all():
        dist = np.full(f.shape, -1)
        dist[known] = 0
        r = 0
        while (dist < 0).any():  # rings by dilation, for the range check
            r += 1
            grown = np.zeros(f.shape, bool)
            grown[1:] |= dist[:-1] == r - 1
            grown[:-1] |= dist[1:] == r - 1
            grown[:, 1:] |= dist[:, :-1] == r - 1
            grown[:, :-1] |= dist[:, 1:] == r - 1
            dist[grown & (dist < 0)] = r
        near = got[dist <= 1]
        assert got.min() >= near.min() and got.max() <= near.max()
    for op in (np.transpose, np.flipud, np.fliplr):
        g2 = np.ascontiguousarray(op(f))
        fill_outward(g2, np.ascontiguousarray(op(known)))
        assert np.array_equal(g2, op(got))


def test_the_outward_fill_continues_a_plane():
    """Next to the known samples a plane continues exactly (the linear extrapolations),
    so a padded smooth DEM's first fill is its own surface; farther out it is flat."""
    i, j = np.mgrid[0:9, 0:9]
    plane = 7 * i - 3 * j + 100
    known = (i < 6) & (j < 5)
    f = np.where(known, plane, 0)
    fill_outward(f, known)
    ring1 = ((i == 6) & (j < 5)) | ((j == 5) & (i < 6))
    assert np.array_equal(f[ring1], plane[ring1])
    assert f[8, 0] == f[7, 0] == plane[6, 0]  # flat past the first ring, down the column

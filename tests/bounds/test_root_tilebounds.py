"""Tile bounds and GeoMipMapping blocks on a root grid's extent (issue 45), checked
against the square that holds it: the extent padded with invalid samples to a (2^m + 1)²
square has the same level-L cells, triangles and footprints, so every tile the roots
hold has the square's bounds, and every block its δ_n."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.tilebounds import tile_and_block_errors

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

@settings(max_examples=25, deadline=None)
@given(st.sampled_from([(2, 1), (1, 2), (2, 2)]), st.integers(1, 2), st.integers(1, 2),
       st.sampled_from([1.0, 0.95, 0.6]), st.integers(0, 2**32 - 1))
def test_root_grid_tile_bounds_are_the_square_s_that_holds_it(roots, te, lmax, p, seed):
    rx, ry = roots
    span = 1 << (te + lmax)
    R, C = ry * span + 1, rx * span + 1
    rng = np.random.default_rng(seed)
    N = max(R, C) if rx != ry else 2 * span + 1
    z = np.zeros((N, N))
    z[:R, :C] = np.cumsum(rng.normal(0, 2, (R, C)), axis=1)
    valid = np.zeros((N, N), bool)
    valid[:R, :C] = rng.random((R, C)) < p
    valid[:R, :C][rng.integers(2, R + 1):] = False  # a lattice short of the extent
    ii, jj = np.indices((N, N)).astype(float)
    got, blocks = tile_and_block_errors(z[:R, :C], valid[:R, :C], jj[:R, :C], -ii[:R, :C], te,
                                        span)
    want, wblocks = tile_and_block_errors(z, valid, jj, -ii, te)
    inside = {k: v for k, v in want.items()
              if k[0] <= lmax and k[1] * (span >> lmax << k[0]) < C - 1
              and k[2] * (span >> lmax << k[0]) < R - 1}
    assert got == inside
    assert {k[0] for k in got} <= set(range(lmax + 1))
    nbr, nbc = (R - 1) >> te, (C - 1) >> te
    assert blocks.shape == (nbr, nbc, min(te, lmax) + 1)
    np.testing.assert_array_equal(blocks, wblocks[:nbr, :nbc, :blocks.shape[2]])


def test_a_rectangle_is_refused_without_its_roots():
    with pytest.raises(ValueError, match=r"same \(N, N\) shape"):
        tile_and_block_errors(np.zeros((5, 9)), np.ones((5, 9), bool), np.zeros((5, 9)),
                              np.zeros((5, 9)), 1)

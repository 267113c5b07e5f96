import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.core.grid import Grid

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@given(st.integers(2, 3000), st.integers(2, 3000), st.sampled_from([2, 4, 16, 64]))
def test_padding_is_smallest_power_of_two_plus_one(h, w, ts):
    g = Grid.for_shape(h, w, ts)
    assert g.size >= max(h, w)
    assert g.n == 1 or (1 << (g.n - 1)) + 1 < max(h, w)
    assert g.tile_samples <= g.size
    assert g.tiles_per_side(g.top_level) == 1
    # the level-0 tiles exactly tile the padded domain with shared borders
    assert g.tiles_per_side(0) * (g.tile_samples - 1) + 1 == g.size


def test_tile_rows_are_vertex_aligned():
    g = Grid.for_shape(1025, 1025, 64)
    assert g.tile_rows(0, 1)[0] == 64 and g.tile_rows(0, 1)[-1] == 128
    assert g.tile_rows(2, 1)[0] == 256 and (np.diff(g.tile_rows(2, 1)) == 4).all()
    assert g.ancestors(0, 13, 7) == [(1, 6, 3), (2, 3, 1), (3, 1, 0), (4, 0, 0)]


def test_footprint_counts_match_brute_force():
    rng = np.random.default_rng(0)
    g = Grid.for_shape(40, 33, 8)
    valid = g.pad(rng.random((40, 33)) > 0.7, False)
    counts = g.footprint_counts(valid)
    for L in g.levels:
        s = g.tile_span(L)
        for y in range(g.tiles_per_side(L)):
            for x in range(g.tiles_per_side(L)):
                assert counts[L][y, x] == valid[y * s:(y + 1) * s + 1, x * s:(x + 1) * s + 1].sum()
    stored = list(g.stored_tiles(valid))
    assert stored[0] == (g.top_level, 0, 0)
    keys = set(stored)
    for L, x, y in stored:  # ancestors of stored tiles are stored
        assert all(a in keys for a in g.ancestors(L, x, y))

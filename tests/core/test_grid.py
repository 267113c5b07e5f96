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


@given(st.integers(2, 5000), st.integers(2, 5000), st.sampled_from([2, 4, 16, 64]))
def test_root_grid_pads_level_0_to_the_next_tile_multiple_only(h, w, ts):
    g = Grid.for_shape(h, w, ts, roots=True)
    step = 1 << g.t
    tx, ty = g.tiles(0)
    assert g.shape == (ty * step + 1, tx * step + 1)
    # covers the raster, and one tile fewer would not: less than one tile row/column over
    assert g.shape[0] >= h and g.shape[1] >= w
    assert g.shape[0] - step < h or ty == 1
    assert g.shape[1] - step < w or tx == 1
    for L in g.levels[1:]:  # each level halves the one below, rounding up
        assert g.tiles(L) == tuple(-(-k // 2) for k in g.tiles(L - 1))
    rx, ry = g.roots
    assert rx * ry <= 2 and (g.top_level == 0 or np.prod(g.tiles(g.top_level - 1)) > 2)
    for L in g.levels:  # every level's lattice lies inside the roots' extent
        assert all(k * g.tile_span(L) + 1 <= e
                   for k, e in zip(g.tiles(L)[::-1], g.extent, strict=True))
    assert g.offsets()[-1] == sum(np.prod(g.tiles(L)) for L in g.levels)
    sq = Grid.for_shape(h, w, ts)
    assert g.t == sq.t
    if g.square:  # the same tiles as the square grid: the square grid itself
        assert g == sq and g.to_json() == sq.to_json() == {"rows": h, "cols": w, "n": g.n,
                                                           "t": g.t}
    else:
        assert Grid(**g.to_json()) == g
        with pytest.raises(ValueError, match="needs a square grid"):
            g.tiles_per_side(0)


@given(st.integers(2, 200), st.integers(2, 200), st.sampled_from([4, 8, 16]),
       st.integers(0, 99))
def test_root_grid_footprints_parents_and_children(h, w, ts, seed):
    g = Grid.for_shape(h, w, ts, roots=True)
    rng = np.random.default_rng(seed)
    valid = g.pad(rng.random((h, w)) > 0.9, False)
    assert valid.shape == g.shape
    counts = g.footprint_counts(valid)
    for L in g.levels:
        s = g.tile_span(L)
        assert counts[L].shape == g.tiles(L)[::-1]
        ys, xs = np.indices(counts[L].shape)
        brute = [valid[y * s:(y + 1) * s + 1, x * s:(x + 1) * s + 1].sum()
                 for y, x in zip(ys.ravel(), xs.ravel(), strict=True)]
        assert counts[L].ravel().tolist() == brute
    keys = set(g.stored_tiles(valid))
    for L, x, y in keys:
        assert all(a in keys for a in g.ancestors(L, x, y))
        if L < g.top_level:
            assert (L, x, y) in g.children(*g.parent(L, x, y))
    for L in g.levels[1:]:  # the children of a level's tiles are the level below, once each
        tx, ty = g.tiles(L)
        kids = [c for y in range(ty) for x in range(tx) for c in g.children(L, x, y)]
        assert sorted(kids) == sorted((L - 1, x, y) for y in range(g.tiles(L - 1)[1])
                                      for x in range(g.tiles(L - 1)[0]))


def test_root_grid_of_the_issue_shapes():
    conus = Grid.for_shape(520, 1180, 64, roots=True)
    assert conus.shape == (577, 1217) and conus.roots == (2, 1)
    assert np.prod(conus.shape) <= 1.15 * 520 * 1180
    wide = Grid.for_shape(1024, 4096, 64, roots=True)
    assert wide.shape == (1025, 4097) and wide.roots == (2, 1) and wide.top_level == 5
    square = Grid.for_shape(1025, 1025, 64, roots=True)
    assert square == Grid.for_shape(1025, 1025, 64) and square.roots == (1, 1)


@given(st.integers(2, 120), st.integers(2, 120), st.sampled_from([2, 4, 8, 16]),
       st.booleans(), st.integers(-1, 10**6))
def test_footprint_counts_of_a_full_mask_are_the_boxes_areas(h, w, ts, roots, hole):
    """An all-valid mask's counts are its footprints' areas, computed without the
    integral image: the same as brute force, and as the integral image's with one sample
    invalid wherever the hole falls (-1: none)."""
    from geoterrain.core.grid import footprint_counts

    g = Grid.for_shape(h, w, ts, roots=roots)
    valid = np.ones(g.shape, bool)
    if hole >= 0:
        valid.flat[hole % valid.size] = False
    counts = footprint_counts(valid, g.t, g.top_level)
    for L in g.levels:
        s = g.tile_span(L)
        ys, xs = np.indices(counts[L].shape)
        brute = [valid[y * s:(y + 1) * s + 1, x * s:(x + 1) * s + 1].sum()
                 for y, x in zip(ys.ravel(), xs.ravel(), strict=True)]
        assert counts[L].dtype == np.int64 and counts[L].ravel().tolist() == brute


@given(st.integers(2, 5000), st.integers(2, 5000), st.sampled_from([2, 4, 16, 64]),
       st.booleans())
def test_tiles_a_level_are_the_spans_over_the_samples(h, w, ts, roots):
    """``tiles(L)`` (kept once a level) is, at every level and asked twice, the tiles of
    2^(t+L) samples that cover the padded level-0 grid: a square's 2^(top−L) a side, a
    root grid's ceil((cols − 1) / span) × ceil((rows − 1) / span)."""
    g = Grid.for_shape(h, w, ts, roots=roots)
    for _ in range(2):
        for L in g.levels:
            span = 1 << (g.t + L)
            if g.square:
                want = (g.size - 1) // span
                assert g.tiles(L) == (want, want)
            else:
                assert g.tiles(L) == (max(1, -(-(w - 1) // span)), max(1, -(-(h - 1) // span)))
    assert g == Grid(g.rows, g.cols, g.n, g.t, g.layout) and hash(g) == hash(
        Grid(g.rows, g.cols, g.n, g.t, g.layout))

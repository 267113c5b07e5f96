"""The edit's canvas (preprocessing/edit/canvas.py): a tile's lattice by slices is the
lattice by index arrays, on a square store and a root grid, with voids, for windows
anywhere (over a tile's border, its far corner, past it)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.preprocessing.edit.canvas import Canvas
from tests.preprocessing.editcheck import integer_dem, write_dem


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    out = []
    for k, (rows, cols, roots) in enumerate([(33, 33, False), (17, 33, True)]):
        d = tmp_path_factory.mktemp(f"canvas{k}")
        z = integer_dem(3 + k, rows, cols, 0.02)
        out.append(geoterrain.preprocess(write_dem(d / "dem.tif", z, -9999.0), tile_size=4,
                                         root_grid=roots))
    return out


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(which=st.integers(0, 1), level=st.integers(0, 3), r=st.integers(-6, 36),
       c=st.integers(-6, 36), h=st.integers(1, 12), w=st.integers(1, 12),
       seed=st.integers(0, 99), pick=st.integers(0, 10 ** 6))
def test_tile_lattice_is_the_lattice_of_the_tile_s_samples(stores, which, level, r, c, h, w,
                                                           seed, pick):
    with geoterrain.open(stores[which]) as t:
        g = t.grid
        level = min(level, g.top_level)
        rng = np.random.default_rng(seed)
        heights = rng.normal(500, 20, (h, w)).round()
        valid = rng.random((h, w)) > 0.2
        canvas = Canvas(t, r, c, np.where(valid, heights, np.nan), valid)
        nx, ny = g.tiles(level)
        x, y = pick % nx, (pick // nx) % ny
        span, step, T = g.tile_span(level), 1 << level, g.tile_samples
        rows = y * span + np.arange(T) * step
        cols = x * span + np.arange(T) * step
        want = canvas.lattice(level, rows, cols)
        got = canvas.tile_lattice(level, x, y)
    assert np.array_equal(got[0], want[0], equal_nan=True)
    assert np.array_equal(got[1], want[1])


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(tuples=st.lists(st.tuples(*[st.integers(0, 40)] * 4), max_size=80),
       arrays=st.lists(st.lists(st.tuples(*[st.integers(0, 40)] * 4), max_size=40), max_size=3))
def test_dirty_rectangles_merged_are_the_sorted_distinct_ones(tuples, arrays):
    """The edit log's dirty rectangles (edit._merged): the distinct ones in tuple order,
    from 4-tuples and (n, 4) arrays alike, or their bounding box past MAX_DIRTY."""
    from geoterrain.preprocessing.edit import MAX_DIRTY, _merged

    rects = list(tuples) + [np.array(a, np.int64).reshape(-1, 4) for a in arrays]
    flat = sorted(set(tuples) | {tuple(r) for a in arrays for r in a})
    want = ([list(r) for r in flat] if len(flat) <= MAX_DIRTY else
            [[min(r[0] for r in flat), min(r[1] for r in flat), max(r[2] for r in flat),
              max(r[3] for r in flat)]])
    got = _merged(rects)
    assert got == want
    assert all(type(v) is int for r in got for v in r)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(which=st.integers(0, 1), level=st.integers(0, 3), r=st.integers(-6, 36),
       c=st.integers(-6, 36), h=st.integers(1, 12), w=st.integers(1, 12),
       lo=st.tuples(st.integers(0, 32), st.integers(0, 32)),
       n=st.tuples(st.integers(1, 20), st.integers(1, 20)), seed=st.integers(0, 99))
def test_lattice_by_slices_is_the_lattice_by_index_arrays(stores, which, level, r, c, h, w,
                                                          lo, n, seed):
    """Rows and columns a step apart take slices (Canvas.lattice); with one more row a
    gap further on (index arrays) the rows they share hold the same heights."""
    with geoterrain.open(stores[which]) as t:
        g = t.grid
        level = min(level, g.top_level)
        step = 1 << level
        R, C = g.extent
        rows = np.arange(lo[0] // step * step, R, step)[:n[0]]
        cols = np.arange(lo[1] // step * step, C, step)[:n[1]]
        if not rows.size or not cols.size:
            return
        rng = np.random.default_rng(seed)
        heights = rng.normal(500, 20, (h, w)).round()
        valid = rng.random((h, w)) > 0.2
        canvas = Canvas(t, r, c, np.where(valid, heights, np.nan), valid)
        got = canvas.lattice(level, rows, cols)
        want = canvas.lattice(level, np.append(rows, rows[-1] + 2 * step),
                              np.append(cols, cols[-1] + 2 * step))
    assert np.array_equal(got[0], want[0][:-1, :-1], equal_nan=True)
    assert np.array_equal(got[1], want[1][:-1, :-1])

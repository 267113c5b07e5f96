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

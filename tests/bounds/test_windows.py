"""The window kernels (geoterrain/bounds/windows.py) give the whole-grid kernels' values
bit for bit: δ's raw values and block sweeps, the radii's nested codes, the tile errors'
field, on random grids with voids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import Cell, _block_sweep, _raw_delta, check_grid
from geoterrain.bounds.radii import _proxy_positions
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import _level_field_nb
from geoterrain.bounds.vertexdata import log8_table
from geoterrain.bounds.windows import (
    block_sweep_rect,
    fine_raw_delta,
    level_field_rect,
    nest_codes_rect,
)


def _grid(seed: int, n: int, holes: float):
    rng = np.random.default_rng(seed)
    N = (1 << n) + 1
    z = rng.normal(0, 10 ** rng.uniform(-1, 3), (N, N)).cumsum(0).cumsum(1) / N
    z += rng.uniform(-1e4, 1e4)
    v = rng.random((N, N)) >= holes
    return z, v


def _vertices(N: int) -> np.ndarray:
    out = []
    h = 1
    while h < N - 1:
        s = 2 * h
        nb = (N - 1) // s
        for a in range(nb):
            for b in range(nb + 1):
                out.append((h + a * s, b * s, h))
        for a in range(nb + 1):
            for b in range(nb):
                out.append((a * s, h + b * s, h))
        for a in range(nb):
            for b in range(nb):
                out.append((h + a * s, h + b * s, h))
        h *= 2
    return np.array(out, np.int64)


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 6),
       holes=st.sampled_from([0.0, 0.0, 0.05, 0.5]))
def test_fine_raw_delta_is_the_whole_grids(seed, n, holes):
    z, v = _grid(seed, n, holes)
    zf, vv, _ = check_grid(z, v)
    raw = _raw_delta(zf, vv)
    verts = _vertices(z.shape[0])
    out = np.zeros(len(verts), np.float32)
    fine_raw_delta(zf, vv.view(np.uint8), 0, 0, z.shape[0], verts, out)
    assert np.array_equal(out, raw[verts[:, 0], verts[:, 1]])


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(1, 7), main=st.booleans(),
       cuts=st.integers(1, 5))
def test_a_block_swept_by_rectangles_is_swept_whole(seed, k, main, cuts):
    rng = np.random.default_rng(seed)
    s = 1 << k
    z = rng.normal(0, 10 ** rng.uniform(-2, 4), (s + 1, s + 1)).cumsum(0)
    z += rng.uniform(-1e4, 1e4)
    whole = np.array(_block_sweep(z, 0, 0, s, main))
    cell = Cell(0, 0, s, main, z[0, 0], z[0, s], z[s, 0], z[s, s])
    zc = z[s // 2, s // 2]
    rows = sorted({0, s + 1, *rng.integers(1, s + 1, cuts).tolist()})
    cols = sorted({0, s + 1, *rng.integers(1, s + 1, cuts).tolist()})
    best = np.zeros(5)
    for a0, a1 in zip(rows[:-1], rows[1:], strict=True):
        for c0, c1 in zip(cols[:-1], cols[1:], strict=True):
            part = np.ascontiguousarray(z[a0:a1, c0:c1])
            best = np.maximum(best, block_sweep_rect(part, a0, c0, cell, zc, a0, a1 - 1, c0,
                                                     c1 - 1))
    assert np.array_equal(best, whole)


@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 6),
       holes=st.sampled_from([0.0, 0.05, 0.5]))
def test_nested_radius_codes_are_the_whole_grids(seed, n, holes):
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    ii, jj = np.indices((N, N)).astype(np.float64)
    X, Y = 10.0 * jj, -10.0 * ii
    codes, e = radius_codes(X, Y, np.where(v, z, np.nan), v)
    xp, yp, zp = _proxy_positions(X, Y, np.where(v, z, np.nan), v)
    mine = np.zeros((N, N), np.uint8)
    verts = _vertices(N)
    leaf = (verts[:, 2] == 1) & ~(((verts[:, 0] % 2) == 1) & ((verts[:, 1] % 2) == 1))
    nest_codes_rect(np.ascontiguousarray(xp), np.ascontiguousarray(yp), zp, mine,
                    log8_table(e).astype(np.float64), verts[~leaf], 0, 0, N)
    assert np.array_equal(mine, codes)


@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 6), L=st.integers(1, 3),
       holes=st.sampled_from([0.0, 0.05, 0.5]), corner=st.tuples(st.integers(0, 3),
                                                                   st.integers(0, 3)))
def test_level_field_on_a_window_is_the_whole_grids(seed, n, L, holes, corner):
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    s = 1 << min(L, n)
    zf, vv, _ = check_grid(z, v)
    E = np.zeros((N, N))
    mixed = _level_field_nb(zf, vv.view(np.uint8), s, E)
    nb = (N - 1) // s
    a0, b0 = (corner[0] * nb // 4) * s, (corner[1] * nb // 4) * s
    a1, b1 = min(a0 + 3 * s, N - 1), min(b0 + 2 * s, N - 1)
    Ew = np.zeros((a1 - a0 + 1, b1 - b0 + 1))
    mw = np.zeros(((a1 - a0) // s, (b1 - b0) // s), np.bool_)
    level_field_rect(np.ascontiguousarray(zf[a0:a1 + 1, b0:b1 + 1]),
                     np.ascontiguousarray(vv[a0:a1 + 1, b0:b1 + 1]).view(np.uint8), a0, b0, s,
                     Ew, mw)
    assert np.array_equal(mw, mixed[a0 // s:a1 // s, b0 // s:b1 // s])
    # inside the window (its border samples also see cells outside it) the field is equal
    assert np.array_equal(Ew[s:-s, s:-s], E[a0 + s:a1 - s + 1, b0 + s:b1 - s + 1])

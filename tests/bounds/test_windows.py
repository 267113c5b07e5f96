"""The window kernels (geoterrain/bounds/windows.py) give the whole-grid kernels' values
bit for bit: δ's raw values and block sweeps, the radii's nested codes, the tile errors'
field, on random grids with voids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import Cell, _block_sweep, _raw_delta, check_grid
from geoterrain.bounds.log8codes import log8_table
from geoterrain.bounds.radii import _proxy_positions
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import _level_field_nb, cell_counts_nb
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


def _vertices(N: int, C: int | None = None, span: int | None = None) -> np.ndarray:
    """Every vertex (i, j, h) of the N × N square, or of an N × C root grid's extent
    (roots of side ``span``: half-spans below it), fine to coarse."""
    C = N if C is None else C
    span = N - 1 if span is None else span
    out = []
    h = 1
    while h < span:
        s = 2 * h
        nr, nc = (N - 1) // s, (C - 1) // s
        for a in range(nr):
            for b in range(nc + 1):
                out.append((h + a * s, b * s, h))
        for a in range(nr + 1):
            for b in range(nc):
                out.append((a * s, h + b * s, h))
        for a in range(nr):
            for b in range(nc):
                out.append((h + a * s, h + b * s, h))
        h *= 2
    return np.array(out, np.int64)


def _root_grid(seed: int, n: int, holes: float, wide: bool):
    # 2 × 1 (wide) or 1 × 2 roots of side 2**n: the extent (2**n + 1, 2**(n+1) + 1) or
    # its transpose
    rng = np.random.default_rng(seed)
    R, C = (1 << n) + 1, (1 << (n + 1)) + 1
    if not wide:
        R, C = C, R
    z = rng.normal(0, 10 ** rng.uniform(-1, 3), (R, C)).cumsum(0).cumsum(1) / R
    z += rng.uniform(-1e4, 1e4)
    v = rng.random((R, C)) >= holes
    return z, v


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
    fine_raw_delta(zf, vv.view(np.uint8), 0, 0, z.shape[0], z.shape[1], verts, out)
    assert np.array_equal(out, raw[verts[:, 0], verts[:, 1]])


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 5), wide=st.booleans(),
       holes=st.sampled_from([0.0, 0.0, 0.05, 0.5]))
def test_fine_raw_delta_is_the_root_grids(seed, n, wide, holes):
    """On 2 × 1 and 1 × 2 roots (the extent R × C, half-spans below a root's side): the
    edge midpoints on the extent's last row and column and on the roots' shared edge."""
    z, v = _root_grid(seed, n, holes, wide)
    span = 1 << n
    zf, vv, _ = check_grid(z, v, span)
    raw = _raw_delta(zf, vv, span)
    verts = _vertices(z.shape[0], z.shape[1], span)
    out = np.zeros(len(verts), np.float32)
    fine_raw_delta(zf, vv.view(np.uint8), 0, 0, z.shape[0], z.shape[1], verts, out)
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
                    log8_table(e).astype(np.float64), verts[~leaf], 0, 0, N, N)
    assert np.array_equal(mine, codes)


@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 5), wide=st.booleans(),
       holes=st.sampled_from([0.0, 0.05, 0.5]))
def test_nested_radius_codes_are_the_root_grids(seed, n, wide, holes):
    z, v = _root_grid(seed, n, holes, wide)
    R, C = z.shape
    span = 1 << n
    ii, jj = np.indices((R, C)).astype(np.float64)
    X, Y = 10.0 * jj, -10.0 * ii
    codes, e = radius_codes(X, Y, np.where(v, z, np.nan), v, span=span)
    xp, yp, zp = _proxy_positions(X, Y, np.where(v, z, np.nan), v)
    mine = np.zeros((R, C), np.uint8)
    verts = _vertices(R, C, span)
    leaf = (verts[:, 2] == 1) & ~(((verts[:, 0] % 2) == 1) & ((verts[:, 1] % 2) == 1))
    nest_codes_rect(np.ascontiguousarray(xp), np.ascontiguousarray(yp), zp, mine,
                    log8_table(e).astype(np.float64), verts[~leaf], 0, 0, R, C)
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


def _counts_by_sweep(vf, i0, j0, s, main):
    # cell_counts_nb's definition, sample by sample (its plain-count shortcut aside)
    tot, c1, t1, c2, t2 = 0, 0.0, 0.0, 0.0, 0.0
    for di in range(s + 1):
        for dj in range(s + 1):
            first = dj >= di if main else di + dj <= s
            both = dj == di if main else di + dj == s
            v = float(vf[i0 + di, j0 + dj])
            tot += int(vf[i0 + di, j0 + dj])
            if first or both:
                c1, t1 = c1 + v, t1 + 1.0
            if (not first) or both:
                c2, t2 = c2 + v, t2 + 1.0
    return tot, c1, t1, c2, t2


@pytest.mark.fast
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), s=st.sampled_from([1, 2, 4, 8]),
       holes=st.sampled_from([0.0, 0.05, 0.5, 1.0]), main=st.booleans())
def test_cell_counts_are_the_sample_sweeps(seed, s, holes, main):
    # all valid, none valid (the shortcut) and mixed cells: the same five numbers
    v = (np.random.default_rng(seed).random((s + 3, s + 3)) >= holes).view(np.uint8)
    got = cell_counts_nb(v, 1, 2, s, main)
    assert got == _counts_by_sweep(v, 1, 2, s, main)
    assert [type(a) for a in got[1:]] == [float] * 4


@pytest.mark.fast
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 6), L=st.integers(1, 4))
def test_level_field_of_an_all_valid_grid_needs_no_mask(seed, n, L):
    z, v = _grid(seed, n, 0.0)
    zf, vv, _ = check_grid(z, v)
    s = 1 << min(L, n)
    E, E2 = np.zeros(zf.shape), np.full(zf.shape, 7.0)
    mixed = _level_field_nb(zf, vv.view(np.uint8), s, E)
    # the mask unread: zeros in it would change the field were it read
    mixed2 = _level_field_nb(zf, np.zeros_like(vv, np.uint8), s, E2, True)
    assert np.array_equal(E, E2) and np.array_equal(mixed, mixed2) and not mixed.any()

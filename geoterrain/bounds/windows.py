"""δ, r and the tile errors' field on windows of a grid, with the whole-grid kernels'
arithmetic: what an edit (:mod:`geoterrain.preprocessing.edit`) recomputes where it
changed the heights, and nowhere else.

Each kernel takes a window of the grid (``z``, ``vb``: heights in scene units, invalid
ones 0, and validity, their sample (0, 0) at grid sample (``oi``, ``oj``)) and the
vertices to compute in grid coordinates, so the union-jack parity
(:func:`geoterrain.core.bintree.main_diagonal_nb`) and the bintree's children are the
whole grid's. They call the same compiled helpers as :mod:`geoterrain.bounds.delta`,
:mod:`geoterrain.bounds.radii` and :mod:`geoterrain.bounds.tilebounds`, in the same
order, so a value computed here is the whole grid's bit for bit (tested):

- :func:`fine_raw_delta`: raw δ (seed 002 §2.3, the exact diamond maximum) of vertices
  whose diamond lies in the window;
- :func:`block_sweep_rect`: :func:`geoterrain.bounds.delta._block_sweep`'s five maxima over
  a rectangle of a block (a block larger than a window is swept a tile at a time, its
  maxima the largest of the parts');
- :func:`nest_codes_rect` and :func:`nest_codes_sparse`: the radii's log8 codes nested
  on their children's codes (§2.4, L50–52);
- :func:`level_field_rect`: the tile errors' field |z − S_L| and mixed cells on a window.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.bounds.delta import (
    _FM,
    Cell,
    Diamond,
    _block_sweep,
    _centre1,
    _edge_err_part,
    _mid1,
    cell_rows_nb,
    edge_status_nb,
)
from geoterrain.bounds.radii import code_up_nb
from geoterrain.bounds.tilebounds import cell_counts_nb, cell_field_rows_nb, cell_status_nb
from geoterrain.core.bintree import child_nb, main_diagonal_nb
from geoterrain.core.rounding import round_up32

__all__ = ["block_sweep_rect", "fine_raw_delta", "level_field_rect", "nest_codes_rect",
           "nest_codes_sparse"]


@njit(cache=True, fastmath=_FM)
def block_sweep_rect(z, r0, q0, cell, zc, a0, a1, c0, c1):
    """The five maxima of :func:`geoterrain.bounds.delta._block_sweep_part` (centre, left,
    right, top, bottom quarter) over rows ``a0 … a1`` and columns ``c0 … c1`` of the
    block ``cell`` (block-relative, inclusive); ``z`` holds the grid's samples from row
    ``r0`` and column ``q0``; ``zc`` is the block's centre height. The same expressions
    in the same order: a block's maxima are the largest of its rectangles'."""
    i0, j0, s, main, z00, z01, z10, z11 = cell
    h = s // 2
    inv = 1.0 / s
    invh = 1.0 / h
    kl = (zc - 0.5 * (z00 + z10)) * invh
    kr = (zc - 0.5 * (z01 + z11)) * invh
    kt = (zc - 0.5 * (z00 + z01)) * invh
    kb = (zc - 0.5 * (z10 + z11)) * invh
    mc = 0.0
    ml = 0.0
    mr = 0.0
    mt = 0.0
    mb = 0.0
    for di in range(a0, a1 + 1):
        zi = i0 + di - r0
        zj = j0 - q0
        fi = di * inv
        b1, g1, b2, g2 = cell_rows_nb(z00, z01, z10, z11, fi, inv, main)
        upper = di <= h
        lo = di if upper else s - di
        hi = s - di if upper else di
        use1 = (not upper) if main else upper
        bm = b1 if use1 else b2
        gm = g1 if use1 else g2
        bl = z00 + (z10 - z00) * fi
        br = z01 + (z11 - z01) * fi + kr * s
        if upper:
            bq = z00 + kt * di
            gq = (z01 - z00) * inv
        else:
            bq = z10 + kb * (s - di)
            gq = (z11 - z10) * inv
        a = 0.0
        q = 0.0
        for dj in range(max(c0, 0), min(lo, c1 + 1)):
            zz = z[zi, zj + dj]
            a = max(a, abs(zz - (b1 + g1 * dj)))
            q = max(q, abs(zz - (bl + kl * dj)))
        ml = max(ml, q)
        q = 0.0
        for dj in range(max(c0, lo), min(hi, c1) + 1):
            zz = z[zi, zj + dj]
            a = max(a, abs(zz - (bm + gm * dj)))
            q = max(q, abs(zz - (bq + gq * dj)))
        if upper:
            mt = max(mt, q)
        if di >= h:
            mb = max(mb, q)
        q = 0.0
        for dj in range(max(c0, hi + 1), min(s, c1) + 1):
            zz = z[zi, zj + dj]
            a = max(a, abs(zz - (b2 + g2 * dj)))
            q = max(q, abs(zz - (br - kr * dj)))
        mr = max(mr, q)
        mc = max(mc, a)
        # the two diagonal samples also belong to the left / right quarters
        if c0 <= lo <= c1:
            ml = max(ml, abs(z[zi, zj + lo] - (bl + kl * lo)))
        if c0 <= hi <= c1:
            mr = max(mr, abs(z[zi, zj + hi] - (br - kr * hi)))
    return mc, ml, mr, mt, mb


@njit(cache=True, nogil=True)
def _block_status(vb, i0, j0, s):
    # bit 1: the closed block holds a valid sample, bit 2: an invalid one
    f = 0
    for i in range(i0, i0 + s + 1):
        for j in range(j0, j0 + s + 1):
            f |= 1 if vb[i, j] else 2
        if f == 3:
            break
    return f


@njit(cache=True, nogil=True)
def _quarter(z, vb, i0, j0, s, main, which):
    # (status, the quarter maximum `which` (1 left, 2 right, 3 top, 4 bottom)) of the
    # closed block at window (i0, j0); the maximum only for an all-valid block
    f = _block_status(vb, i0, j0, s)
    if f != 1:
        return f, 0.0
    m = _block_sweep(z, i0, j0, s, main)
    return f, m[which]


@njit(cache=True)
def fine_raw_delta(z, vb, oi, oj, R, C, verts, out):
    """Raw δ (float32 rounded up; +inf where the diamond mixes valid and invalid samples,
    0 where it holds none) of the vertices ``verts`` (rows: grid i, j and half-span h),
    as :func:`geoterrain.bounds.delta._raw_delta_nb` computes them, into ``out``; every
    vertex's closed diamond (and its blocks) lies in the window, the grid is R × C (the
    square's N × N, or a root grid's extent)."""
    for k in range(verts.shape[0]):
        i, j, h = verts[k, 0], verts[k, 1], verts[k, 2]
        il, jl = i - oi, j - oj
        s = 2 * h
        if (i // h) % 2 == 1 and (j // h) % 2 == 1:  # a block centre
            main = main_diagonal_nb((i - h) // s, (j - h) // s)
            f = _block_status(vb, il - h, jl - h, s)
            v = np.float32(0.0)
            if f == 1:
                if h == 1:
                    v = round_up32(_centre1(z, il, jl, main))
                else:
                    v = round_up32(_block_sweep(z, il - h, jl - h, s, main)[0])
            elif f == 3:
                v = np.float32(np.inf)
            out[k] = v
            continue
        rows = (i // h) % 2 == 1  # hypotenuse along the rows: ends (i ± h, j)
        flo = 0
        fhi = 0
        qlo = 0.0
        qhi = 0.0
        if rows:
            a = (i - h) // s
            if j > 0:
                flo, qlo = _quarter(z, vb, il - h, jl - s, s, main_diagonal_nb(a, j // s - 1),
                                    2)
            if j < C - 1:
                fhi, qhi = _quarter(z, vb, il - h, jl, s, main_diagonal_nb(a, j // s), 1)
        else:
            b = (j - h) // s
            if i > 0:
                flo, qlo = _quarter(z, vb, il - s, jl - h, s, main_diagonal_nb(i // s - 1, b),
                                    4)
            if i < R - 1:
                fhi, qhi = _quarter(z, vb, il, jl - h, s, main_diagonal_nb(i // s, b), 3)
        f = flo | fhi
        v = np.float32(0.0)
        if f == 1:
            if h == 1:
                v = round_up32(_mid1(z, il, jl, rows))
            else:
                m = 0.0
                if flo:
                    m = max(m, qlo)
                if fhi:
                    m = max(m, qhi)
                v = round_up32(m)
        elif f != 2:  # a mix: the diamond swept (bounds.edge_err_window)
            if rows:
                lo_ok = j - h >= 0
                hi_ok = j + h <= C - 1
                za = z[il - h, jl]
                zb = z[il + h, jl]
                z_lo = z[il, jl - h] if lo_ok else 0.0
                z_hi = z[il, jl + h] if hi_ok else 0.0
            else:
                lo_ok = i - h >= 0
                hi_ok = i + h <= R - 1
                za = z[il, jl - h]
                zb = z[il, jl + h]
                z_lo = z[il - h, jl] if lo_ok else 0.0
                z_hi = z[il + h, jl] if hi_ok else 0.0
            m, cnt, tot = _edge_err_part(z, vb, Diamond(il, jl, h, rows, lo_ok, hi_ok, za, zb,
                                                        z_lo, z_hi), -h, h, 0)
            m, c = edge_status_nb(m, cnt, tot)
            if c == 2:
                v = np.float32(np.inf)
            elif c == 1:
                v = round_up32(m)
        out[k] = v


@njit(cache=True)
def nest_codes_rect(x, y, z, codes, table, verts, oi, oj, R, C):
    """The radius codes of ``verts`` (rows: grid i, j, h; fine to coarse, each level's
    edge midpoints before its centres, none an h = 1 edge midpoint, a leaf), nested on
    their children's codes as :func:`geoterrain.bounds.radii.nest_code_nb` nests them, into
    ``codes``; ``x``, ``y``, ``z`` (scene, invalid z at the stand-in height) and
    ``codes`` hold the window from grid sample (``oi``, ``oj``), which holds every
    child in the R × C grid."""
    for k in range(verts.shape[0]):
        i, j, h = verts[k, 0], verts[k, 1], verts[k, 2]
        il, jl = i - oi, j - oj
        best = 0.0
        for c in range(4):
            ci, cj = child_nb(i, j, h, c)
            if 0 <= ci < R and 0 <= cj < C:
                cl, ck = ci - oi, cj - oj
                d = np.sqrt((x[il, jl] - x[cl, ck]) ** 2 + (y[il, jl] - y[cl, ck]) ** 2
                            + (z[il, jl] - z[cl, ck]) ** 2) + table[codes[cl, ck]]
                best = max(best, d)
        codes[il, jl] = code_up_nb(table, best)


@njit(cache=True)
def nest_codes_sparse(px, py, pz, child_codes, present, table, out):
    """:func:`nest_codes_rect` for vertices far apart: row k holds vertex k's position
    (column 0) and its four children's (columns 1 … 4, in ``child_nb``'s order), their
    codes and whether each is in the grid; the codes go to ``out``."""
    for k in range(px.shape[0]):
        best = 0.0
        for c in range(4):
            if present[k, c]:
                d = np.sqrt((px[k, 0] - px[k, c + 1]) ** 2 + (py[k, 0] - py[k, c + 1]) ** 2
                            + (pz[k, 0] - pz[k, c + 1]) ** 2) + table[child_codes[k, c]]
                best = max(best, d)
        out[k] = code_up_nb(table, best)


@njit(cache=True)
def level_field_rect(z, vb, oi, oj, s, E, mixed):
    """:func:`geoterrain.bounds.tilebounds._level_field_nb` on a window: E (zeroed
    first) gets, at each sample, the largest |z − S_L| over the all-valid closed
    triangles of the level cells of side ``s`` that lie in the window and hold it;
    ``mixed`` (one per cell of the window, cell rows and columns from the window's
    first) whether a cell's triangle mixes valid and invalid samples. The window's
    origin (``oi``, ``oj``) is a multiple of ``s``."""
    E[:, :] = 0.0
    nbi = (z.shape[0] - 1) // s
    nbj = (z.shape[1] - 1) // s
    for bi in range(nbi):
        for bj in range(nbj):
            i0 = bi * s
            j0 = bj * s
            main = main_diagonal_nb(oi // s + bi, oj // s + bj)
            skip, whole, ok1, ok2, mix = cell_status_nb(cell_counts_nb(vb, i0, j0, s, main), s)
            mixed[bi, bj] = mix
            if skip:
                continue
            cell_field_rows_nb(z, Cell(i0, j0, s, main, z[i0, j0], z[i0, j0 + s], z[i0 + s, j0],
                                       z[i0 + s, j0 + s]), whole, ok1, ok2, 0, s, E)

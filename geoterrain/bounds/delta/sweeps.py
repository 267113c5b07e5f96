"""The sweeps of one diamond or one block that δ is made of (seed 002 §2.3, the exact
maximum of |z − S| over a vertex's closed diamond): an edge midpoint's diamond swept row by
row, a union-jack block's centre and four quarters in one pass, the h = 1 closed forms, and
the named tuples the kernels take. The whole grid's passes over them:
:mod:`geoterrain.bounds.delta.exact`; in row bands: :mod:`geoterrain.preprocessing.bands.delta`;
a level-0 tile on read: :mod:`geoterrain.bounds.leafbounds`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.core.rounding import round_up32

__all__ = ["Beside", "Cell", "Diamond", "cell_rows_nb", "edge_delta_nb", "edge_err_window",
           "edge_status_nb"]


# ------------------------------------------------------------- the kernels' bundles
class Cell(NamedTuple):
    """A union-jack cell (a block) of side ``s``, its first sample at row ``i0``, column
    ``j0`` (as the caller's arrays number them), its diagonal (``main``: (0, 0)–(1, 1),
    else (0, 1)–(1, 0)) and its corner heights."""

    i0: int
    j0: int
    s: int
    main: bool
    z00: float
    z01: float
    z10: float
    z11: float


class Diamond(NamedTuple):
    """An edge midpoint's diamond: the vertex (``ic``, ``jc``) of half-span ``h``, its
    hypotenuse along the rows (``rows``: ends (ic ± h, jc)) or the columns, the heights
    ``za``, ``zb`` of the hypotenuse's ends and ``z_lo``, ``z_hi`` of the other two
    corners, which exist only if ``lo_ok``, ``hi_ok`` (else 0, never read)."""

    ic: int
    jc: int
    h: int
    rows: bool
    lo_ok: bool
    hi_ok: bool
    za: float
    zb: float
    z_lo: float
    z_hi: float


class Beside(NamedTuple):
    """The two blocks beside an edge midpoint, on its low and high side: their statuses
    ``flo``, ``fhi`` (1 all valid, 2 all invalid, 3 mixed, 0 outside the grid) and, for
    h ≥ 2, their quarter maxima ``qlo``, ``qhi`` facing it."""

    flo: int
    fhi: int
    qlo: float
    qhi: float


# ------------------------------------------------------------- numba δ kernel (exact)
# Every kernel returns (max |z − S|, status) with status 0 = all invalid, 1 = all valid,
# 2 = mixed; +inf is assigned afterwards in numpy (the block sweeps are compiled with fast
# math, so no kernel sees a non-finite value: invalid heights are zeroed beforehand).

_FM = {"nnan", "ninf", "nsz"}


@njit(cache=True, inline="always")
def _mid1(z, ic, jc, rows):
    # an h = 1 edge midpoint between two all-valid cells: its distance to the hypotenuse
    if rows:
        return abs(z[ic, jc] - 0.5 * (z[ic - 1, jc] + z[ic + 1, jc]))
    return abs(z[ic, jc] - 0.5 * (z[ic, jc - 1] + z[ic, jc + 1]))


# no fast math here: a reader repeats these for level 0's vertices (bounds/leafbounds/)
# and must get the same bits on any machine (fast math may fuse a multiply-add)
@njit(cache=True)
def _edge_err_part(z, vb, dia, d0, d1, r0):
    """Rows ``ic + d`` (d in [d0, d1]) of an edge midpoint's diamond sweep (``dia``:
    :class:`Diamond`): (max, valid count, sample count). ``z``/``vb`` hold grid rows from
    ``r0`` on (a band, or the grid with r0 = 0). Max and counts are exact, so sweeping
    the rows in any split gives the bits of one sweep."""
    ic, jc, h, rows, lo_ok, hi_ok, za, zb, z_lo, z_hi = dia
    invh = 1.0 / h
    zm = 0.5 * (za + zb)
    g = 0.5 * (zb - za) * invh
    k_lo = (z_lo - zm) * invh if lo_ok else 0.0
    k_hi = (z_hi - zm) * invh if hi_ok else 0.0
    m = 0.0
    cnt = 0
    tot = 0
    if rows:
        for di in range(max(-h, d0), min(h, d1) + 1):
            w = h - abs(di)
            i = ic + di - r0
            line = zm + g * di
            jlo = -w if lo_ok else 0
            jhi = w if hi_ok else 0
            for dj in range(jlo, 1):
                if not vb[i, jc + dj]:
                    continue
                m = max(m, abs(z[i, jc + dj] - (line - k_lo * dj)))
                cnt += 1
            for dj in range(1, jhi + 1):
                if not vb[i, jc + dj]:
                    continue
                m = max(m, abs(z[i, jc + dj] - (line + k_hi * dj)))
                cnt += 1
            tot += jhi - jlo + 1
    else:
        dlo = -h if lo_ok else 0
        dhi = h if hi_ok else 0
        for di in range(max(dlo, d0), min(dhi, d1) + 1):
            w = h - abs(di)
            i = ic + di - r0
            k = -k_lo * di if di < 0 else k_hi * di
            base = zm + k
            row = z[i, jc - w:jc + w + 1]
            vrow = vb[i, jc - w:jc + w + 1]
            for dj in range(2 * w + 1):
                if vrow[dj]:
                    m = max(m, abs(row[dj] - (base + g * (dj - w))))
                    cnt += 1
            tot += 2 * w + 1
    return m, cnt, tot


@njit(cache=True, inline="always")
def edge_status_nb(m, cnt, tot):
    """(δ, status) of a swept diamond: status 0 = all invalid, 1 = all valid, 2 = mixed."""
    if cnt == 0:
        return 0.0, 0
    if cnt < tot:
        return 0.0, 2
    return m, 1


@njit(cache=True)
def _edge_err(z, vb, ic, jc, h, rows, N):
    # Diamond of an edge midpoint = |di| + |dj| <= h, clipped to the grid; the hypotenuse
    # runs along the rows (rows=True: endpoints (ic ± h, jc)) or along the columns.
    return edge_err_window(z, vb, ic, jc, h, rows, N, 0)


@njit(cache=True)
def edge_err_window(z, vb, ic, jc, h, rows, N, w0):
    """:func:`_edge_err` of grid vertex (ic, jc) on ``z``/``vb`` holding the (N, N) grid's
    rows from ``w0`` on (a band whose rows hold the whole diamond)."""
    il = ic - w0
    if rows:
        lo_ok = jc - h >= 0
        hi_ok = jc + h <= N - 1
        za = z[il - h, jc]
        zb = z[il + h, jc]
        z_lo = z[il, jc - h] if lo_ok else 0.0
        z_hi = z[il, jc + h] if hi_ok else 0.0
    else:
        lo_ok = ic - h >= 0
        hi_ok = ic + h <= N - 1
        za = z[il, jc - h]
        zb = z[il, jc + h]
        z_lo = z[il - h, jc] if lo_ok else 0.0
        z_hi = z[il + h, jc] if hi_ok else 0.0
    m, cnt, tot = _edge_err_part(z, vb, Diamond(ic, jc, h, rows, lo_ok, hi_ok, za, zb, z_lo,
                                                z_hi), -h, h, w0)
    return edge_status_nb(m, cnt, tot)


@njit(cache=True, inline="always")
def edge_delta_nb(z, vb, ic, jc, h, rows, N, w0, beside, old):
    """Raw δ of edge midpoint (ic, jc) from its two blocks (``beside``: :class:`Beside`);
    ``z``/``vb`` hold the grid's rows from ``w0`` on. Both blocks all valid: the max of
    their quarters (h = 1: the closed form); a mix: the diamond swept (+inf if it mixes
    too); ``old`` when nothing is valid."""
    flo, fhi, qlo, qhi = beside
    f = flo | fhi
    if f == 2:
        return old
    if f == 1:
        if h == 1:
            m = _mid1(z, ic - w0, jc, rows)
        else:
            m = 0.0
            if flo:
                m = max(m, qlo)
            if fhi:
                m = max(m, qhi)
        return round_up32(m)
    m, c = edge_err_window(z, vb, ic, jc, h, rows, N, w0)
    if c == 2:
        return np.inf
    if c == 1:
        return round_up32(m)
    return old


@njit(cache=True, inline="always")
def cell_rows_nb(z00, z01, z10, z11, fi, inv, main):
    """Row fi of a union-jack cell's two planes: z = b1 + g1·dj left of the diagonal,
    z = b2 + g2·dj right of it (dj in samples, inv = 1/side).

    ``main``: the diagonal joins (0, 0)–(1, 1); otherwise (0, 1)–(1, 0).
    """
    if main:
        return (z00 + (z10 - z00) * fi, (z11 - z10) * inv,
                z00 + (z11 - z01) * fi, (z01 - z00) * inv)
    return (z00 + (z10 - z00) * fi, (z01 - z00) * inv,
            z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11), -(z10 - z11) * inv)


@njit(cache=True)
def _centre1(z, ci, cj, main):
    # h = 1 closed form: only the centre and the 4 edge midpoints of the 3×3 block are
    # not vertices; the block edges are triangle legs, the centre lies on the diagonal.
    z00 = z[ci - 1, cj - 1]
    z01 = z[ci - 1, cj + 1]
    z10 = z[ci + 1, cj - 1]
    z11 = z[ci + 1, cj + 1]
    sc = 0.5 * (z00 + z11) if main else 0.5 * (z01 + z10)
    m = abs(z[ci, cj] - sc)
    m = max(m, abs(z[ci - 1, cj] - 0.5 * (z00 + z01)))
    m = max(m, abs(z[ci + 1, cj] - 0.5 * (z10 + z11)))
    m = max(m, abs(z[ci, cj - 1] - 0.5 * (z00 + z10)))
    m = max(m, abs(z[ci, cj + 1] - 0.5 * (z01 + z11)))
    return m


@njit(cache=True, fastmath=_FM)
def _block_sweep_part(z, cell, zc, d0, d1, r0):
    """Rows ``d0 … d1`` (block-relative, inclusive) of :func:`_block_sweep`'s pass over
    the block ``cell`` (:class:`Cell`, at a grid row), its centre height ``zc`` given;
    ``z`` holds grid rows from ``r0`` on. Maxima are exact, so sweeping a block's rows in
    any split gives the bits of one sweep."""
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
    for di in range(d0, d1 + 1):
        row = z[i0 + di - r0, j0:j0 + s + 1]
        fi = di * inv
        # centre surface: P1 left of the union-jack diagonal, P2 right of it
        b1, g1, b2, g2 = cell_rows_nb(z00, z01, z10, z11, fi, inv, main)
        upper = di <= h
        lo = di if upper else s - di
        hi = s - di if upper else di
        use1 = (not upper) if main else upper  # plane of the middle segment
        bm = b1 if use1 else b2
        gm = g1 if use1 else g2
        # quarter surfaces along this row
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
        for dj in range(lo):
            zz = row[dj]
            a = max(a, abs(zz - (b1 + g1 * dj)))
            q = max(q, abs(zz - (bl + kl * dj)))
        ml = max(ml, q)
        q = 0.0
        for dj in range(lo, hi + 1):
            zz = row[dj]
            a = max(a, abs(zz - (bm + gm * dj)))
            q = max(q, abs(zz - (bq + gq * dj)))
        if upper:
            mt = max(mt, q)
        if di >= h:
            mb = max(mb, q)
        q = 0.0
        for dj in range(hi + 1, s + 1):
            zz = row[dj]
            a = max(a, abs(zz - (b2 + g2 * dj)))
            q = max(q, abs(zz - (br - kr * dj)))
        mr = max(mr, q)
        mc = max(mc, a)
        # the two diagonal samples also belong to the left / right quarters
        ml = max(ml, abs(row[lo] - (bl + kl * lo)))
        mr = max(mr, abs(row[hi] - (br - kr * hi)))
    return mc, ml, mr, mt, mb


@njit(cache=True)
def _block_sweep(z, i0, j0, s, main):
    """One pass over an all-valid closed block of side s = 2h: the exact max error of its
    centre (surface = the 2 union-jack halves) and of its 4 quarter triangles (surface of
    the next depth: each quarter's diamond is one quarter of each adjacent block).
    Returns (centre, left, right, top, bottom); quarters are closed (diagonals in both)."""
    h = s // 2
    return _block_sweep_part(z, Cell(i0, j0, s, main, z[i0, j0], z[i0, j0 + s], z[i0 + s, j0],
                                     z[i0 + s, j0 + s]), z[i0 + h, j0 + h], 0, s, 0)

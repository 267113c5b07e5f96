"""Per-vertex error bounds: exact δ and its saturation (the nested radii:
:mod:`geoterrain.bounds.radii`).

Seed 002 (Lindstrom & Pascucci): δ is the object-space error of a vertex (§2.3), saturated
so that δ(parent) ≥ δ(child) (§2.4, L46); with the nested bounding-sphere radii
(:mod:`geoterrain.bounds.radii`) the screen-space error of LP eq. 2, ρ = λ δ / (|p − o| − r), is
monotone along the vertex DAG.

Unlike the midpoint-only error of the seed (and of Martini), δ here is the exact maximum
of |z − S| over every valid full-resolution sample of the vertex's closed diamond, S being
the two triangles drawn while the vertex is absent, so δ bounds the vertical error of any
mesh extracted with it. Grid and bintree conventions: docs/conventions.md and
:mod:`geoterrain.core.bintree` (whose compiled helpers give the parents, children and
union-jack parity used here). Per-tile bounds: :mod:`geoterrain.bounds.tilebounds`; the slow
numpy oracles the tests compare against: :mod:`geoterrain.testing.reference`.

Invalid samples
---------------
``valid`` is authoritative (a valid sample with a non-finite height is treated as
invalid). Heights of invalid samples are never read for δ or tile errors. A diamond that
mixes valid and invalid samples gets δ = +inf; an all-invalid one gets 0.

Root grids
----------
On a rectangular root grid (issue 45, :mod:`geoterrain.core.bintree`) the arrays are
the roots' extent, (ry·S + 1, rx·S + 1) for roots of side S = ``span``, with the samples
beyond the raster invalid: the same kernels, over a rectangle of blocks, stop at the
roots' centres and edges (half-span S/2), and every root's corners get 0 as the square's
four do. ``span`` None is the square (S = N − 1).

"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import cores_for, parallel_kernel

__all__ = ["below_own_error", "delta_max_finite", "saturate", "vertex_errors",
           "vertex_errors_fields"]


# --------------------------------------------------------------------------- helpers


def grid_order(N: int) -> int:
    """n for a grid side N = 2**n + 1 (n ≥ 1); ValueError otherwise."""
    n = int(N - 1).bit_length() - 1
    if N < 3 or (1 << n) + 1 != N:
        raise ValueError(f"grid side must be 2**n + 1 with n >= 1, got {N}")
    return n


def check_grid(z: np.ndarray, valid: np.ndarray, span: int | None = None
               ) -> tuple[np.ndarray, np.ndarray, int]:
    """Checked, contiguous ``(z, valid, n)``: non-finite heights become invalid, and
    invalid heights 0 (never read). ``span``: a root grid's root side 2**n, the arrays
    then a whole number of roots each way (see the module's docstring)."""
    z = np.asarray(z, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if span is None:
        if z.ndim != 2 or z.shape[0] != z.shape[1] or valid.shape != z.shape:
            raise ValueError(f"z and valid must be the same (N, N) shape, got {z.shape}, "
                             f"{valid.shape}")
        n = grid_order(z.shape[0])
    else:
        n = grid_order(span + 1)
        if z.ndim != 2 or valid.shape != z.shape or any((k - 1) % span or k < 3
                                                         for k in z.shape):
            raise ValueError(f"z and valid must be the same (ry·{span} + 1, rx·{span} + 1) "
                             f"shape, got {z.shape}, {valid.shape}")
    if valid.all() and np.isfinite(z).all():
        return np.ascontiguousarray(z), np.ascontiguousarray(valid), n
    valid = valid & np.isfinite(z)
    zf = np.where(valid, z, 0.0)  # invalid heights are never read
    return zf, valid, n


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
# Rows on every core for large grids (errors 0.54 → 0.34 s, radii 0.32 → 0.20 s on the
# quiet 4097² fBm, docs/lab/preprocess.md); small ones run on one thread, where a busy
# core made the barriers cost more than the work (geoterrain/core/threads.py: cores_for).
# Each output is written by one iteration, so the values do not depend on the threads.
# (Each prange kernel is a ParallelKernel: a fork() child runs its serial twin.)


@njit(cache=True, inline="always")
def _mid1(z, ic, jc, rows):
    # an h = 1 edge midpoint between two all-valid cells: its distance to the hypotenuse
    if rows:
        return abs(z[ic, jc] - 0.5 * (z[ic - 1, jc] + z[ic + 1, jc]))
    return abs(z[ic, jc] - 0.5 * (z[ic, jc - 1] + z[ic, jc + 1]))


# no fast math here: a reader repeats these for level 0's vertices (geoterrain/bounds/leafbounds.py)
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


@parallel_kernel(cache=True, nogil=True)
def _block_status_nb(vb, span):
    # bs[centre of a closed 2h block] = bit 1: holds a valid sample, bit 2: an invalid one;
    # built fine to coarse (a closed 2h block is the union of its four closed h blocks),
    # up to blocks of side ``span`` (the square's N − 1, or a root's side).
    R, C = vb.shape
    bs = np.zeros((R, C), np.uint8)
    nr = (R - 1) // 2
    nc = (C - 1) // 2
    for k in prange(nr * nc):
        bi = k // nc
        bj = k - bi * nc
        f = 0
        for di in range(3):
            for dj in range(3):
                f |= 1 if vb[2 * bi + di, 2 * bj + dj] else 2
        bs[2 * bi + 1, 2 * bj + 1] = f
    h = 2
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        q = h // 2
        for k in prange(nr * nc):
            bi = k // nc
            bj = k - bi * nc
            ci = bi * s + h
            cj = bj * s + h
            bs[ci, cj] = (bs[ci - q, cj - q] | bs[ci - q, cj + q]
                          | bs[ci + q, cj - q] | bs[ci + q, cj + q])
        h *= 2
    return bs


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


@parallel_kernel(cache=True, nogil=True)
def _raw_delta_nb(z, vb, bs, all_valid, span):
    """Raw exact δ, float32 rounded up (+inf for mixed diamonds); ``bs`` the blocks'
    status (:func:`_block_status_nb`; unread when ``all_valid``); vertices of half-span
    below ``span`` (the square's N − 1, or a root's side)."""
    R, C = z.shape
    out = np.zeros((R, C), np.float32)
    QL = np.empty((max((R - 1) // 4, 1), max((C - 1) // 4, 1)))
    QR = np.empty_like(QL)
    QT = np.empty_like(QL)
    QB = np.empty_like(QL)
    h = np.int64(1)  # not a literal 1: the edge sweep compiles once
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        # centres of the 2h blocks (+ quarter maxima for the edge midpoints, h >= 2)
        for bi in prange(nr):
            for bj in range(nc):
                ci = bi * s + h
                cj = bj * s + h
                f = 1 if all_valid else bs[ci, cj]
                main = main_diagonal_nb(bi, bj)
                if f == 1:
                    if h == 1:
                        m = _centre1(z, ci, cj, main)
                    else:
                        m, ml, mr, mt, mb = _block_sweep(z, bi * s, bj * s, s, main)
                        QL[bi, bj] = ml
                        QR[bi, bj] = mr
                        QT[bi, bj] = mt
                        QB[bi, bj] = mb
                    out[ci, cj] = round_up32(m)
                elif f == 3:
                    out[ci, cj] = np.inf
        # edge midpoints: hypotenuse along the rows (typ 0) or along the columns (typ 1)
        for typ in range(2):
            rows = typ == 0
            na = nr if rows else nr + 1
            nb = nc + 1 if rows else nc
            lim = C if rows else R  # the domain's size across the hypotenuse
            for a in prange(na):
                for b in range(nb):
                    ic = h + a * s if rows else a * s
                    jc = b * s if rows else h + b * s
                    # adjacent blocks (lo side, hi side) and their status
                    flo = 0
                    fhi = 0
                    if rows:
                        if jc > 0:
                            flo = 1 if all_valid else bs[ic, jc - h]
                        if jc < C - 1:
                            fhi = 1 if all_valid else bs[ic, jc + h]
                    else:
                        if ic > 0:
                            flo = 1 if all_valid else bs[ic - h, jc]
                        if ic < R - 1:
                            fhi = 1 if all_valid else bs[ic + h, jc]
                    if h >= 2 and rows:
                        qlo = QR[a, b - 1] if flo else 0.0
                        qhi = QL[a, b] if fhi else 0.0
                    elif h >= 2:
                        qlo = QB[a - 1, b] if flo else 0.0
                        qhi = QT[a, b] if fhi else 0.0
                    else:
                        qlo = qhi = 0.0
                    out[ic, jc] = edge_delta_nb(z, vb, ic, jc, h, rows, lim, 0,
                                                Beside(flo, fhi, qlo, qhi), out[ic, jc])
        h *= 2
    return out


@parallel_kernel(cache=True, nogil=True)
def _saturate_pull_nb(d, span):
    # LP §2.4 (L46), rows on every core: each vertex pulls its children's δ, depths fine
    # to coarse (one max per DAG edge; at each h a receiver never gives in the same phase,
    # so the order does not matter; δ ≥ +0.0, no NaN): the centres of h from their 4 edge
    # midpoints of h, then the edge midpoints of 2h (odd (I + J) on the 2h lattice) from
    # the centres of h around.
    R, C = d.shape
    h = 1
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        for a in prange(nr):
            i = h + a * s
            for b in range(nc):
                j = h + b * s
                v = d[i, j]
                for w in (d[i, j - h], d[i, j + h], d[i - h, j], d[i + h, j]):
                    if v < w:
                        v = w
                d[i, j] = v
        for a in prange(nr + 1):
            i = a * s
            for b in range((a + 1) % 2, nc + 1, 2):
                j = b * s
                v = d[i, j]
                for di in (-h, h):
                    for dj in (-h, h):
                        if 0 <= i + di < R and 0 <= j + dj < C and v < d[i + di, j + dj]:
                            v = d[i + di, j + dj]
                d[i, j] = v
        h *= 2
    for i in range(0, R, span):
        for j in range(0, C, span):
            d[i, j] = 0
    return d


def saturate(d: np.ndarray, span: int | None = None) -> np.ndarray:
    """Saturate per-vertex errors in place, fine to coarse, so δ(parent) ≥ δ(child) on
    every bintree edge (seed 002 §2.4, L46); the domain corners (every root's, on a root
    grid of root side ``span``) get 0. Returns ``d``.

    Examples
    --------
    >>> d = np.zeros((3, 3), np.float32); d[0, 1] = 2.0  # an edge midpoint
    >>> float(saturate(d)[1, 1])  # its parent, the centre
    2.0
    >>> d = np.zeros((3, 5), np.float32); d[1, 2] = 2.0  # the edge two roots share
    >>> saturate(d, 2)[1].tolist()  # both roots' centres, its parents
    [0.0, 2.0, 2.0, 2.0, 0.0]
    """
    with cores_for(d.size):  # small grids on one thread
        return _saturate_pull_nb(d, d.shape[0] - 1 if span is None else span)


# ----------------------------------------------- δ's centre sweep and the tile-bound field
# An all-valid grid's union-jack cell of side s is swept by δ's centre (the block of half-span
# s / 2, against the same two planes) and by the tile-bound field of level log2(s)
# (geoterrain/bounds/tilebounds.py: cell_field_rows_nb). Both are made in one sweep where the
# cells lie inside the level-0 tiles (s ≤ cpt): the field's part of each cell is reduced where
# it is made to (a) the cell's maximum and (b) its samples on the tiles' lines, and the
# tiles' maxima are pooled from those (tilebounds.tile_and_block_errors). The two sweeps
# differ on one sample a row: in a cell's lower half (row > s / 2) δ takes the diagonal
# sample on the plane of the row's middle segment, the field on the other one.


@njit(cache=True, nogil=True)
def _field_err(zz, b1, g1, b2, g2, dj, cut):
    # |z − S| of the tile-bound field at sample dj of a cell row (cell_field_rows_nb's
    # arithmetic: plane 1 before ``cut``, plane 2 from it; no fast math, as there)
    if dj < cut:
        return abs(zz - (b1 + g1 * dj))
    return abs(zz - (b2 + g2 * dj))


@njit(cache=True, nogil=True)
def _field_lines(row, i, j0, s, di, main, b1, g1, b2, g2, lines):
    """Row ``di`` (grid row ``i``) of a cell's part of the tile-bound field on the level-0
    tiles' lines, maxed into ``lines`` = (H, V, cpt, par): the whole row into H[par, k] if
    it is tile line k, its first and last samples into V[par, l, i] if they are on
    tile column line l."""
    H, V, cpt, par = lines
    cut = di if main else s - di + 1
    m = cpt - 1  # cpt a power of two: no division a row
    if (i & m) == 0:
        hk = H[par, i // cpt]
        for dj in range(s + 1):
            hk[j0 + dj] = max(hk[j0 + dj], _field_err(row[dj], b1, g1, b2, g2, dj, cut))
    if (j0 & m) == 0:
        l0 = j0 // cpt
        V[par, l0, i] = max(V[par, l0, i], _field_err(row[0], b1, g1, b2, g2, np.int64(0),
                                                       cut))  # int64: one signature
    if ((j0 + s) & m) == 0:
        l1 = (j0 + s) // cpt
        V[par, l1, i] = max(V[par, l1, i], _field_err(row[s], b1, g1, b2, g2, s, cut))


@njit(cache=True, fastmath=_FM)
def _block_sweep_field(z, cell, zc, lines):
    """:func:`_block_sweep` of an all-valid block (the same five maxima, the same bits),
    and in the same pass its cell's part of the tile-bound field (cell_field_rows_nb's
    values, all valid: their maximum, sixth; those on the tiles' lines into ``lines``,
    :func:`_field_lines`)."""
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
    tf = 0.0
    m = lines[2] - 1
    on_cols = (j0 & m) == 0 or ((j0 + s) & m) == 0  # a side on a tile column line
    on_top = (i0 & m) == 0  # the top row on a tile row line
    on_bottom = ((i0 + s) & m) == 0
    for di in range(s + 1):
        row = z[i0 + di, j0:j0 + s + 1]
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
        for dj in range(lo):
            zz = row[dj]
            a = max(a, abs(zz - (b1 + g1 * dj)))
            q = max(q, abs(zz - (bl + kl * dj)))
        ml = max(ml, q)
        q = 0.0
        # the middle segment; in the lower half without its diagonal sample (main: its
        # last, else its first), which δ and the field take on different planes
        m0 = lo if (upper or main) else lo + 1
        m1 = hi if (upper or not main) else hi - 1
        for dj in range(m0, m1 + 1):
            zz = row[dj]
            a = max(a, abs(zz - (bm + gm * dj)))
            q = max(q, abs(zz - (bq + gq * dj)))
        ed = 0.0
        ef = 0.0
        if not upper:
            dd = hi if main else lo
            zz = row[dd]
            q = max(q, abs(zz - (bq + gq * dd)))
            ed = abs(zz - (bm + gm * dd))
            ef = _field_err(zz, b1, g1, b2, g2, dd, di if main else s - di + 1)
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
        mc = max(mc, max(a, ed))
        tf = max(tf, max(a, ef))
        ml = max(ml, abs(row[lo] - (bl + kl * lo)))
        mr = max(mr, abs(row[hi] - (br - kr * hi)))
        if on_cols or (di == 0 and on_top) or (di == s and on_bottom):
            _field_lines(row, i0 + di, j0, s, di, main, b1, g1, b2, g2, lines)
    return mc, ml, mr, mt, mb, tf


@parallel_kernel(cache=True, nogil=True)
def _raw_delta_fields_nb(z, span, cpt, smax, P, H, V):
    """:func:`_raw_delta_nb` of an all-valid grid (the same values), and the tile-bound
    field of every level whose cells (side s = 2h, 4 ≤ s ≤ ``smax`` ≤ ``cpt``) lie in the
    level-0 tiles of side ``cpt``, made in δ's centre sweep (:func:`_block_sweep_field`):
    level L = log2(s)'s cells' maxima into P[L − 2, cell row, tile column], its samples
    on the tiles' row lines into H[L − 2, parity of the cell row, line, column], on their
    column lines into V[L − 2, parity, line, row] (two parities: cells of adjacent rows
    share a row of samples; each element is written by one row of cells). Level 1 (cells
    of side 2, whose δ is a closed form on 5 of their 9 samples) is not made here: its
    field a cell at a time cost more than the field's own kernel (0.27 against 0.10 s of
    CPU for δ's h = 1 pass with it, 4097² fBm; that kernel's level 1 is 0.16 s)."""
    R, C = z.shape
    out = np.zeros((R, C), np.float32)
    QL = np.empty((max((R - 1) // 4, 1), max((C - 1) // 4, 1)))
    QR = np.empty_like(QL)
    QT = np.empty_like(QL)
    QB = np.empty_like(QL)
    vb = np.ones((1, 1), np.uint8)  # never read: every diamond is all valid
    h = np.int64(1)
    lev = -1  # P, H and V's level index: L − 2
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        field = 2 < s <= smax
        for bi in prange(nr):
            lines = (H[lev], V[lev], cpt, bi & 1) if field else (H[0], V[0], cpt, 0)
            for bj in range(nc):
                ci = bi * s + h
                cj = bj * s + h
                main = main_diagonal_nb(bi, bj)
                if h == 1:
                    m = _centre1(z, ci, cj, main)
                else:
                    i0 = bi * s
                    j0 = bj * s
                    cell = Cell(i0, j0, s, main, z[i0, j0], z[i0, j0 + s], z[i0 + s, j0],
                                z[i0 + s, j0 + s])
                    if field:
                        m, ml, mr, mt, mb, t = _block_sweep_field(z, cell, z[ci, cj], lines)
                        tj = j0 // cpt
                        P[lev, bi, tj] = max(P[lev, bi, tj], t)
                    else:
                        m, ml, mr, mt, mb = _block_sweep_part(z, cell, z[ci, cj], 0, s, 0)
                    QL[bi, bj] = ml
                    QR[bi, bj] = mr
                    QT[bi, bj] = mt
                    QB[bi, bj] = mb
                out[ci, cj] = round_up32(m)
        for typ in range(2):
            rows = typ == 0
            na = nr if rows else nr + 1
            nb = nc + 1 if rows else nc
            lim = C if rows else R
            for a in prange(na):
                for b in range(nb):
                    ic = h + a * s if rows else a * s
                    jc = b * s if rows else h + b * s
                    if rows:
                        flo = 1 if jc > 0 else 0
                        fhi = 1 if jc < C - 1 else 0
                    else:
                        flo = 1 if ic > 0 else 0
                        fhi = 1 if ic < R - 1 else 0
                    if h >= 2 and rows:
                        qlo = QR[a, b - 1] if flo else 0.0
                        qhi = QL[a, b] if fhi else 0.0
                    elif h >= 2:
                        qlo = QB[a - 1, b] if flo else 0.0
                        qhi = QT[a, b] if fhi else 0.0
                    else:
                        qlo = qhi = 0.0
                    out[ic, jc] = edge_delta_nb(z, vb, ic, jc, h, rows, lim, 0,
                                                Beside(flo, fhi, qlo, qhi), out[ic, jc])
        h *= 2
        lev += 1
    return out


def _raw_delta(zf: np.ndarray, valid: np.ndarray, span: int | None = None) -> np.ndarray:
    span = zf.shape[0] - 1 if span is None else span
    all_valid = bool(valid.all())
    vb = valid.view(np.uint8)
    bs = np.ones((1, 1), np.uint8) if all_valid else _block_status_nb(vb, span)
    return _raw_delta_nb(zf, vb, bs, all_valid, span)



def vertex_errors(z: np.ndarray, valid: np.ndarray, span: int | None = None) -> np.ndarray:
    """Exact, saturated per-vertex errors δ, float32 (N, N) rounded up (or of a root
    grid's extent, roots of side ``span``: see the module's docstring).

    δ(v) = max over the valid full-resolution samples of v's closed diamond of |z − S|, S
    being the two diamond triangles drawn while v is absent (seed 002 §2.3, but the exact
    maximum, not the midpoint error); +inf if the diamond mixes valid and invalid samples,
    0 if it is all invalid; then saturated so δ(parent) ≥ δ(child) (§2.4, L46). The
    domain corners get 0. Computed by a compiled kernel in O(N² log N).

    Parameters
    ----------
    z : (N, N) float64 heights in scene units, N = 2**n + 1 (invalid values ignored).
    valid : (N, N) bool.
    span : None for the square; a root grid's root side 2**n, ``z`` and ``valid`` then
        (ry·2**n + 1, rx·2**n + 1).

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> d = vertex_errors(z, np.ones((3, 3), bool))
    >>> d.dtype, float(d[1, 1]), float(d[0, 1])
    (dtype('float32'), 2.0, 0.0)
    >>> z = np.zeros((3, 5)); z[1, 3] = 2.0  # the second of 2 × 1 roots of side 2
    >>> vertex_errors(z, np.ones((3, 5), bool), span=2)[1].tolist()
    [0.0, 0.0, 0.0, 2.0, 0.0]
    """
    zf, valid, n = check_grid(z, valid, span)
    with cores_for(zf.size):  # small grids on one thread (geoterrain/core/threads.py)
        return _saturate_pull_nb(_raw_delta(zf, valid, 1 << n), 1 << n)


def vertex_errors_fields(z: np.ndarray, valid: np.ndarray, span: int | None = None,
                         t: int = 6) -> tuple[np.ndarray, dict | None]:
    """:func:`vertex_errors`, and on an all-valid grid the tile-bound fields of the levels
    L ≥ 2 whose cells lie in the level-0 tiles (tiles of side 2**t samples), made in the
    same sweep: {L: (bm, hl, vl)} as :func:`geoterrain.bounds.tilebounds.tile_and_block_errors`
    reduces each level's field (the max over each level-0 tile's closed footprint, over its
    top line, over its left line), to pass to it as ``fields``; None where the grid holds
    an invalid sample (each has its own path there).

    Examples
    --------
    >>> z = np.random.default_rng(1).normal(size=(17, 17)); ok = np.ones((17, 17), bool)
    >>> d, fields = vertex_errors_fields(z, ok, t=2)
    >>> bool(np.array_equal(d, vertex_errors(z, ok))), sorted(fields), fields[2][0].shape
    (True, [2], (4, 4))
    """
    zf, valid, n = check_grid(z, valid, span)
    S = 1 << n
    te = min(t, n)
    cpt = 1 << te  # level-0 tile side in samples (tilebounds.tile_and_block_errors's)
    smax = min(cpt, 1 << (n - te))  # the largest cell of a level held in those tiles
    if smax < 4 or not valid.all():
        with cores_for(zf.size):
            return _saturate_pull_nb(_raw_delta(zf, valid, S), S), None
    R, C = zf.shape
    nl = smax.bit_length() - 1  # levels 2 … nl (level 1: tilebounds' own kernel)
    nbr, nbc = (R - 1) // cpt, (C - 1) // cpt
    k = max(nl - 1, 1)
    P = np.zeros((k, (R - 1) // 4, nbc))
    H = np.zeros((k, 2, nbr + 1, C))
    V = np.zeros((k, 2, nbc + 1, R))
    with cores_for(zf.size):  # small grids on one thread (geoterrain/core/threads.py)
        d = _saturate_pull_nb(_raw_delta_fields_nb(zf, S, cpt, smax, P, H, V), S)
    fields = {}
    for L in range(2, nl + 1):
        s = 1 << L
        Hl = H[L - 2].max(axis=0)  # (lines, C): the field on each tile row line
        Vl = V[L - 2].max(axis=0)  # (lines, R): on each tile column line
        hl = np.maximum(Hl[:, :-1].reshape(nbr + 1, nbc, cpt).max(axis=2), Hl[:, cpt::cpt])
        vl = np.maximum(Vl[:, :-1].reshape(nbc + 1, nbr, cpt).max(axis=2), Vl[:, cpt::cpt]).T
        own = P[L - 2, :(R - 1) // s].reshape(nbr, cpt // s, nbc).max(axis=1)
        # a tile's closed footprint: its own cells, and its border lines' samples, which
        # the cells beside it hold too (a maximum: exact)
        bm = np.maximum(np.maximum(own, np.maximum(hl[:-1], hl[1:])),
                        np.maximum(vl[:, :-1], vl[:, 1:]))
        fields[L] = (bm, hl, np.ascontiguousarray(vl))
    return d, fields


# ------------------------------------------------------------- a check on read
@njit(cache=True, nogil=True)
def _below_own_error_nb(d, z, valid):
    """Flat index of the first vertex whose δ is below its own error (|z_v − the mean of
    its split edge's ends|), or −1. A centre vertex takes the smaller of its two
    diagonals' (the union-jack parity depends on the tile's place); only vertices whose
    corners are all valid are checked (a mixed diamond's δ is +inf)."""
    T = d.shape[0]
    h = 1
    while h < T - 1:
        for i in range(0, T, h):
            for j in range(0, T, h):
                oi = (i // h) & 1
                oj = (j // h) & 1
                if oi + oj == 0 or not valid[i, j]:
                    continue
                zv = z[i, j]
                if oi + oj == 2:  # the centre of a 2h block
                    if not (valid[i - h, j - h] and valid[i + h, j + h]
                            and valid[i - h, j + h] and valid[i + h, j - h]):
                        continue
                    a, b = z[i - h, j - h], z[i + h, j + h]
                    c, e = z[i - h, j + h], z[i + h, j - h]
                    err = min(abs(zv - 0.5 * (a + b)), abs(zv - 0.5 * (c + e)))
                    mag = abs(a) + abs(b) + abs(c) + abs(e)
                else:  # the midpoint of a row or column edge
                    if oi:
                        a, b, ok = z[i - h, j], z[i + h, j], valid[i - h, j] and valid[i + h, j]
                    else:
                        a, b, ok = z[i, j - h], z[i, j + h], valid[i, j - h] and valid[i, j + h]
                    if not ok:
                        continue
                    err = abs(zv - 0.5 * (a + b))
                    mag = abs(a) + abs(b)
                # float64 rounding of the two computations of the same error
                if d[i, j] < err - 1e-12 * (mag + abs(zv)) - 1e-300:
                    return i * T + j
        h *= 2
    return -1


def below_own_error(delta: np.ndarray, z: np.ndarray, valid: np.ndarray
                    ) -> tuple[int, int] | None:
    """The first vertex (i, j) of a tile whose δ is below its own error, or None.

    δ(v) is the largest error over v's diamond (seed 002 §2.3), which holds v itself:
    |z_v − (z_a + z_b) / 2| for its split edge (a, b). A δ table swapped with another
    tile's, or edited, fails this on almost any terrain that is not flat, which checksums
    alone (anyone can recompute them) cannot see.

    Examples
    --------
    >>> z = np.array([[0.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    >>> ok = np.ones((3, 3), bool)
    >>> d = vertex_errors(z, ok)
    >>> below_own_error(d, z, ok) is None, below_own_error(d * 0, z, ok)
    (True, (1, 1))
    """
    k = int(_below_own_error_nb(np.ascontiguousarray(delta), np.ascontiguousarray(z, np.float64),
                                np.ascontiguousarray(valid, np.bool_)))
    return None if k < 0 else divmod(k, delta.shape[1])


@njit(cache=True, nogil=True)
def _finite_max_nb(a):
    m = 0.0
    for v in a.ravel():
        if np.isfinite(v) and v > m:
            m = v
    return m


def delta_max_finite(delta: np.ndarray) -> float:
    """The largest finite δ, or 0 (the store's ``delta_max_finite``), without copying
    the finite values.

    Examples
    --------
    >>> delta_max_finite(np.array([0.5, np.inf, 2.0, np.nan], np.float32))
    2.0
    """
    return float(_finite_max_nb(delta))  # a float32 value is exact in float64

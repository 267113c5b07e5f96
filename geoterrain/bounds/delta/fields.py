"""δ and the tile-bound fields in one sweep (:func:`vertex_errors_fields`): on an
all-valid grid, δ's centre sweep of each union-jack cell also makes the cell's part of the
tile-bound field of its level (:mod:`geoterrain.bounds.tilebounds`)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta.exact import (  # vertex_errors: the doctest's
    _raw_delta,
    _saturate_pull_nb,
    vertex_errors,  # noqa: F401
)
from geoterrain.bounds.delta.grid import check_grid
from geoterrain.bounds.delta.sweeps import (
    _FM,
    Beside,
    Cell,
    _block_sweep_part,
    _centre1,
    cell_rows_nb,
    edge_delta_nb,
)
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import cores_for, parallel_kernel

__all__ = ["vertex_errors_fields"]


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

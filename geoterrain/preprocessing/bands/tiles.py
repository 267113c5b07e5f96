"""The tile table's bounds of a grid read in row bands (issue 12's streaming preprocess;
the whole-grid twin is :func:`geoterrain.bounds.tilebounds.tile_and_block_errors`).

Every value is a maximum, minimum or count over a tile's closed footprint, so each band
adds its rows. The error field E of level L (|z − S_L| over the all-valid triangles of
the cells of side s = 2**L, seed 000's uniform surface) needs each cell's validity
first:

- **fine levels** (s ≤ band): a band's window holds every cell its rows touch (a halo of
  the largest fine cell's side above), so the cell is counted there;
- **coarse levels** (s > band): a first pass counts each cell's valid samples per
  triangle row by row, and reads the corners every ``band`` samples.

Then each band sweeps E on its own rows (:func:`~geoterrain.bounds.tilebounds.cell_field_rows_nb`,
the whole-grid kernel's rows) and reduces it into the tiles' errors, border errors and
GeoMipMapping blocks' δ_n (seed 000 §2.4); level 0's boxes and every level's footprint
counts come from the same rows. The table is the whole-grid one, bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import Cell
from geoterrain.bounds.tilebounds import (
    TileBounds,
    TileTable,
    cell_counts_nb,
    cell_field_rows_nb,
    cell_status_nb,
    tile_rows,
    tile_table,
)
from geoterrain.codec.pyramid import pyramid_shape
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.threads import parallel_kernel
from geoterrain.preprocessing.bands.delta import BandWindow, grid_shape

__all__ = ["band_tile_bounds"]

Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


class CellCounts(NamedTuple):
    """A coarse level's valid samples per cell, counted by the first pass: in the closed
    cell ``tot``, in its first triangle ``c1`` and its second ``c2`` (each with the
    diagonal)."""

    tot: np.ndarray
    c1: np.ndarray
    c2: np.ndarray


class MixedMarks(NamedTuple):
    """Where a level's cells mix valid and invalid samples, marked on its tiles
    (``tiles``), on the tiles whose border cells mix (``borders``) and on level 0's
    GeoMipMapping blocks (``blocks``); ``cpt`` cells a tile side, ``cb`` cells a block
    side (0: no blocks at this level)."""

    tiles: np.ndarray
    borders: np.ndarray
    blocks: np.ndarray
    cpt: int
    cb: int


@parallel_kernel(cache=True)
def _coarse_counts_nb(v, w0, r_lo, r_hi, s, counts):
    # add rows r_lo … r_hi of v (rows from w0) to each cell's valid counts (CellCounts):
    # the closed cell, its first triangle (with the diagonal) and its second (with the
    # diagonal)
    tot = counts.tot  # one by one (see bounds.tileblobs._level_payloads)
    c1 = counts.c1
    c2 = counts.c2
    nbr, nb = tot.shape
    for bj in prange(nb):
        j0 = bj * s
        for r in range(r_lo, r_hi + 1):
            row = v[r - w0]
            for bi in range(max(0, (r - 1) // s), min(nbr - 1, r // s) + 1):
                di = r - bi * s
                main = main_diagonal_nb(bi, bj)
                a = 0
                f = 0
                g = 0
                for dj in range(s + 1):
                    x = row[j0 + dj]
                    a += x
                    first = dj >= di if main else di + dj <= s
                    both = dj == di if main else di + dj == s
                    if first or both:
                        f += x
                    if (not first) or both:
                        g += x
                tot[bi, bj] += a
                c1[bi, bj] += f
                c2[bi, bj] += g


@parallel_kernel(cache=True)
def _level_rows_nb(band, s, coarse, counts, zd, E, marks):
    """E of level s on the ``band``'s rows r0 … r_end (:class:`BandWindow`: z, v, E hold
    rows from w0; a coarse level's cells counted in ``counts``, :class:`CellCounts`, its
    corners from ``zd``, every B samples), and the mixed cells' ``marks``
    (:class:`MixedMarks`)."""
    nb = (band.v.shape[1] - 1) // s
    bi_lo = max(0, (band.r0 - 1) // s)  # cells with a row in r0 … r_end
    bi_hi = min((band.R - 1) // s - 1, band.r_end // s)
    for parity in range(2):  # even columns of cells, then odd: no thread shares a column
        for kb in prange((nb - parity + 1) // 2):
            bj = 2 * kb + parity
            _level_cells(band, s, coarse, counts, zd, E, marks, bi_lo, bi_hi, bj)


@njit(cache=True, nogil=True)
def _level_cells(band, s, coarse, counts, zd, E, marks, bi_lo, bi_hi, bj):
    # one column bj of cells of _level_rows_nb
    z, v, w0, r0, r_end, dB = band.z, band.v, band.w0, band.r0, band.r_end, band.B
    tot, c1, c2 = counts
    tmix, bmix, kmix, cpt, cb = marks
    t1 = (s + 1) * (s + 2) / 2.0  # samples of a closed triangle (with the diagonal)
    for bi in range(bi_lo, bi_hi + 1):
        main = main_diagonal_nb(bi, bj)
        if coarse:
            n_all, k1, n1, k2, n2 = tot[bi, bj], c1[bi, bj], t1, c2[bi, bj], t1
        else:
            n_all, k1, n1, k2, n2 = cell_counts_nb(v, bi * s - w0, bj * s, s, main)
        skip, whole, ok1, ok2, mix = cell_status_nb((n_all, k1, n1, k2, n2), s)
        if mix:
            tmix[bi // cpt, bj // cpt] = True
            if bi % cpt in (0, cpt - 1) or bj % cpt in (0, cpt - 1):
                bmix[bi // cpt, bj // cpt] = True
            if cb:
                kmix[bi // cb, bj // cb] = True
        if skip:
            continue
        if coarse:
            k = s // dB
            z00, z01 = zd[bi * k, bj * k], zd[bi * k, bj * k + k]
            z10, z11 = zd[bi * k + k, bj * k], zd[bi * k + k, bj * k + k]
        else:
            i = bi * s - w0
            z00, z01 = z[i, bj * s], z[i, bj * s + s]
            z10, z11 = z[i + s, bj * s], z[i + s, bj * s + s]
        d0 = max(0, r0 - bi * s)
        d1 = min(s, r_end - bi * s)
        cell_field_rows_nb(z, Cell(bi * s - w0, bj * s, s, main, z00, z01, z10, z11), whole,
                           ok1, ok2, d0, d1, E)


def _closed_cols(a: np.ndarray, S: int, op) -> np.ndarray:
    # op over each row's closed column blocks [x S, (x + 1) S]: (rows, nt)
    nt = (a.shape[1] - 1) // S
    r = op.reduce(a[:, :-1].reshape(len(a), nt, S), axis=2)
    return op(r, a[:, S::S])


def _into_rows(acc: np.ndarray, per_row: np.ndarray, r0: int, S: int, op) -> None:
    # op each row r (from r0) into the closed footprints' rows y with y S ≤ r ≤ (y + 1) S
    rows = np.arange(r0, r0 + len(per_row))
    nt = acc.shape[0]
    for y in np.unique(np.concatenate([rows // S, (rows - 1) // S])):
        if 0 <= y < nt:
            m = (rows >= y * S) & (rows <= (y + 1) * S)
            if m.any():
                acc[y] = op(acc[y], op.reduce(per_row[m], axis=0))


def band_tile_bounds(rows: Rows, N: int | tuple[int, int], t: int, xs: np.ndarray,
                     ys: np.ndarray, band: int = 256, xy: Rows | None = None,
                     span: int | None = None, table: bool = False
                     ) -> tuple[dict[tuple[int, int, int], TileBounds] | TileTable, np.ndarray]:
    """:func:`~geoterrain.bounds.tilebounds.tile_and_block_errors` of the grid that
    ``rows(i0, i1)`` → (scene heights, valid) hands out, ``band`` rows (a power of two)
    at a time; ``xs``, ``ys``: scene x of each column and y of each row (a projected or
    pixel frame), or on a curvilinear (geographic) grid ``xy(i0, i1)`` → the rows'
    scene X, Y. ``span``: a root grid's root side, ``N`` then its extent (R, C)
    (``tile_and_block_errors`` with ``span``: its tiles and blocks over the extent).
    ``table``: the tiles as a :class:`~geoterrain.bounds.tilebounds.TileTable` (arrays),
    not a dict (the streaming preprocess: memory that does not grow by a Python object
    per tile).

    Examples
    --------
    >>> from geoterrain.bounds.tilebounds import tile_and_block_errors
    >>> z = np.random.default_rng(4).normal(size=(17, 17)).cumsum(0)
    >>> v = np.ones((17, 17), bool); v[3, 5] = False
    >>> xs = ys = np.arange(17.0)
    >>> X, Y = np.meshgrid(xs, -ys)
    >>> a = band_tile_bounds(lambda i, j: (z[i:j], v[i:j]), 17, 2, xs, -ys, band=2)
    >>> b = tile_and_block_errors(z, v, X, Y, 2)
    >>> a[0] == b[0], bool(np.array_equal(a[1], b[1]))
    (True, True)
    >>> c = band_tile_bounds(lambda i, j: (z[i:j], v[i:j]), 17, 2, xs, -ys, band=2, table=True)
    >>> c[0].to_dict() == b[0]
    True
    """
    if band < 2 or band & (band - 1):
        raise ValueError(f"band must be a power of two ≥ 2, got {band}")
    NR, NC = grid_shape(N)
    S0 = NR - 1 if span is None else span
    n, te = pyramid_shape(S0 + 1, t)
    lmax = n - te
    cpt = 1 << te
    nb0r, nb0c = (NR - 1) // cpt, (NC - 1) // cpt
    B = min(band, S0)
    nbands = (NR - 1) // B
    xs = np.asarray(xs, np.float64)
    ys = np.asarray(ys, np.float64)

    def window(i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
        # bounds.check_grid's rules: non-finite heights invalid, invalid heights 0
        z, v = rows(i0, i1)
        z = np.asarray(z, np.float64)
        v = np.asarray(v, bool) & np.isfinite(z)
        return np.ascontiguousarray(np.where(v, z, 0.0)), np.ascontiguousarray(v)

    # first pass: the coarse levels' cell counts, and the grid every B samples
    coarse = {L: CellCounts(np.zeros(((NR - 1) >> L, (NC - 1) >> L), np.int64),
                            np.zeros(((NR - 1) >> L, (NC - 1) >> L)),
                            np.zeros(((NR - 1) >> L, (NC - 1) >> L)))
              for L in range(1, lmax + 1) if (1 << L) > B}
    zd = np.zeros((nbands + 1, (NC - 1) // B + 1))
    for k in range(nbands):
        r0 = k * B
        last = k == nbands - 1
        z, v = window(r0, r0 + B + 1)
        zd[k] = z[0, ::B]
        if last:
            zd[k + 1] = z[B, ::B]
        vb = v.view(np.uint8)
        for L, cells in coarse.items():
            _coarse_counts_nb(vb, r0, r0, r0 + B if last else r0 + B - 1, 1 << L, cells)
    nts = [((NR - 1) >> (te + L), (NC - 1) >> (te + L)) for L in range(lmax + 1)]
    err = [np.zeros(m) for m in nts]
    bnd = [np.zeros(m) for m in nts]
    tmix = [np.zeros(m, bool) for m in nts]
    bmix = [np.zeros(m, bool) for m in nts]
    nblk = min(te, lmax) + 1
    blocks = np.zeros((nb0r, nb0c, nblk))
    kmix = np.zeros((nb0r, nb0c, nblk), bool)
    counts = [np.zeros(m, np.int64) for m in nts]
    box0 = np.empty((6, nb0r, nb0c))
    box0[0::2] = np.inf
    box0[1::2] = -np.inf
    # a fine cell with a row in the band starts at most its side above it: the window's
    # halo is the largest fine side, not a band (coarse cells read the band's rows only)
    halo = min(B, 1 << lmax)
    for k in range(nbands):
        r0 = k * B
        r_end = NR - 1 if k == nbands - 1 else r0 + B - 1
        w0 = max(0, r0 - halo)
        z, v = window(w0, min(NR, r0 + B + 1))
        core = slice(r0 - w0, r_end - w0 + 1)
        vc = v[core]
        # footprint counts of every level, and level 0's boxes
        cs = np.zeros((len(vc), NC + 1), np.int64)
        np.cumsum(vc, axis=1, out=cs[:, 1:])
        for L, (_, m) in enumerate(nts):
            S = cpt << L
            _into_rows(counts[L], cs[:, S + 1::S] - cs[:, :-1:S][:, :m], r0, S, np.add)
        cs = None  # (a band's int64 row sums: 8.4 MB at 2^20 samples a band)
        zc = z[core]
        if not vc.any():  # each box term below would be its fill: x, y not read
            gx = gy = None
        elif xy is None:
            gx, gy = xs[None, :], ys[r0:r_end + 1, None]
        else:
            gx, gy = (np.asarray(a, np.float64) for a in xy(r0, r_end + 1))
        boxes = () if gx is None else ((np.minimum, np.inf, 0), (np.maximum, -np.inf, 1))
        for op, fill, sl in boxes:  # level 0's boxes: z, x, y of the valid samples
            _into_rows(box0[sl], _closed_cols(np.where(vc, zc, fill), cpt, op), r0, cpt, op)
            _into_rows(box0[2 + sl], _closed_cols(np.where(vc, gx, fill), cpt, op),
                       r0, cpt, op)
            _into_rows(box0[4 + sl], _closed_cols(np.where(vc, gy, fill), cpt, op), r0, cpt,
                       op)
        # every level's error field on this band's rows, reduced into its tiles
        E = np.zeros(z.shape)
        band = BandWindow(z, v.view(np.uint8), w0, r0, r_end, B, NR, NC)
        for L in range(1, lmax + 1):
            s = 1 << L
            S = cpt << L
            E[:] = 0.0
            cells = coarse.get(L, CellCounts(np.zeros((0, 0), np.int64), np.zeros((0, 0)),
                                             np.zeros((0, 0))))
            cb = (1 << (te - L)) if L < nblk else 0
            _level_rows_nb(band, s, L in coarse, cells, zd, E,
                           MixedMarks(tmix[L], bmix[L], kmix[..., L if cb else 0], cpt, cb))
            Ec = E[core]
            _into_rows(err[L], _closed_cols(Ec, S, np.maximum), r0, S, np.maximum)
            if cb:
                blk = blocks[..., L].copy()
                _into_rows(blk, _closed_cols(Ec, cpt, np.maximum), r0, cpt, np.maximum)
                blocks[..., L] = blk
            # border lines: rows y S (whole), and columns x S on the rows of tile y
            rws = np.arange(r0, r_end + 1)
            on = rws % S == 0
            if on.any():
                lines = _closed_cols(Ec[on], S, np.maximum)
                for r, line in zip(rws[on], lines, strict=True):
                    for y in (r // S - 1, r // S):
                        if 0 <= y < nts[L][0]:
                            np.maximum(bnd[L][y], line, out=bnd[L][y])
            colv = Ec[:, ::S]
            _into_rows(bnd[L], np.maximum(colv[:, :-1], colv[:, 1:]), r0, S, np.maximum)
        # this band's arrays go before the next band's are read
        z = v = vc = zc = cs = gx = gy = E = Ec = colv = band = None
    per_level = []
    for L in range(lmax + 1):
        e = np.where(tmix[L], np.inf, err[L])
        b = np.where(bmix[L], np.inf, bnd[L])
        per_level.append((e, b))
        if 0 < L < nblk:
            blocks[..., L] = np.where(kmix[..., L], np.inf, blocks[..., L])
    return (tile_table if table else tile_rows)(per_level, box0, counts), blocks

"""Per-tile error bounds and boxes of the stored pyramid (the store's tile table).

For every stored tile ``(L, x, y)`` (docs/conventions.md): the max vertical error of the
level-L union-jack surface over the tile's footprint, the same on its border lines (what
a skirt must cover), and the box of its valid samples. Invalid samples are handled as in
:mod:`geoterrain.bounds.delta`: never read, and a triangle mixing valid and invalid samples
makes the bound +inf. The GeoMipMapping blocks' δ_n (:func:`tile_and_block_errors`) are
stored as one blob, :func:`pack_block_errors` / :func:`unpack_block_errors`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import Cell, cell_rows_nb, check_grid
from geoterrain.core import zstdsafe
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.grid import footprint_counts
from geoterrain.core.rounding import round_up
from geoterrain.core.threads import cores_for, parallel_kernel

__all__ = ["TileBounds", "TileTable", "pack_block_errors", "tile_and_block_errors", "tile_errors",
           "tile_table", "unpack_block_errors"]


def closed_blocks(a: np.ndarray, s: int, op, dtype=None) -> np.ndarray:
    """``op``-reduction of ``a`` over the closed blocks ``[p*s : (p+1)*s + 1]`` (shared
    borders), separably: rows, then columns. Returns (blocks down, blocks across)."""
    R, C = a.shape[:2]
    nbr, nbc = (R - 1) // s, (C - 1) // s
    r = op.reduce(a[:-1].reshape(nbr, s, C), axis=1, dtype=dtype)
    r = op(r, a[s::s])
    c = op.reduce(r[:, :-1].reshape(nbr, nbc, s), axis=2)
    return op(c, r[:, s::s])


class TileBounds(NamedTuple):
    """Bounds of one stored tile, in the column order of the store's tile table."""

    nvalid: int
    zmin: float
    zmax: float
    error: float
    boundary_error: float
    xmin: float
    xmax: float
    ymin: float
    ymax: float


@parallel_kernel(cache=True, nogil=True)
def _level_field_nb(z, vf, s, E, all_valid=False):
    # E = max over the all-valid closed triangles containing a sample of |z − S_L| (0 if
    # none), S_L the union-jack surface of cell size s; and per cell whether one of its
    # two closed triangles mixes valid and invalid samples. Rows of cells run on every
    # core, even rows then odd ones, so no two threads share a row of E (a max: the
    # order does not change it). ``all_valid``: every sample is (vf is then not read).
    nbr, nbc = (z.shape[0] - 1) // s, (z.shape[1] - 1) // s  # a root grid's rectangle too
    E[:, :] = 0.0
    mixed = np.zeros((nbr, nbc), np.bool_)
    for parity in range(2):
        for k in prange((nbr - parity + 1) // 2):
            _level_field_row(z, vf, s, E, mixed, 2 * k + parity, all_valid)
    return mixed


@njit(cache=True, nogil=True)
def _level_field_row(z, vf, s, E, mixed, bi, all_valid):
    # one row bi of cells of _level_field_nb
    nb = (z.shape[1] - 1) // s
    for bj in range(nb):
        i0 = bi * s
        j0 = bj * s
        main = main_diagonal_nb(bi, bj)
        whole = ok1 = ok2 = True
        if not all_valid:
            skip, whole, ok1, ok2, mix = cell_status_nb(cell_counts_nb(vf, i0, j0, s, main), s)
            mixed[bi, bj] = mix
            if skip:
                continue
        cell_field_rows_nb(z, Cell(i0, j0, s, main, z[i0, j0], z[i0, j0 + s], z[i0 + s, j0],
                                   z[i0 + s, j0 + s]), whole, ok1, ok2, 0, s, E)


@parallel_kernel(cache=True, nogil=True)
def _level_blocks_nb(z, vf, s, cpt, all_valid, bm, hl, vl, mixed):
    """_level_field_nb's field E reduced where it is made, a band of blocks at a time
    (blocks: closed squares of ``cpt`` cells of side 1, the level-0 tiles), never held
    whole: ``bm[bi, bj]`` the max of E over block (bi, bj)'s closed footprint
    (:func:`closed_blocks` of E), ``hl[bi, bj]`` over its top line (row bi·cpt, columns
    bj·cpt … (bj + 1)·cpt; ``hl[nbr]`` the last row's), ``vl[bi, bj]`` over its left
    line (``vl[:, nbc]`` the last column's), ``mixed`` as _level_field_nb's. Each band
    (rows r0 … r0 + cpt) sweeps the rows of every cell of side s that holds one of them
    into a field of its own (the cells above and below it: their one row on the band's
    edge), with :func:`cell_field_rows_nb`, the same values sample by sample: a maximum
    does not depend on the order. Bands run on every core."""
    R, C = z.shape
    nbr, nbc = (R - 1) // cpt, (C - 1) // cpt
    ncr, ncc = (R - 1) // s, (C - 1) // s
    for bi in prange(nbr):
        r0 = bi * cpt
        r1 = r0 + cpt
        Eb = np.zeros((cpt + 1, C))
        zb = z[r0:r1 + 1]
        for ci in range(max(0, (r0 - 1) // s), min(ncr - 1, r1 // s) + 1):
            d0 = max(0, r0 - ci * s)
            d1 = min(s, r1 - ci * s)
            i0 = ci * s
            own = r0 <= i0 < r1  # the band that holds the cell's first row marks it
            if all_valid and s == 2:  # level 1: a row of cells a sample row at a time
                _cells2_rows_nb(z, i0, r0, ci, ncc, d0, d1, Eb)
                continue
            for cj in range(ncc):
                j0 = cj * s
                main = main_diagonal_nb(ci, cj)
                whole = ok1 = ok2 = True
                if not all_valid:
                    skip, whole, ok1, ok2, mix = cell_status_nb(
                        cell_counts_nb(vf, i0, j0, s, main), s)
                    if own:
                        mixed[ci, cj] = mix
                    if skip:
                        continue
                cell_field_rows_nb(zb, Cell(i0 - r0, j0, s, main, z[i0, j0], z[i0, j0 + s],
                                            z[i0 + s, j0], z[i0 + s, j0 + s]),
                                   whole, ok1, ok2, d0, d1, Eb)
        # the band's column maxima first (element-wise over whole rows: vectorised; a
        # max does not depend on the order), then each block's from its columns
        cm = Eb[0].copy()
        for i in range(1, cpt + 1):
            ei = Eb[i]
            for j in range(C):
                cm[j] = max(cm[j], ei[j])
        for bj in range(nbc + 1):
            vl[bi, bj] = cm[bj * cpt]
        e0 = Eb[0]
        e1 = Eb[cpt]
        for bj in range(nbc):
            j0 = bj * cpt
            m = 0.0
            top = 0.0
            bottom = 0.0
            for j in range(j0, j0 + cpt + 1):
                m = max(m, cm[j])
                top = max(top, e0[j])
                bottom = max(bottom, e1[j])
            bm[bi, bj] = m
            hl[bi, bj] = top
            if bi == nbr - 1:
                hl[nbr, bj] = bottom


@njit(cache=True, nogil=True)
def _cells2_rows_nb(z, i0, r0, ci, ncc, d0, d1, Eb):
    """Rows d0 … d1 of every cell of side 2 in cell row ``ci`` (first grid row ``i0``),
    all valid, maxed into the band field ``Eb`` (its row 0 is grid row ``r0``):
    :func:`cell_field_rows_nb`'s values, a sample row across the cells at a time (no call
    and no slices a cell)."""
    inv = 1.0 / 2
    for di in range(d0, d1 + 1):
        fi = di * inv
        er = Eb[i0 + di - r0]
        zr = z[i0 + di]
        for cj in range(ncc):
            j0 = 2 * cj
            main = main_diagonal_nb(ci, cj)
            b1, g1, b2, g2 = cell_rows_nb(z[i0, j0], z[i0, j0 + 2], z[i0 + 2, j0],
                                          z[i0 + 2, j0 + 2], fi, inv, main)
            cut = di if main else 2 - di + 1
            for dj in range(3):
                if dj < cut:
                    e = abs(zr[j0 + dj] - (b1 + g1 * dj))
                else:
                    e = abs(zr[j0 + dj] - (b2 + g2 * dj))
                er[j0 + dj] = max(er[j0 + dj], e)


@njit(cache=True, nogil=True)
def cell_counts_nb(vf, i0, j0, s, main):
    """(valid samples, then valid and total samples of each closed triangle) of the closed
    cell of side s at (i0, j0) of ``vf`` (the first triangle holds the diagonal too)."""
    tot = 0
    for di in range(s + 1):  # a plain count first (vectorised): most cells are all or none
        for dj in range(s + 1):
            tot += vf[i0 + di, j0 + dj]
    if tot == 0 or tot == (s + 1) * (s + 1):  # the same values as the sweep below
        t = (s + 1) * (s + 2) / 2.0
        c = t if tot else 0.0
        return tot, c, t, c, t
    c1 = 0.0
    c2 = 0.0
    t1 = 0.0
    t2 = 0.0
    for di in range(s + 1):
        for dj in range(s + 1):
            first = dj >= di if main else di + dj <= s
            both = dj == di if main else di + dj == s
            v = np.float64(vf[i0 + di, j0 + dj])
            if first or both:
                c1 += v
                t1 += 1.0
            if (not first) or both:
                c2 += v
                t2 += 1.0
    return tot, c1, t1, c2, t2


@njit(cache=True, nogil=True)
def cell_status_nb(counts, s):
    """What a cell's :func:`cell_counts_nb` say of its part of a level's field, as
    (skip, whole, ok1, ok2, mixed): ``whole`` every sample valid, ``ok1`` / ``ok2`` its
    first / second closed triangle all valid, ``mixed`` one of them mixes valid and
    invalid samples, ``skip`` neither triangle is all valid (nothing of E to sweep).

    >>> cell_status_nb((4, 3.0, 3.0, 3.0, 3.0), 1)  # a cell of side 1, all valid
    (False, True, True, True, False)
    """
    tot, c1, t1, c2, t2 = counts
    whole = tot == (s + 1) * (s + 1)
    ok1 = c1 == t1
    ok2 = c2 == t2
    mixed = (not whole) and ((0.0 < c1 < t1) or (0.0 < c2 < t2))
    return not (whole or ok1 or ok2), whole, ok1, ok2, mixed


@njit(cache=True, nogil=True)
def cell_field_rows_nb(z, cell, whole, ok1, ok2, d0, d1, E):
    """Rows d0 … d1 (cell-relative) of one cell's part of _level_field_nb's E: |z − S_L|
    on the samples of its all-valid triangles (every sample if ``whole``; else of the
    first if ``ok1``, of the second if ``ok2``), maxed into E (E and z share their row
    numbering; ``cell``: :class:`~geoterrain.bounds.delta.Cell`, its corners given)."""
    i0, j0, s, main, z00, z01, z10, z11 = cell
    inv = 1.0 / s
    if whole:  # all valid: split each row at the diagonal
        for di in range(d0, d1 + 1):
            i = i0 + di
            fi = di * inv
            b1, g1, b2, g2 = cell_rows_nb(z00, z01, z10, z11, fi, inv, main)
            cut = di if main else s - di + 1
            # the row as two slices and a plain max (no conditional store, no index
            # arithmetic per sample: the loops vectorise); z and E are finite here
            zr = z[i, j0:j0 + s + 1]
            er = E[i, j0:j0 + s + 1]
            for dj in range(cut):
                er[dj] = max(er[dj], abs(zr[dj] - (b1 + g1 * dj)))
            for dj in range(cut, s + 1):
                er[dj] = max(er[dj], abs(zr[dj] - (b2 + g2 * dj)))
        return
    for di in range(d0, d1 + 1):
        i = i0 + di
        for dj in range(s + 1):
            j = j0 + dj
            if main:
                first = dj >= di
                both = dj == di
            else:
                first = di + dj <= s
                both = di + dj == s
            if both:
                first = ok1
            if not (ok1 if first else ok2):
                continue
            if main:
                if first:
                    S = z00 + (z01 - z00) * (dj * inv) + (z11 - z01) * (di * inv)
                else:
                    S = z00 + (z10 - z00) * (di * inv) + (z11 - z10) * (dj * inv)
            else:
                if first:
                    S = z00 + (z10 - z00) * (di * inv) + (z01 - z00) * (dj * inv)
                else:
                    S = (z11 + (z01 - z11) * ((s - di) * inv)
                         + (z10 - z11) * ((s - dj) * inv))
            e = abs(z[i, j] - S)
            if e > E[i, j]:
                E[i, j] = e


@parallel_kernel(cache=True, nogil=True)
def _tile_boxes_nb(z, x, y, vb, S):
    # Per closed tile footprint of span S: the box of the valid samples (each tile reads
    # its own footprint in raster order: the same min/max sequence as a raster sweep).
    ntr, ntc = (z.shape[0] - 1) // S, (z.shape[1] - 1) // S
    box = np.empty((6, ntr, ntc))
    for ty in prange(ntr):
        for tx in range(ntc):
            z0, z1, x0, x1, y0, y1 = np.inf, -np.inf, np.inf, -np.inf, np.inf, -np.inf
            for i in range(ty * S, ty * S + S + 1):
                for j in range(tx * S, tx * S + S + 1):
                    if vb[i, j]:
                        z0 = min(z0, z[i, j])
                        z1 = max(z1, z[i, j])
                        x0 = min(x0, x[i, j])
                        x1 = max(x1, x[i, j])
                        y0 = min(y0, y[i, j])
                        y1 = max(y1, y[i, j])
            box[0, ty, tx], box[1, ty, tx], box[2, ty, tx] = z0, z1, x0
            box[3, ty, tx], box[4, ty, tx], box[5, ty, tx] = x1, y0, y1
    return box


def _pooled(per_level: list, box0: np.ndarray) -> list[np.ndarray]:
    # each level's boxes pooled up from level 0's (a parent's closed footprint is the
    # union of its children's); the errors made monotone up the quadtree (in place)
    boxes = [box0]
    for err, _ in per_level[1:]:
        ntr, ntc = err.shape
        b4 = boxes[-1].reshape(6, ntr, 2, ntc, 2)
        box = np.empty((6, ntr, ntc))
        box[0::2] = b4[0::2].min(axis=(2, 4))
        box[1::2] = b4[1::2].max(axis=(2, 4))
        boxes.append(box)
    for L in range(1, len(per_level)):  # monotone up the quadtree
        child = per_level[L - 1][0]
        cmax = child.reshape(child.shape[0] // 2, 2, child.shape[1] // 2, 2).max(axis=(1, 3))
        np.maximum(per_level[L][0], cmax, out=per_level[L][0])
    return boxes


def tile_rows(per_level: list, box0: np.ndarray, nvalid: list
              ) -> dict[tuple[int, int, int], TileBounds]:
    """The stored tiles' :class:`TileBounds` from each level's (error, boundary error)
    arrays, level 0's boxes (6, tiles down, tiles across) and the footprint counts: boxes
    pooled up the levels (a parent's closed footprint is the union of its children's),
    errors made monotone up the quadtree (:func:`tile_table`: the same as arrays)."""
    boxes = _pooled(per_level, box0)
    out: dict[tuple[int, int, int], TileBounds] = {}
    for L, ((err, bnd), box) in enumerate(zip(per_level, boxes, strict=True)):
        nval = nvalid[L]
        ty, tx = np.nonzero(nval > 0)
        cols = (nval[ty, tx].astype(np.int64), box[0, ty, tx], box[1, ty, tx], err[ty, tx],
                bnd[ty, tx], box[2, ty, tx], box[3, ty, tx], box[4, ty, tx], box[5, ty, tx])
        # whole columns to Python ints and floats (tolist), one tuple a tile
        keys = [(L, x, y) for x, y in zip(tx.tolist(), ty.tolist(), strict=True)]
        rows = zip(*(np.asarray(c, np.float64).tolist() if k else c.tolist()
                     for k, c in enumerate(cols)), strict=True)
        out.update(zip(keys, map(TileBounds._make, rows), strict=True))
    return out


class TileTable:
    """The stored tiles' bounds as two arrays, not a dict of tuples: ``keys`` (n, 3) int64
    (L, x, y) in sorted order and ``rows`` (n, 9) float64 in :class:`TileBounds`' order
    (``nvalid`` exact). 16385² at tile size 64 has 87 381 tiles: 8.4 MB here; as
    :func:`tile_rows`' dict, held by the streamed preprocess from its tile pass to the
    store's writing, 36.5 MB traced (named tuples, Python floats, keys: 438 bytes a tile;
    docs/lab/streaming.md).

    Examples
    --------
    >>> t = TileTable.from_dict({(1, 0, 0): TileBounds(9, 0.0, 2.0, 0.5, 0.25, 0, 1, 0, 1),
    ...                          (0, 1, 0): TileBounds(4, 1.0, 2.0, 0.0, 0.0, 1, 2, 0, 1)})
    >>> t.keys.tolist(), t.bounds(1)[:4]
    ([[0, 1, 0], [1, 0, 0]], (9, 0.0, 2.0, 0.5))
    >>> TileTable.from_dict(t.to_dict()).rows.tolist() == t.rows.tolist()
    True
    """

    __slots__ = ("keys", "rows")

    def __init__(self, keys: np.ndarray, rows: np.ndarray) -> None:
        self.keys = np.asarray(keys, np.int64).reshape(-1, 3)
        self.rows = np.asarray(rows, np.float64).reshape(len(self.keys), len(TileBounds._fields))

    def __len__(self) -> int:
        return len(self.keys)

    def __getstate__(self) -> tuple:  # (a pass's result crosses to a worker process)
        return self.keys, self.rows

    def __setstate__(self, state: tuple) -> None:
        self.keys, self.rows = state

    def bounds(self, i: int) -> TileBounds:
        """Row ``i`` as a :class:`TileBounds` (``nvalid`` an int, the rest Python floats)."""
        r = self.rows[i].tolist()
        return TileBounds(int(r[0]), *r[1:])

    def to_dict(self) -> dict[tuple[int, int, int], TileBounds]:
        """:func:`tile_rows`' dict (in key order)."""
        return {tuple(k): self.bounds(i) for i, k in enumerate(self.keys.tolist())}

    @classmethod
    def from_dict(cls, d: dict) -> TileTable:
        """The table of a :func:`tile_rows` dict."""
        keys = np.array(sorted(d), np.int64).reshape(-1, 3)
        return cls(keys, np.array([d[tuple(k)] for k in keys.tolist()], np.float64))


def tile_table(per_level: list, box0: np.ndarray, nvalid: list) -> TileTable:
    """:func:`tile_rows` as a :class:`TileTable`: the same tiles and numbers, gathered
    with whole-array indexing, level by level (no Python object per tile)."""
    boxes = _pooled(per_level, box0)
    keys, rows = [], []
    for L, ((err, bnd), box) in enumerate(zip(per_level, boxes, strict=True)):
        nval = nvalid[L]
        ty, tx = np.nonzero(nval > 0)
        keys.append(np.stack([np.full(len(ty), L), tx, ty], axis=1))
        b = box[:, ty, tx].astype(np.float64)  # (6, k): zmin, zmax, xmin, xmax, ymin, ymax
        rows.append(np.stack([nval[ty, tx].astype(np.float64), b[0], b[1],
                              err[ty, tx].astype(np.float64),
                              bnd[ty, tx].astype(np.float64), b[2], b[3], b[4], b[5]], axis=1))
    k = np.concatenate(keys).astype(np.int64) if keys else np.zeros((0, 3), np.int64)
    r = np.concatenate(rows) if rows else np.zeros((0, len(TileBounds._fields)))
    order = np.lexsort((k[:, 2], k[:, 1], k[:, 0]))  # (L, x, y), sorted as tuples sort
    return TileTable(k[order], r[order])


def tile_errors(
    z: np.ndarray, valid: np.ndarray, x: np.ndarray, y: np.ndarray, t: int = 6,
    span: int | None = None,
) -> dict[tuple[int, int, int], TileBounds]:
    """Error bounds of every stored tile ``(L, x, y)`` of the pyramid (docs/conventions.md):
    the first half of :func:`tile_and_block_errors`.

    Examples
    --------
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> tb = tile_errors(I * J, np.ones((5, 5), bool), J, -I, t=1)
    >>> sorted(tb), tb[(1, 0, 0)].error, tb[(1, 0, 0)].nvalid
    ([(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 0)], 1.0, 25)
    """
    return tile_and_block_errors(z, valid, x, y, t, span)[0]


def tile_and_block_errors(
    z: np.ndarray, valid: np.ndarray, x: np.ndarray, y: np.ndarray, t: int = 6,
    span: int | None = None, counts: list[np.ndarray] | None = None,
    fields: dict | None = None,
) -> tuple[dict[tuple[int, int, int], TileBounds], np.ndarray]:
    """Error bounds of every stored tile ``(L, x, y)`` of the pyramid (docs/conventions.md),
    and every GeoMipMapping block's exact δ_n.

    Returns a dict keyed by ``(L, x, y)`` (x counts columns, y rows) of :class:`TileBounds`
    (a NamedTuple ordered like the store's tile columns) for every tile whose footprint
    holds a valid sample:

    * ``error``: max over the valid footprint samples of |z − S_L|, S_L the union-jack
      uniform surface of level L; +inf if a level-L triangle of the tile (closed, drawn or
      not) mixes valid and invalid samples (level 0 is the data itself: always 0); then
      made monotone up the quadtree (parent ≥ its children).
    * ``boundary_error``: the same max over the samples on the tile's four border lines
      (what a skirt must cover); +inf if a mixed triangle lies in a border cell.
    * ``zmin, zmax, xmin, xmax, ymin, ymax``: box of the valid footprint samples in scene
      coordinates; ``nvalid``: number of valid footprint samples (borders included).

    The second result, ``blocks`` (nb, nb, n_max + 1) indexed [y, x, n], is seed 000
    §2.4's δ_n for every level-0 tile (a GeoMipMapping block) drawn at its geomipmap n
    (the level-n union-jack surface over the block, n = 0 … min(t, top level)): the max
    over the block's valid closed-footprint samples of |z − S_n|, not made monotone, and
    +inf where a level-n triangle in the block mixes valid and invalid samples. It is the
    same field as ``error``, pooled over one block instead of a level-n tile, so it is
    exact where ``error`` of the covering tile is only an upper bound. A block without
    valid samples has 0.

    ``span``: a root grid's root side 2**n; the arrays are then the roots' extent
    (:attr:`geoterrain.core.grid.Grid.extent`), each root a pyramid of its own whose
    top level is the grid's (the blocks (down, across, n_max + 1)).
    ``counts``: :func:`geoterrain.core.grid.footprint_counts` of ``valid`` when the caller
    has them (the height codec reads them too), else computed here. ``fields``: the levels'
    fields reduced by :func:`geoterrain.bounds.delta.vertex_errors_fields` on the same ``z``,
    ``valid``, ``span`` and ``t`` (an all-valid grid, made in δ's sweep), not swept again.

    Examples
    --------
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> tb, blocks = tile_and_block_errors(I * J, np.ones((5, 5), bool), J, -I, t=1)
    >>> blocks.shape, blocks[..., 1].tolist()  # 2×2 blocks, each a 3×3 sample square
    ((2, 2, 2), [[1.0, 1.0], [1.0, 1.0]])
    """
    zf, valid, n = check_grid(z, valid, span)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    R, C = zf.shape
    te = min(t, n)
    lmax = n - te
    cpt = 1 << te  # cells per tile side
    vb = valid.view(np.uint8)
    xc, yc = x, y  # no copy: x and y may be broadcast views (Frame.grid_xy)
    nvalid = footprint_counts(valid, te, lmax) if counts is None else counts
    per_level = []
    nbr, nbc = (R - 1) // cpt, (C - 1) // cpt  # blocks (level-0 tiles) down, across
    blocks = np.zeros((nbr, nbc, min(te, lmax) + 1))
    all_valid = bool(valid.all())  # the level fields then read no mask
    with cores_for(zf.size):  # small grids' kernels on one thread (threads.py)
        for L in range(lmax + 1):
            S = 1 << (te + L)  # tile span in full-resolution samples
            ntr, ntc = (R - 1) // S, (C - 1) // S
            if L == 0:  # the data itself: E is 0 everywhere and no triangle is mixed
                z0 = np.zeros((ntr, ntc))
                per_level.append((z0, z0.copy()))
                box0 = _tile_boxes_nb(zf, xc, yc, vb, S)
                continue
            # max of E over each block (level-0 tile) and its top and left lines, where
            # the field is made; a level-L tile's closed footprint is the union of its
            # 2^L × 2^L blocks' closed ones, its border lines their lines'
            s = 1 << L
            bm, hl = np.empty((nbr, nbc)), np.empty((nbr + 1, nbc))
            vl, mixed = np.empty((nbr, nbc + 1)), np.zeros(((R - 1) // s, (C - 1) // s), bool)
            if fields is not None and L in fields:  # made in δ's sweep: every sample valid
                bm, hl, vl = fields[L]
            else:
                _level_blocks_nb(zf, vb, s, cpt, all_valid, bm, hl, vl, mixed)
            g = 1 << L
            err = bm.reshape(ntr, g, ntc, g).max(axis=(1, 3))
            m4 = mixed.reshape(ntr, cpt, ntc, cpt)
            err = np.where(m4.any(axis=(1, 3)), np.inf, err)
            if L < blocks.shape[2]:  # the same field over each block (seed 000 §2.4 δ_n)
                c = 1 << (te - L)  # level-L cells per block side
                mb = mixed.reshape(nbr, c, nbc, c).any(axis=(1, 3))
                blocks[..., L] = np.where(mb, np.inf, bm)
            rows = hl[::g].reshape(ntr + 1, ntc, g).max(axis=2)  # closed segments
            cols = vl[:, ::g].reshape(ntr, g, ntc + 1).max(axis=1)
            bnd = np.maximum(np.maximum(rows[:-1], rows[1:]), np.maximum(cols[:, :-1], cols[:, 1:]))
            border = (m4[:, 0].any(axis=2) | m4[:, -1].any(axis=2)
                      | m4[:, :, :, 0].any(axis=1) | m4[:, :, :, -1].any(axis=1))
            bnd = np.where(border, np.inf, bnd)
            per_level.append((err, bnd))
    out = tile_rows(per_level, box0, nvalid)
    return out, blocks


def pack_block_errors(blocks: np.ndarray) -> bytes:
    """Every GeoMipMapping block's δ_n (nb, nb, levels), as little-endian float32
    rounded *up* (a stored δ_n is never below the exact one; +inf stays +inf), zstd.

    Examples
    --------
    >>> b = np.array([[[0.0, 0.1, np.inf]]])
    >>> back = unpack_block_errors(pack_block_errors(b), 1, 3)
    >>> bool((back >= b).all()), back[0, 0, 2]
    (True, np.float64(inf))
    """
    a = round_up(np.asarray(blocks, np.float64), np.float32).astype("<f4")
    return zstdsafe.compress_one(np.ascontiguousarray(a).tobytes(), 6)


def unpack_block_errors(blob: bytes, nb: int | tuple[int, int], levels: int) -> np.ndarray:
    """Inverse of :func:`pack_block_errors`: (nb, nb, levels) float64, or (down, across,
    levels) with ``nb`` = (down, across) (a root grid's level-0 tiles). A store may come
    from a stranger: ``ValueError`` unless the blob decodes to exactly that many values,
    each ≥ 0 (+inf allowed, NaN not)."""
    nd, na = (nb, nb) if np.ndim(nb) == 0 else nb
    raw = zstdsafe.decompress(blob, nd * na * levels * 4, exact=True)
    a = np.frombuffer(raw, "<f4").astype(np.float64).reshape(nd, na, levels)
    if not (a >= 0).all():  # NaN fails too
        raise ValueError("a block δ_n is negative or NaN")
    return a

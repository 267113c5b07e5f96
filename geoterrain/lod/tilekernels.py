"""Compiled tile-tree kernels (numba): the coarsest tile holding a sample, the tree's
roots and rows, tiles marked and walked from the top (:func:`lp_tiles_walk`), the level
boxes of a tile set and the pooled samples gathered (:func:`gather_pooled`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.lod.activekernels import sample_xy
from geoterrain.lod.lpkernels import lp_tiles


@njit(cache=True, nogil=True)
def level_boxes(L, i0, i1, j0, j1, boxes):
    """Grow ``boxes[L]`` (rows i0, i1, columns j0, j1) to hold each tile's samples."""
    for k in range(L.shape[0]):
        b = boxes[L[k]]
        b[0] = min(b[0], i0[k])
        b[1] = max(b[1], i1[k])
        b[2] = min(b[2], j0[k])
        b[3] = max(b[3], j1[k])


@njit(cache=True, nogil=True)
def gather_pooled(flat, N, slabs, xyz, ij, level):
    """Scene positions ``xyz`` (x, y, height · zfac), grid ``ij`` and pyramid level of
    full-resolution samples ``flat`` (i·N + j), read from the coarsest tile holding
    each in the pool's ``slabs`` (:class:`~geoterrain.lod.pool.PoolSlabs`; unstored
    tiles: NaN height, x = y = 0)."""
    top, t, base, slot_of = slabs.top, slabs.t, slabs.base, slabs.slot_of
    H, X, Y, aff, zfac = slabs.H, slabs.X, slabs.Y, slabs.aff, slabs.zfac
    for k in range(flat.shape[0]):
        i, j = flat[k] // N, flat[k] % N
        L, idx, a, b = _coarsest_tile(i, j, top, t, base)
        s = slot_of[idx] if idx >= 0 else -1
        level[k] = L
        ij[k, 0], ij[k, 1] = i, j
        if s < 0:
            xyz[k, 0], xyz[k, 1], xyz[k, 2] = 0.0, 0.0, np.nan
        else:
            x, y = sample_xy(X, Y, aff, s, a, b, i, j)
            xyz[k, 0], xyz[k, 1], xyz[k, 2] = x, y, H[s, a, b] * zfac


@njit(cache=True, nogil=True, inline="always")
def tree_roots(base, top):
    """(across, down) top tiles of a tile walk's ``base``
    (:meth:`geoterrain.core.grid.Grid.walk_table`): a root grid's, or (1, 1)."""
    if base.shape[0] > top + 2:
        return base[2 * top + 2], base[3 * top + 3]
    return np.int64(1), np.int64(1)


@njit(cache=True, nogil=True, inline="always")
def tree_row(table, base, top, L, x, y):
    """The row of tile (L, x, y) in a tile walk's dense ``table`` (−1: not stored, or
    past a root grid's last tile column or row; a square's level L is 2^(top − L) tiles
    a side)."""
    if base.shape[0] > top + 2:
        across = base[top + 2 + L]
        if x >= across or y >= base[2 * top + 3 + L]:
            return np.int64(-1)
    else:
        across = np.int64(1) << (top - L)
    return table[base[L] + y * across + x]


@njit(cache=True, nogil=True)
def _coarsest_tile(i, j, top, t, base):
    """Level, slot-table index and sample (a, b) of the coarsest tile holding sample
    (i, j). ``base`` (:meth:`geoterrain.core.grid.Grid.offsets`, then each level's tiles
    across and down: ``base[top + 2 + L]``, ``base[2 top + 3 + L]``; a square's table
    stops at its offsets, its level L 2^(top − L) tiles a side). Index −1: the sample
    lies beyond the level's tiles (a root grid's padding past the raster, no tile)."""
    low = i | j
    L = top
    if low != 0:
        L = 0
        while (low & 1) == 0 and L < top:
            low >>= 1
            L += 1
    li, lj = i >> L, j >> L
    if base.shape[0] > top + 2:
        across, down = base[top + 2 + L], base[2 * top + 3 + L]
    else:
        across = down = np.int64(1) << (top - L)
    ty, tx = li >> t, lj >> t
    if ty == down and li == ty << t:  # the last tile's far border
        ty -= 1
    if tx == across and lj == tx << t:
        tx -= 1
    if ty >= down or tx >= across:
        return L, np.int64(-1), np.int64(0), np.int64(0)
    return L, base[L] + ty * across + tx, li - (ty << t), lj - (tx << t)


@njit(cache=True, nogil=True)
def mark_tiles(flat, N, top, t, base, occ):
    """Flag in ``occ`` (the pool's slot-table layout) the coarsest tile of each sample."""
    for k in range(flat.shape[0]):
        idx = _coarsest_tile(flat[k] // N, flat[k] % N, top, t, base)[1]
        if idx >= 0:
            occ[idx] = True


@njit(cache=True, nogil=True)
def lp_tiles_walk(tree, dmax, rmax, rsub, grow, gsub, view, floor, out):
    """:func:`lp_tiles` for the tiles the quadtree ``tree``
    (:class:`~geoterrain.lod.tiles.TileTree`) reaches from the top: a subtree whose
    box grown by its largest radius (``rsub``: the tile's and every descendant's) and
    vertically by its largest finite δ (``gsub``, as ``grow`` is the tile's) lies
    outside a frustum plane is not entered. A descendant's box lies in its ancestor's
    and its radius and δ are at most ``rsub`` and ``gsub``, so :func:`lp_tiles` gives
    those tiles status 0 too: the result is the same, at a cost that follows the tiles
    near the frustum.
    ``out``/``floor`` are filled for the visited rows (``out`` must start at 0).
    Returns tiles visited."""
    table, base, top, lo, hi = tree
    planes = view.planes
    P = planes.shape[0]
    # a root grid's base carries each level's tiles across and down (_coarsest_tile)
    rect = base.shape[0] > top + 2
    rx = base[2 * top + 2] if rect else 1
    ry = base[3 * top + 3] if rect else 1
    stack = np.empty((4 * (top + 2) + rx * ry, 3), np.int64)
    sp, visited = 0, 0
    for y in range(ry):
        for x in range(rx):
            stack[sp, 0], stack[sp, 1], stack[sp, 2] = top, x, y
            sp += 1
    for k in range(floor.shape[0]):
        floor[k] = -1.0
    fl = np.empty(1)
    while sp > 0:
        sp -= 1
        L, x, y = stack[sp, 0], stack[sp, 1], stack[sp, 2]
        across = base[top + 2 + L] if rect else np.int64(1) << (top - L)
        if rect and (x >= across or y >= base[2 * top + 3 + L]):
            continue  # past a root grid's last tile column or row
        row = table[base[L] + y * across + x]
        if row < 0:
            continue
        visited += 1
        r, g = rsub[row], gsub[row]
        skip = False
        for q in range(P):
            a, b, c, w = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
            fx = hi[row, 0] + r if a >= 0 else lo[row, 0] - r
            fy = hi[row, 1] + r if b >= 0 else lo[row, 1] - r
            fz = hi[row, 2] + r + g if c >= 0 else lo[row, 2] - r - g
            if a * fx + b * fy + c * fz + w < 0:
                skip = True
                break
        if skip:
            continue
        st = lp_tiles(lo[row:row + 1], hi[row:row + 1], dmax[row:row + 1],
                      rmax[row:row + 1], grow[row:row + 1], view, fl)
        out[row] = st[0]
        floor[row] = fl[0]
        if L > 0:
            for dy in range(2):
                for dx in range(2):
                    stack[sp, 0], stack[sp, 1], stack[sp, 2] = L - 1, 2 * x + dx, 2 * y + dy
                    sp += 1
    return visited

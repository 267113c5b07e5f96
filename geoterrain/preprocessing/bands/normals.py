"""Every level's normal codes from a grid read in row bands (issue 12's streaming
preprocess; the whole-grid twins are :func:`geoterrain.bounds.normals.level_normal_maps` and
:func:`~geoterrain.bounds.normals.encode_octahedral`).

Level L's map is the central differences of level L's own samples (every 2**L-th row and
column), so a band of level-L rows needs one row of halo each side. The levels form a
cascade: each keeps its last row (the next band's halo) and the rows whose successor
has not arrived, and hands its even rows, every other column, to the next level. Codes
go to the scratch arrays ``n{L}`` ((N_L, 2·N_L) uint8: each row's (u, v) pairs), the
same bytes as the whole-grid maps'.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoterrain.bounds.normals import encode_octahedral, normal_map
from geoterrain.preprocessing.bands.delta import grid_shape
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["band_normal_codes", "ring_lines"]


def ring_lines(n: int, t: int) -> np.ndarray:
    """The lines (rows or columns) of a level's n that a tile's border ring and its
    one-sided tangents read (:func:`geoterrain.bounds.normals.ring_guess`): those whose
    index mod 2**t is 0, 1 or 2**t − 1, ascending (the scratch arrays ``zr{L}`` and
    ``zc{L}`` hold the level's heights there).

    Examples
    --------
    >>> ring_lines(9, 2).tolist()
    [0, 1, 3, 4, 5, 7, 8]
    """
    S = 1 << t
    o = np.arange(n) % S
    return np.flatnonzero((o == 0) | (o == 1) | (o == S - 1))

Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


class _Level:
    """One level of the cascade: its buffered rows (scene heights, valid, and on a
    curvilinear grid scene x, y) from level row ``start`` on, and ``done``, the rows whose
    normals are written."""

    def __init__(self, rows: int, xs: np.ndarray, ys: np.ndarray, curvilinear: bool) -> None:
        self.rows, self.xs, self.ys = rows, xs, ys
        self.start = self.done = 0
        self.z = np.empty((0, len(xs)), np.float64)
        self.v = np.empty((0, len(xs)), np.bool_)
        self.X = np.empty((0, len(xs)), np.float64) if curvilinear else None
        self.Y = np.empty((0, len(xs)), np.float64) if curvilinear else None


def band_normal_codes(rows: Rows, N: int | tuple[int, int], xs: np.ndarray,
                      ys: np.ndarray, levels: int, sa: ScratchArrays, band: int = 256,
                      bits: int = 8, xy: Rows | None = None, t: int | None = None) -> None:
    """Write ``n{L}`` (L < ``levels``) to ``sa``: the octahedral codes of
    ``encode_octahedral(level_normal_maps(X, Y, Z, valid, levels)[L], bits)``, from
    ``rows(i0, i1)`` → (scene heights, valid) of rows i0 … i1 − 1.

    ``xs``, ``ys``: scene x of each column and y of each row (a projected or pixel frame);
    on a curvilinear (geographic) grid, ``xy(i0, i1)`` → the rows' scene X, Y instead
    (``xs`` and ``ys`` then only give the grid's side). ``N``: the grid's side, or a
    root grid's extent (rows, cols). ``t`` (the tile exponent): also ``zr{L}`` and
    ``zc{L}``, float64, the level's scene heights (NaN where not valid) on its
    :func:`ring_lines` rows (all columns) and columns (all rows): what the writer guesses
    each tile's ring normals from (schema 17).

    Examples
    --------
    >>> from geoterrain.bounds.normals import level_normal_maps
    >>> z = np.random.default_rng(3).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> xs = ys = np.arange(9.0)
    >>> sa = ScratchArrays()
    >>> band_normal_codes(lambda a, b: (z[a:b], v[a:b]), 9, xs, -ys, 3, sa, band=2)
    >>> X, Y = np.meshgrid(xs, -ys)
    >>> top = encode_octahedral(level_normal_maps(X, Y, z, v, 3)[2], 8)
    >>> bool((sa.read("n2", 0, 3).reshape(3, 3, 2) == top).all())
    True
    """
    xs = np.asarray(xs, np.float64)
    ys = np.asarray(ys, np.float64)
    NR, NC = grid_shape(N)
    lv = []
    lines: list[tuple[np.ndarray, np.ndarray]] = []
    for L in range(levels):
        s = 1 << L
        mr, mc = (NR - 1) // s + 1, (NC - 1) // s + 1
        sa.create(f"n{L}", (mr, 2 * mc), np.uint8)
        lv.append(_Level(mr, xs[::s], ys[::s], xy is not None))
        if t is not None:
            lr, lc = ring_lines(mr, t), ring_lines(mc, t)
            sa.create(f"zr{L}", (len(lr), mc), np.float64)
            sa.create(f"zc{L}", (mr, len(lc)), np.float64)
            lines.append((lr, lc))

    def feed(L: int, a0: int, z: np.ndarray, v: np.ndarray, gx: np.ndarray | None,
             gy: np.ndarray | None) -> None:
        # level L's rows a0 … a0 + len(z) − 1, which follow the rows fed before
        cur = lv[L]
        if lines:  # the heights on the ring lines, NaN where not valid (no band copy)
            lr, lc = lines[L]
            a, b = np.searchsorted(lr, [a0, a0 + len(z)])
            for q in range(a, b):  # (a band holds a few: 3 of each 2**t rows)
                r = lr[q] - a0
                sa.write(f"zr{L}", q, np.where(v[r:r + 1], z[r:r + 1], np.nan))
            sa.write(f"zc{L}", a0, np.where(v[:, lc], z[:, lc], np.nan))
        cur.z = np.concatenate([cur.z, z])
        cur.v = np.concatenate([cur.v, v])
        if gx is not None:
            cur.X = np.concatenate([cur.X, gx])
            cur.Y = np.concatenate([cur.Y, gy])
        end = cur.start + len(cur.z)
        hi = cur.rows if end >= cur.rows else end - 1  # rows below hi have their successor
        if hi > cur.done:
            w0, w1 = max(cur.done - 1, 0), min(hi + 1, end)  # one row of halo each side
            zz, vv = cur.z[w0 - cur.start:w1 - cur.start], cur.v[w0 - cur.start:w1 - cur.start]
            if cur.X is not None:
                X = cur.X[w0 - cur.start:w1 - cur.start]
                Y = cur.Y[w0 - cur.start:w1 - cur.start]
            else:
                X = np.broadcast_to(cur.xs[None, :], zz.shape)
                Y = np.broadcast_to(cur.ys[w0:w1, None], zz.shape)
            n = normal_map(X, Y, zz, vv)[cur.done - w0:hi - w0]
            sa.write(f"n{L}", cur.done, encode_octahedral(n, bits).reshape(len(n), -1))
            cur.done = hi
            keep = max(cur.done - 1, cur.start) - cur.start  # the next band's halo row
            cur.z, cur.v, cur.start = cur.z[keep:], cur.v[keep:], cur.start + keep
            if cur.X is not None:
                cur.X, cur.Y = cur.X[keep:], cur.Y[keep:]
        if L + 1 < levels:  # the even rows, every other column, are the next level's
            first = a0 + (a0 & 1)
            if first < a0 + len(z):
                k = first - a0
                feed(L + 1, first // 2, z[k::2, ::2], v[k::2, ::2],
                     None if gx is None else gx[k::2, ::2],
                     None if gy is None else gy[k::2, ::2])

    for r0 in range(0, NR, band):
        r1 = min(r0 + band, NR)
        z, v = rows(r0, r1)
        gx = gy = None
        if xy is not None:
            gx, gy = (np.asarray(a, np.float64) for a in xy(r0, r1))
        feed(0, r0, np.asarray(z, np.float64), np.asarray(v, bool), gx, gy)
        z = v = gx = gy = None  # before the next band's are read

"""Every level's normal codes from a grid read in row bands (issue 12's streaming
preprocess; the whole-grid twins are :func:`geoterrain.normals.normal_map`,
:func:`~geoterrain.normals.normal_pyramid` and
:func:`~geoterrain.normals.encode_octahedral`).

Level 0 is the full-resolution normal map (central differences: a band needs one row
of halo each side). Level L + 1's row a is the binomial 3 × 3 filter of level L's rows
2a − 1 … 2a + 1 (seed 000's per-level normal maps, filtered from level L alone), so the
levels form a cascade: each keeps the rows its next level has not used yet, at most a
band's worth and one row. Codes go to the scratch arrays ``n{L}`` ((N_L, 2·N_L) uint8:
each row's (u, v) pairs), the same bytes as the whole-grid maps'.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoterrain.normals import _reduce_part_nb, encode_octahedral, normal_map
from geoterrain.scratch import ScratchArrays

__all__ = ["band_normal_codes"]

Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


class _Level:
    """One level of the cascade: its buffered rows (normals float32, weights float32)
    from global row ``start`` on, and the next row its successor will compute."""

    def __init__(self, rows: int) -> None:
        self.rows = rows
        self.start = 0
        self.n = np.empty((0, 0, 3), np.float32)
        self.w = np.empty((0, 0), np.float32)
        self.next_out = 0  # the successor level's next row


def band_normal_codes(rows: Rows, N: int, xs: np.ndarray, ys: np.ndarray, levels: int,
                      sa: ScratchArrays, band: int = 256, bits: int = 8) -> None:
    """Write ``n{L}`` (L < ``levels``) to ``sa``: the octahedral codes of
    ``encode_octahedral(normal_pyramid(normal_map(X, Y, Z, valid), valid, levels)[L],
    bits)``, from ``rows(i0, i1)`` → (scene heights, valid) of rows i0 … i1 − 1.

    ``xs``, ``ys``: scene x of each column and y of each row (a projected or pixel frame).

    Examples
    --------
    >>> from geoterrain.normals import normal_pyramid
    >>> z = np.random.default_rng(3).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> xs = ys = np.arange(9.0)
    >>> sa = ScratchArrays()
    >>> band_normal_codes(lambda a, b: (z[a:b], v[a:b]), 9, xs, -ys, 3, sa, band=2)
    >>> n = normal_map(*np.meshgrid(xs, -ys), z, v)
    >>> top = encode_octahedral(normal_pyramid(n, v, 3)[2], 8)
    >>> bool((sa.read("n2", 0, 3).reshape(3, 3, 2) == top).all())
    True
    """
    xs = np.asarray(xs, np.float64)
    ys = np.asarray(ys, np.float64)
    sizes = [(N - 1) // (1 << L) + 1 for L in range(levels)]
    for L, m in enumerate(sizes):
        sa.create(f"n{L}", (m, 2 * m), np.uint8)
    lv = [_Level(m) for m in sizes]

    def emit(L: int, r0: int, n: np.ndarray, w: np.ndarray) -> None:
        # rows r0 … of level L: code them, then feed the next level what it can take
        sa.write(f"n{L}", r0, encode_octahedral(n, bits).reshape(len(n), -1))
        if L + 1 >= levels:
            return
        cur = lv[L]
        cur.n = np.concatenate([cur.n, n]) if len(cur.n) else n
        cur.w = np.concatenate([cur.w, w]) if len(cur.w) else w
        end = cur.start + len(cur.n)  # rows buffered: cur.start … end − 1
        # row a reads rows 2a − 1 … 2a + 1 (those past the level's last row: none)
        a_hi = sizes[L + 1] - 1 if end >= cur.rows else (end - 2) // 2
        if a_hi >= cur.next_out:
            a0 = cur.next_out
            out = np.empty((a_hi - a0 + 1, sizes[L + 1], 3), np.float32)
            wout = np.empty(out.shape[:2], np.float32)
            _reduce_part_nb(cur.n, cur.w, cur.start, cur.rows, out, wout, a0)
            cur.next_out = a_hi + 1
            keep = max(2 * cur.next_out - 1, cur.start) - cur.start  # rows still needed
            cur.n, cur.w, cur.start = cur.n[keep:], cur.w[keep:], cur.start + keep
            emit(L + 1, a0, out, wout)

    for r0 in range(0, N, band):
        r1 = min(r0 + band, N)
        w0, w1 = max(r0 - 1, 0), min(r1 + 1, N)
        z, v = rows(w0, w1)
        v = np.asarray(v, bool)
        X = np.broadcast_to(xs[None, :], z.shape)
        Y = np.broadcast_to(ys[w0:w1, None], z.shape)
        n = normal_map(X, Y, z, v)[r0 - w0:r1 - w0]
        emit(0, r0, n, v[r0 - w0:r1 - w0].astype(np.float32))

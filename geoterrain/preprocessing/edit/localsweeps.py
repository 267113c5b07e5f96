"""Coarse blocks of an edit swept a tile at a time (:mod:`.localbounds`' coarse levels,
whose blocks outgrow a tile): a block's status from its tiles' valid counts, and its
exact maxima |z − P| over its regions, each tile bounded first from its height range
(and the GeoMipMapping table's union-jack surfaces) and swept in decreasing order of
bound until no unswept bound passes the largest value found
(:func:`geoterrain.bounds.windows.block_sweep_rect`); raw δ of a coarse vertex as
``bounds._raw_delta_nb`` computes it. Methods of :class:`.localbounds.Bounds`.
"""

from __future__ import annotations

import numpy as np

from geoterrain.bounds.delta import Cell
from geoterrain.bounds.tilebounds import closed_blocks
from geoterrain.bounds.windows import block_sweep_rect
from geoterrain.core.bintree import child_nb, main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.preprocessing.edit.localerrors import WholeGrid as _Whole

__all__ = ["BlockSweeps"]

_SLACK = 1e-9  # relative slack of a tile's bound (float rounding of the planes)

# The scalar helpers called from this module's Python code run as Python (the same
# integer arithmetic; round_up32's float32 steps are IEEE operations in numpy too): a
# compiled scalar called from Python costs a load from numba's cache in each process
# (2-5 ms each, docs/lab/editing.md) for a few hundred calls of well under a microsecond.
# The kernels below keep calling the compiled ones.
_child = child_nb.py_func
_main_diagonal = main_diagonal_nb.py_func


def _round_up32(a: float) -> float:
    # what the compiled round_up32 returns to Python: its float32 as a float
    return float(round_up32.py_func(a))



class BlockSweeps:
    """The coarse block sweeps of :class:`.localbounds.Bounds` (its window, canvas, rows
    of level-0 tile numbers and caches)."""

    def _status(self, a: int, b: int, s: int, new: bool = True) -> int:
        """A coarse block's status (1 all valid, 2 all invalid, 3 mixed) from its tiles'
        valid counts; 0 outside the grid."""
        if not (0 <= a < (self.R - 1) // s and 0 <= b < (self.C - 1) // s):
            return 0
        k = s // self.S
        n = self.rows0[new][0, a * k:a * k + k, b * k:b * k + k]
        return (1 if (n > 0).any() else 0) | (2 if (n < (self.S + 1) ** 2).any() else 0)

    def _coarse_raw(self, i: int, j: int, h: int, new: bool = True) -> np.float32:
        """Raw δ of a coarse vertex (as bounds._raw_delta_nb computes it)."""
        s = 2 * h
        if (i // h) % 2 == 1 and (j // h) % 2 == 1:
            a, b = (i - h) // s, (j - h) // s
            f = self._status(a, b, s, new)
            if f == 1:
                return _round_up32(self._block_max(a, b, s, (0,), new)[0])
            return np.float32(np.inf) if f == 3 else np.float32(0.0)
        if (i // h) % 2 == 1:  # hypotenuse along the rows
            a, b = (i - h) // s, j // s
            lo, hi = (a, b - 1, 2), (a, b, 1)
        else:
            a, b = i // s, (j - h) // s
            lo, hi = (a - 1, b, 4), (a, b, 3)
        flo = self._status(lo[0], lo[1], s, new)
        fhi = self._status(hi[0], hi[1], s, new)
        f = flo | fhi
        if f == 2:
            return np.float32(0.0)
        if f == 1:
            m = 0.0
            for (ba, bb, which), fs in ((lo, flo), (hi, fhi)):
                if fs:
                    m = max(m, self._block_max(ba, bb, s, (which,), new)[which])
            return _round_up32(m)
        if self._diamond_mixed(i, j, h, new):
            return np.float32(np.inf)
        raise _Whole("nodata beside a coarse vertex whose diamond may be all valid")

    def _diamond_mixed(self, i: int, j: int, h: int, new: bool) -> bool:
        """Whether tiles wholly inside the vertex's diamond hold valid and invalid
        samples (the diamond is then mixed: δ = +inf)."""
        S, T2 = self.S, (self.S + 1) ** 2
        got = 0
        nx, ny = self.g.tiles(0)
        for ty in range(max((i - h) // S, 0), min((i + h) // S, ny - 1) + 1):
            for tx in range(max((j - h) // S, 0), min((j + h) // S, nx - 1) + 1):
                corners = [(ty * S + a, tx * S + b) for a in (0, S) for b in (0, S)]
                if all(abs(p - i) + abs(q - j) <= h for p, q in corners):
                    n = self.rows0[new][0, ty, tx]
                    got |= (1 if n > 0 else 0) | (2 if n < T2 else 0)
                    if got == 3:
                        return True
        return False

    def _block_max(self, a: int, b: int, s: int, want: tuple, new: bool = True) -> np.ndarray:
        """The exact maxima (centre, left, right, top, bottom) of the all-valid block
        (a, b) of side s > tile, those in ``want`` exact: its tiles swept in decreasing
        order of their bound until no bound passes the best value found."""
        c, S = self.c, self.S
        i0, j0 = a * s, b * s
        main = _main_diagonal(a, b)
        corners = c.samples(np.array([i0, i0, i0 + s, i0 + s, i0 + s // 2]),
                            np.array([j0, j0 + s, j0, j0 + s, j0 + s // 2]), new)[0]
        z00, z01, z10, z11, zc = (float(v) for v in corners)
        cell = Cell(i0, j0, s, main, z00, z01, z10, z11)
        k = s // S
        ty, tx = np.meshgrid(np.arange(a * k, a * k + k), np.arange(b * k, b * k + k),
                             indexing="ij")
        ty, tx = ty.ravel(), tx.ravel()
        bkey = (a, b, s, new)
        got = self._bound_cache.get(bkey)
        if got is None:
            zlo = self.rows0[new][1, ty, tx]
            zhi = self.rows0[new][2, ty, tx]
            bound = _bounds(cell, zc, ty * S - i0, tx * S - j0, S, zlo, zhi)
            if k > 2:  # tighter: the union-jack surfaces of the block table
                tight = self._uj_bounds(cell, zc, a, b, s, new)
                bound = np.where(np.isneginf(bound), bound, np.minimum(bound, tight))
            # each region's tiles by decreasing bound, and which were swept
            got = self._bound_cache[bkey] = (bound, np.argsort(-bound, axis=0, kind="stable"),
                                             np.zeros(len(ty), bool), np.zeros(5))
        bound, order, swept, best = got
        pos = [0] * 5
        while True:
            # the wanted region whose next unswept tile's bound most exceeds its best
            pick, gain = -1, 0.0
            for r in want:
                while pos[r] < len(ty) and swept[order[pos[r], r]]:
                    pos[r] += 1
                if pos[r] < len(ty):
                    g = bound[order[pos[r], r], r] - best[r]
                    if g > gain:
                        pick, gain = r, g
            if pick < 0:
                return best.copy()
            q = int(order[pos[pick], pick])
            key = (a, b, s, new, int(ty[q]), int(tx[q]))
            m = self._sweeps.get(key)
            if m is None:
                z, _ = c.tile_z(int(ty[q]), int(tx[q]), new)
                a0, c0 = int(ty[q]) * S - i0, int(tx[q]) * S - j0
                m = self._sweeps[key] = np.array(block_sweep_rect(
                    z, int(ty[q]) * S, int(tx[q]) * S, cell, zc, a0, a0 + S, c0, c0 + S))
            np.maximum(best, m, out=best)
            swept[q] = True
            self.tiles_swept += 1

    def _uj_bounds(self, cell: Cell, zc: float, a: int, b: int, s: int, new: bool
                   ) -> np.ndarray:
        """(tiles, 5) bounds of |z − P| over each tile of block (a, b) from the store's
        GeoMipMapping table: at level n, z lies within the tile's δ_n (rounded up) of
        S_n, the union-jack surface through the tile's level-n samples, and S_n − P is
        linear on each of its triangles, so |z − P| ≤ max over those samples of
        |z − P| + δ_n, at n = max(t − 2, 1) (of n = t, t − 1, t − 2, the coarser two lowered
        the tiles swept by 1 in 116 an edit on the 4097² fBm for a quarter of this
        bound's time, docs/lab/editing.md). Tiles the edit changed get +inf (the table is
        the old one) when ``new``."""
        g, c, S = self.g, self.c, self.S
        i0, j0, s_, main, z00, z01, z10, z11 = cell
        h = s // 2
        k = s // S
        table = self.t.block_errors()
        out = np.full((k * k, 5), np.inf)
        for n in range(max(g.t - 2, 1), min(max(g.t - 2, 1), table.shape[2] - 1) + 1):
            step = 1 << n
            rows = np.arange(i0, i0 + s + 1, step)
            cols = np.arange(j0, j0 + s + 1, step)
            hh, vv = c.lattice(n, rows, cols, new)
            if not vv.all():
                return out
            z = hh * c.factor
            di = (rows - i0)[:, None].astype(np.float64)
            dj = (cols - j0)[None, :].astype(np.float64)
            fi = di / s
            kl = (zc - 0.5 * (z00 + z10)) / h
            kr = (zc - 0.5 * (z01 + z11)) / h
            kt = (zc - 0.5 * (z00 + z01)) / h
            kb = (zc - 0.5 * (z10 + z11)) / h
            if main:
                p1 = z00 + (z10 - z00) * fi + (z11 - z10) / s * dj
                p2 = z00 + (z11 - z01) * fi + (z01 - z00) / s * dj
                left, right = dj < di, dj > di
            else:
                p1 = z00 + (z10 - z00) * fi + (z01 - z00) / s * dj
                p2 = z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11) - (z10 - z11) / s * dj
                left, right = dj < s - di, dj > s - di
            a1, a2 = np.abs(z - p1), np.abs(z - p2)
            errs = [np.where(left, a1, np.where(right, a2, np.maximum(a1, a2))),
                    np.abs(z - (z00 + (z10 - z00) * fi + kl * dj)),
                    np.abs(z - (z01 + (z11 - z01) * fi + kr * s - kr * dj)),
                    np.abs(z - (z00 + kt * di + (z01 - z00) / s * dj)),
                    np.abs(z - (z10 + kb * (s - di) + (z11 - z10) / s * dj))]
            m = S // step
            d_n = table[a * k:a * k + k, b * k:b * k + k, n].ravel()
            for r, e in enumerate(errs):
                per = closed_blocks(e, m, np.maximum).ravel()
                bnd = per + d_n + _SLACK * (np.abs(z).max() + 1.0) * 4
                out[:, r] = np.minimum(out[:, r], bnd)
        if new:  # the edit's tiles: the table holds their old δ_n
            ty = np.repeat(np.arange(a * k, a * k + k), k)
            tx = np.tile(np.arange(b * k, b * k + k), k)
            hit = (ty * S <= c.r1 - 1) & (ty * S + S >= c.r0) & (tx * S <= c.c1 - 1) & \
                (tx * S + S >= c.c0)
            out[hit] = np.inf
        return out


def _bounds(cell: Cell, zc: float, a0: np.ndarray, c0: np.ndarray, S: int, zlo: np.ndarray,
            zhi: np.ndarray) -> np.ndarray:
    """(tiles, 5) upper bounds of |z − P| over each tile (rows a0 … a0 + S, columns
    c0 … c0 + S of the block) for the block's centre surface and its four quarter
    planes (−inf where a tile misses a quarter): z within [zlo, zhi], P linear, so its
    extremes lie at the tile's corners."""
    i0, j0, s, main, z00, z01, z10, z11 = cell
    h = s // 2
    fi = np.stack([a0, a0, a0 + S, a0 + S], 1) / s
    dj = np.stack([c0, c0 + S, c0, c0 + S], 1).astype(np.float64)
    di = fi * s
    kl = (zc - 0.5 * (z00 + z10)) / h
    kr = (zc - 0.5 * (z01 + z11)) / h
    kt = (zc - 0.5 * (z00 + z01)) / h
    kb = (zc - 0.5 * (z10 + z11)) / h
    if main:
        p1 = z00 + (z10 - z00) * fi + (z11 - z10) / s * dj
        p2 = z00 + (z11 - z01) * fi + (z01 - z00) / s * dj
    else:
        p1 = z00 + (z10 - z00) * fi + (z01 - z00) / s * dj
        p2 = z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11) - (z10 - z11) / s * dj
    planes = [np.concatenate([p1, p2], 1),
              z00 + (z10 - z00) * fi + kl * dj,
              z01 + (z11 - z01) * fi + kr * s - kr * dj,
              z00 + kt * di + (z01 - z00) / s * dj,
              z10 + kb * (s - di) + (z11 - z10) / s * dj]
    out = np.empty((len(a0), 5))
    for k, P in enumerate(planes):
        lo, hi = P.min(axis=1), P.max(axis=1)
        b = np.maximum(zhi - lo, hi - zlo)
        out[:, k] = b + _SLACK * (np.abs(zhi) + np.abs(zlo) + np.abs(lo) + np.abs(hi)) + 1e-300
    # which quarter each tile meets (closed: diagonal samples in both)
    r0, r1 = a0, a0 + S
    q0, q1 = c0, c0 + S
    fmax = lambda lo_, hi_: np.minimum(np.clip(h, lo_, hi_), s - np.clip(h, lo_, hi_))  # noqa: E731
    gmin = lambda lo_, hi_: np.maximum(np.clip(h, lo_, hi_), s - np.clip(h, lo_, hi_))  # noqa: E731
    out[:, 1] = np.where(q0 <= fmax(r0, r1), out[:, 1], -np.inf)
    out[:, 2] = np.where(q1 >= gmin(r0, r1), out[:, 2], -np.inf)
    out[:, 3] = np.where(r0 <= fmax(q0, q1), out[:, 3], -np.inf)
    out[:, 4] = np.where(r1 >= gmin(q0, q1), out[:, 4], -np.inf)
    return out

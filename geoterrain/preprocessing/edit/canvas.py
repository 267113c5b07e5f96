"""The samples an edit reads: level-0 tiles as the store holds them and as the edit
leaves them, decoded once each, and windows assembled from them."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.codec.quantize import heights_to_codes

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Canvas"]


class Canvas:
    """Level-0 samples of ``terrain`` before (``new=False``) and after the edit that puts
    ``heights``/``valid`` (source units, NaN where not valid) at rows ``r0 …``, columns
    ``c0 …``.

    Scene heights come as the kernels take them (:func:`geoterrain.bounds.delta.check_grid`):
    float64, 0 where not valid, with the validity as uint8; samples outside the grid or
    in unstored tiles are nodata.

    Examples
    --------
    >>> c = Canvas(t, 1, 2, np.full((2, 2), 7.0), np.ones((2, 2), bool))
    >>> z, v = c.rect(0, 0, 4, 4)
    >>> float(z[1, 2]) == 7.0 * c.factor, z.shape
    (True, (4, 4))
    """

    def __init__(self, terrain: TerrainLike, r0: int, c0: int, heights: np.ndarray,
                 valid: np.ndarray):
        self.terrain = terrain
        g = terrain.grid
        self.grid = g
        self.S = 1 << g.t
        self.ntx, self.nty = g.tiles(0)  # level-0 tiles across and down
        self.r0, self.c0 = int(r0), int(c0)
        self.r1, self.c1 = self.r0 + heights.shape[0], self.c0 + heights.shape[1]
        self.heights = np.where(valid, heights, np.nan)
        self.valid = np.asarray(valid, bool)
        self.codes = heights_to_codes(np.where(self.valid, heights, 0.0), terrain.quantizer)
        f = terrain.frame
        self.factor = f.z_to_m * f.z_scale
        self._tiles: dict = {}
        self._z: dict = {}
        self._big: dict = {}  # new → the largest rectangle assembled: (i0, j0, z, v)

    def fetch(self, keys) -> None:
        """Decode the stored tiles of ``keys`` (level, x, y) that the terrain does not hold
        yet in one batch (:meth:`geoterrain.terrain.Terrain.tiles`: one query), where the
        terrain reads batches; the calls of :meth:`tile` that follow find them cached."""
        t = self.terrain
        batch = getattr(t, "tiles", None)
        if batch is not None:
            keys = [k for k in keys if k in t.tile_info]
            if len(keys) > 1:
                batch(keys)

    def touches(self, i0: int, j0: int, i1: int, j1: int) -> bool:
        """Whether the closed rectangle rows i0 … i1, columns j0 … j1 holds an edited
        sample."""
        return i0 < self.r1 and i1 >= self.r0 and j0 < self.c1 and j1 >= self.c0

    def _key(self, ty: int, tx: int, new: bool) -> tuple[int, int, bool]:
        # a tile the edit does not touch is the same before and after it: one entry
        i0, j0 = ty * self.S, tx * self.S
        return ty, tx, bool(new) and self.touches(i0, j0, i0 + self.S, j0 + self.S)

    def tile(self, ty: int, tx: int, new: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Level-0 tile (x = ``tx``, y = ``ty``): heights (source units, NaN where not
        valid) and validity, (T, T)."""
        key = self._key(ty, tx, new)
        new = key[2]
        got = self._tiles.get(key)
        if got is not None:
            return got
        T = self.S + 1
        t = self.terrain
        if 0 <= ty < self.nty and 0 <= tx < self.ntx and (0, tx, ty) in t.tile_info:
            tl = t.tile(0, tx, ty)
            h, v = tl.heights.copy(), tl.valid.copy()
        else:
            h, v = np.full((T, T), np.nan), np.zeros((T, T), bool)
        i0, j0 = ty * self.S, tx * self.S
        if new:  # (it touches the tile)
            a0, a1 = max(self.r0, i0), min(self.r1, i0 + T)
            b0, b1 = max(self.c0, j0), min(self.c1, j0 + T)
            h[a0 - i0:a1 - i0, b0 - j0:b1 - j0] = self.heights[a0 - self.r0:a1 - self.r0,
                                                               b0 - self.c0:b1 - self.c0]
            v[a0 - i0:a1 - i0, b0 - j0:b1 - j0] = self.valid[a0 - self.r0:a1 - self.r0,
                                                             b0 - self.c0:b1 - self.c0]
        self._tiles[key] = (h, v)
        return h, v

    def tile_z(self, ty: int, tx: int, new: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """The tile's scene heights (0 where not valid) and validity (uint8)."""
        key = self._key(ty, tx, new)
        got = self._z.get(key)
        if got is None:
            h, v = self.tile(ty, tx, key[2])
            z = np.where(v, np.multiply(np.where(v, h, 0.0), self.factor), 0.0)
            got = self._z[key] = (np.ascontiguousarray(z), np.ascontiguousarray(v, np.uint8))
        return got

    def rect(self, i0: int, j0: int, i1: int, j1: int, new: bool = True
             ) -> tuple[np.ndarray, np.ndarray]:
        """Scene heights (0 where not valid) and validity (uint8) of rows i0 … i1 − 1 and
        columns j0 … j1 − 1 (samples outside level 0's tiles are nodata). A rectangle
        inside the largest one assembled so far (the edit's window) is a copy of its part."""
        big = self._big.get(new)
        if big is not None:
            bi, bj, bz, bv = big
            if bi <= i0 and bj <= j0 and i1 <= bi + bz.shape[0] and j1 <= bj + bz.shape[1]:
                return (bz[i0 - bi:i1 - bi, j0 - bj:j1 - bj].copy(),
                        bv[i0 - bi:i1 - bi, j0 - bj:j1 - bj].copy())
        z, v = self._assemble(i0, j0, i1, j1, new)
        if big is None or z.size > big[2].size:
            self._big[new] = (i0, j0, z.copy(), v.copy())
        return z, v

    def _assemble(self, i0: int, j0: int, i1: int, j1: int, new: bool
                  ) -> tuple[np.ndarray, np.ndarray]:
        # rect's samples, tile by tile
        z = np.zeros((i1 - i0, j1 - j0))
        v = np.zeros((i1 - i0, j1 - j0), np.uint8)
        S = self.S
        R, C = self.grid.shape
        tys = range(max(i0, 0) // S, min(i1 - 1, R - 1) // S + 1)
        txs = range(max(j0, 0) // S, min(j1 - 1, C - 1) // S + 1)
        self.fetch([(0, min(tx, self.ntx - 1), min(ty, self.nty - 1)) for ty in tys for tx in txs
                    if self._key(min(ty, self.nty - 1), min(tx, self.ntx - 1), new)
                    not in self._z])
        for ty in tys:
            ty = min(ty, self.nty - 1)
            for tx in txs:
                tx = min(tx, self.ntx - 1)
                tz, tv = self.tile_z(ty, tx, new)
                a0, a1 = max(i0, ty * S), min(i1, ty * S + S + 1)
                b0, b1 = max(j0, tx * S), min(j1, tx * S + S + 1)
                if a1 <= a0 or b1 <= b0:
                    continue
                z[a0 - i0:a1 - i0, b0 - j0:b1 - j0] = tz[a0 - ty * S:a1 - ty * S,
                                                          b0 - tx * S:b1 - tx * S]
                v[a0 - i0:a1 - i0, b0 - j0:b1 - j0] = tv[a0 - ty * S:a1 - ty * S,
                                                          b0 - tx * S:b1 - tx * S]
        return z, v

    def lattice(self, L: int, rows: np.ndarray, cols: np.ndarray, new: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
        """Heights (source units, NaN where not valid) and validity of the level-L
        samples ``rows`` × ``cols`` (ascending multiples of 2^L), from the level-L tiles
        (a lossless store's decoded codes there are the samples' own) and the edit."""
        g, t = self.grid, self.terrain
        T, span, step = g.tile_samples, g.tile_span(L), 1 << L
        rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
        h = np.full((len(rows), len(cols)), np.nan)
        v = np.zeros((len(rows), len(cols)), bool)
        nx, ny = g.tiles(L)
        # rows and columns a step apart (the normals' windows): slices, not index arrays
        regular = bool((np.diff(rows) == step).all() and (np.diff(cols) == step).all())
        ys = range(min(int(rows[0]) // span, ny - 1), min(int(rows[-1]) // span, ny - 1) + 1)
        xs = range(min(int(cols[0]) // span, nx - 1), min(int(cols[-1]) // span, nx - 1) + 1)
        self.fetch([(L, x, y) for y in ys for x in xs])
        for y in ys:
            ri = (rows - y * span) // step
            mr = (ri >= 0) & (ri < T)
            for x in xs:
                if (L, x, y) not in t.tile_info:
                    continue
                tl = t.tile(L, x, y)
                ci = (cols - x * span) // step
                mc = (ci >= 0) & (ci < T)
                if regular:
                    a, b = _run(mr), _run(mc)
                    if a is not None and b is not None:
                        src = (slice(int(ri[a.start]), int(ri[a.stop - 1]) + 1),
                               slice(int(ci[b.start]), int(ci[b.stop - 1]) + 1))
                        h[a, b] = tl.heights[src]
                        v[a, b] = tl.valid[src]
                    continue
                h[np.ix_(mr, mc)] = tl.heights[np.ix_(ri[mr], ci[mc])]
                v[np.ix_(mr, mc)] = tl.valid[np.ix_(ri[mr], ci[mc])]
        if new:
            mr = (rows >= self.r0) & (rows < self.r1)
            mc = (cols >= self.c0) & (cols < self.c1)
            if mr.any() and mc.any():
                if regular:
                    a, b = _run(mr), _run(mc)
                    src = (slice(int(rows[a.start]) - self.r0, int(rows[a.stop - 1]) - self.r0 + 1,
                                 step),
                           slice(int(cols[b.start]) - self.c0, int(cols[b.stop - 1]) - self.c0 + 1,
                                 step))
                    h[a, b] = self.heights[src]
                    v[a, b] = self.valid[src]
                    return h, v
                h[np.ix_(mr, mc)] = self.heights[np.ix_(rows[mr] - self.r0, cols[mc] - self.c0)]
                v[np.ix_(mr, mc)] = self.valid[np.ix_(rows[mr] - self.r0, cols[mc] - self.c0)]
        return h, v

    def tile_lattice(self, L: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`lattice` of tile (L, x, y)'s own samples as the edit leaves them: the
        tile's decoded heights and the edit's samples on its lattice, by slices.

        Examples
        --------
        >>> c = Canvas(t, 1, 2, np.full((2, 2), 7.0), np.ones((2, 2), bool))
        >>> T, s = t.grid.tile_samples, t.grid.tile_span(1)
        >>> h, v = c.tile_lattice(1, 0, 0)
        >>> r = np.arange(T) * 2
        >>> all(np.array_equal(a, b, equal_nan=True) for a, b in zip((h, v), c.lattice(1, r, r)))
        True
        """
        g, t = self.grid, self.terrain
        T, span, step = g.tile_samples, g.tile_span(L), 1 << L
        if (L, x, y) in t.tile_info:
            tl = t.tile(L, x, y)
            h, v = np.array(tl.heights, np.float64), np.array(tl.valid, bool)
        else:
            h, v = np.full((T, T), np.nan), np.zeros((T, T), bool)
        i0, j0 = y * span, x * span
        # the tile's lattice indices within the edit's rows r0 … r1 − 1, columns c0 … c1 − 1
        a0, a1 = -(-max(self.r0 - i0, 0) // step), min(self.r1 - 1 - i0, span) // step + 1
        b0, b1 = -(-max(self.c0 - j0, 0) // step), min(self.c1 - 1 - j0, span) // step + 1
        if a0 < a1 and b0 < b1:
            rr = slice(i0 + a0 * step - self.r0, i0 + (a1 - 1) * step - self.r0 + 1, step)
            cc = slice(j0 + b0 * step - self.c0, j0 + (b1 - 1) * step - self.c0 + 1, step)
            h[a0:a1, b0:b1] = self.heights[rr, cc]
            v[a0:a1, b0:b1] = self.valid[rr, cc]
        return h, v

    def samples(self, i: np.ndarray, j: np.ndarray, new: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
        """Scene heights (0 where not valid) and validity (bool) of scattered samples,
        each read from the coarsest tile that holds it."""
        i, j = np.asarray(i, np.int64).ravel(), np.asarray(j, np.int64).ravel()
        g, t = self.grid, self.terrain
        top = g.top_level
        z = np.zeros(i.shape)
        v = np.zeros(i.shape, bool)
        for k, (a, b) in enumerate(zip(i.tolist(), j.tolist(), strict=True)):
            if new and self.r0 <= a < self.r1 and self.c0 <= b < self.c1:
                v[k] = bool(self.valid[a - self.r0, b - self.c0])
                z[k] = self.heights[a - self.r0, b - self.c0] * self.factor if v[k] else 0.0
                continue
            bits = a | b
            L = top if bits == 0 else min((bits & -bits).bit_length() - 1, top)
            span, (nx, ny) = g.tile_span(L), g.tiles(L)
            y, x = min(a // span, ny - 1), min(b // span, nx - 1)
            if (L, x, y) not in t.tile_info:
                continue
            tl = t.tile(L, x, y)
            ra, cb = (a - y * span) >> L, (b - x * span) >> L
            v[k] = bool(tl.valid[ra, cb])
            z[k] = tl.heights[ra, cb] * self.factor if v[k] else 0.0
        return z, v


def _run(mask: np.ndarray) -> slice | None:
    """The slice of a mask's one run of True (ascending rows or columns a step apart
    that lie in a range), None where it has none."""
    k = np.flatnonzero(mask)
    return slice(int(k[0]), int(k[-1]) + 1) if k.size else None

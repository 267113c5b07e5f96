"""The viewshed's window of the grid: which of its tiles the sweep has read, at which
level, and the reads themselves, safe for the two halves of the sweep running at once.

:class:`Window` holds the heights (metres) of the tiles read, in blocks from a pool that
the sweep takes back from the tile rows it has left (a cold viewshed's fresh memory was
mostly these blocks), and the per-tile numbers the compiled sweep
(:mod:`geoterrain.analysis.sweep`) tests before it asks for a tile: the catalog's box
top (free) and, once read, how far the heights may be from the source's. A half of the
sweep gets its own view (:meth:`Window.half`): its own status and error arrays, and the
rows it owns; its reads write only those rows, so the two halves never write what the
other reads, and the store is read under one lock (a terrain is not thread-safe).

Examples
--------
>>> w = Window(t, 0, 40, 0, 40, eps=0.0, level=0)
>>> north = w.half(0, 4)
>>> north.read(0, 0)  # bounded from level 1 first (status 3), then read (1)
>>> int(north.tiles.status[0, 0]), int(w.status[0, 0])
(3, 0)
>>> north.read(0, 0); int(north.tiles.status[0, 0])
1
>>> all(w.height(i, j) == t.tile(0, 0, 0).heights[i, j] for i in range(4) for j in range(4))
True
"""

from __future__ import annotations

import contextlib
import math
import mmap
import threading
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.analysis.sweep import SweepTiles

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Half", "Window", "level_surface"]


class Window:
    """Window rows ``r0`` … ``r1`` − 1, columns ``c0`` … ``c1`` − 1 of the grid: the
    :class:`~geoterrain.analysis.sweep.SweepTiles` with nothing decoded (``tiles``), read
    at ``level`` where that level's tile error is finite (level 0 otherwise), heights known
    to ±``eps`` metres (the codec's error)."""

    def __init__(self, terrain: TerrainLike, r0: int, r1: int, c0: int, c1: int, eps: float,
                 level: int):
        g, f = terrain.grid, terrain.frame
        self.terrain, self.level, self.eps = terrain, level, eps
        self.r0, self.r1, self.c0, self.c1 = r0, r1, c0, c1
        across, down = g.tiles(0)  # level 0's tiles (a square's, or a root grid's)
        ty0, ty1 = r0 >> g.t, min((r1 - 1) >> g.t, down - 1)
        tx0, tx1 = c0 >> g.t, min((c1 - 1) >> g.t, across - 1)
        nty, ntx = ty1 - ty0 + 1, tx1 - tx0 + 1
        zs = f.z_scale or 1.0
        inf, cells, get = math.inf, g.tile_samples ** 2, terrain.tile_info.get
        st, tops = [], []
        for y in range(ty0, ty1 + 1):  # per tile, from the catalog: nothing decoded
            for x in range(tx0, tx1 + 1):
                info = get((0, x, y))
                if info is None:
                    st.append(2)
                    tops.append(inf)
                    continue
                st.append(0)
                top = info["zmax"]
                # the box is in scene units (a hair above it for the units' rounding); a
                # tile with nodata is never decided from its box (its voids have no answer)
                tops.append((top / zs) * (1 + 1e-12) + 1e-9 if info["nvalid"] == cells
                            and top is not None and math.isfinite(top) else inf)
        status = np.array(st, np.int8).reshape(nty, ntx)
        ztop = np.array(tops, np.float64).reshape(nty, ntx)
        # a block of heights per tile read, from a pool: the sweep reads only the tile
        # row it sweeps, and each half gives its own rows' blocks back once it leaves
        # them, so at most three tile rows hold blocks (the observer's, which both halves
        # read, and one for each half)
        side = (1 << g.t) + 1
        blocks = min(nty, 3) * ntx
        z = _scratch(blocks * side, side).reshape(blocks, side, side)
        slot = np.full((nty, ntx), -1, np.int64)
        self.tiles = SweepTiles(z, slot, status, ztop, np.full((nty, ntx), eps), r0, c0, g.t,
                                ty0, tx0, down - 1, across - 1)
        self._free = list(range(blocks - 1, -1, -1))  # the lowest block is taken first
        self.lock = threading.Lock()

    def height(self, r: int, c: int) -> float:
        """The height held for window cell (r, c) (metres; meaningful where its tile was
        read)."""
        tl = self.tiles
        ty = min((r + tl.r0) >> tl.t, tl.tlast_y) - tl.ty0
        tx = min((c + tl.c0) >> tl.t, tl.tlast_x) - tl.tx0
        return float(tl.z[tl.slot[ty, tx], r + tl.r0 - ((ty + tl.ty0) << tl.t),
                          c + tl.c0 - ((tx + tl.tx0) << tl.t)])

    def block(self, ty: int, tx: int) -> np.ndarray:
        """Window tile (ty, tx)'s block of heights, given it from the pool if it has none
        (call under :attr:`lock` where two halves read at once)."""
        tl = self.tiles
        b = int(tl.slot[ty, tx])
        if b < 0:
            if not self._free:  # the sweep reads three tile rows at most (see __init__)
                raise RuntimeError("the viewshed's window ran out of height blocks")
            b = tl.slot[ty, tx] = self._free.pop()
        return tl.z[b]

    def give_back(self, ty: int) -> None:
        """Return the blocks of window tile row ``ty`` to the pool: no sweep reads it
        again (call under :attr:`lock`)."""
        row = self.tiles.slot[ty]
        self._free.extend(int(b) for b in row[row >= 0][::-1])
        row[:] = -1

    @property
    def status(self) -> np.ndarray:
        return self.tiles.status

    def half(self, lo: int, hi: int, base: Half | None = None) -> Half:
        """A view that owns window rows ``lo`` … ``hi`` − 1, starting from a copy of the
        tiles' status and error as they stand in ``base`` (what it read is read for the
        new view too; None: nothing read)."""
        tl = self.tiles if base is None else base.tiles
        return Half(self, tl._replace(status=tl.status.copy(), zerr=tl.zerr.copy()), lo, hi)


class Half:
    """What one part of the sweep reads: its :class:`SweepTiles` and the window rows it
    writes (:meth:`read`). A half sweeps its rows outward, so once it asks for a tile of
    another tile row it is done with the row it was in: that row's blocks go back to
    the window's pool where the row is this half's alone."""

    def __init__(self, window: Window, tiles: SweepTiles, lo: int, hi: int):
        self.w, self.tiles, self.lo, self.hi = window, tiles, lo, hi
        self.row = -1  # the tile row it last read

    def _own(self, ty: int) -> bool:
        """Whether every window row of tile row ``ty`` is one of this half's."""
        tl, w = self.tiles, self.w
        g0 = (ty + tl.ty0) << tl.t
        g1 = g0 + (1 << tl.t) + (ty + tl.ty0 == tl.tlast_y)
        return max(g0, w.r0) - w.r0 >= self.lo and min(g1, w.r1) - w.r0 <= self.hi

    def _enter(self, ty: int) -> None:
        if ty != self.row:
            if self.row >= 0 and self._own(self.row):
                with self.w.lock:
                    self.w.give_back(self.row)
            self.row = ty

    def read(self, ty: int, tx: int, at: int | None = None,
             probe: tuple[int, float, float, float, float] | None = None) -> None:
        """Read window tile (``ty``, ``tx``) into this half's rows: at the window's level
        (``at`` None) or ``at``; at level 0 a tile not yet read is first bounded from level
        1 (status 3: the sweep may then decide its cells without level 0), unless the
        cell that asked for it (``probe``: window row, column, its lowest sight line,
        curvature drop and lift, :class:`~geoterrain.analysis.sweep.SweepState`) is not
        hidden by that bound either: the sweep would ask again from that very cell."""
        w, st = self.w, self.tiles.status
        at = w.level if at is None else at
        self._enter(ty)
        # the status is this half's own; only the terrain's reads and the blocks take
        # the lock
        if at == 0 and st[ty, tx] == 0 and self._bound_first(ty, tx, probe):
            return
        terrain = w.terrain
        ty0, tx0 = self.tiles.ty0, self.tiles.tx0
        a0, a1, b0, b1 = self._cells(ty, tx)
        gy, gx = (ty + ty0) << self.tiles.t, (tx + tx0) << self.tiles.t
        zm = terrain.frame.z_to_m
        key = (at, (tx + tx0) >> at, (ty + ty0) >> at)
        err = terrain.tile_info[key]["error"] if key in terrain.tile_info else np.inf
        if at == 0 or not math.isfinite(err):
            with w.lock:
                tile = terrain.tile(0, tx + tx0, ty + ty0)
                z = w.block(ty, tx)[a0 - gy:a1 - gy, b0 - gx:b1 - gx]
            np.multiply(tile.heights[a0 - gy:a1 - gy, b0 - gx:b1 - gx], zm, out=z)
        else:
            with w.lock:
                z = w.block(ty, tx)[a0 - gy:a1 - gy, b0 - gx:b1 - gx]
            np.multiply(level_surface(terrain, at, np.arange(a0, a1), np.arange(b0, b1),
                                      w.lock), zm, out=z)
            zs = terrain.frame.z_scale or 1.0
            self.tiles.zerr[ty, tx] = w.eps + err / zs * (1 + 1e-12) + 1e-9
        st[ty, tx] = 1

    def _cells(self, ty: int, tx: int) -> tuple[int, int, int, int]:
        """The grid rows a0 … a1 − 1 and columns b0 … b1 − 1 the sweep takes from the
        tile, within this half's rows: the tile's rows and columns but the last, which its
        neighbour owns (sweep._tile_of), except on the grid's last tile."""
        tl, w = self.tiles, self.w
        span = 1 << tl.t
        gy, gx = (ty + tl.ty0) * span, (tx + tl.tx0) * span
        a0 = max(gy, w.r0 + self.lo)
        a1 = min(gy + span + (ty + tl.ty0 == tl.tlast_y), w.r0 + self.hi)
        b0, b1 = max(gx, w.c0), min(gx + span + (tx + tl.tx0 == tl.tlast_x), w.c1)
        return a0, max(a1, a0), b0, b1

    def _bound_first(self, ty: int, tx: int, probe=None) -> bool:
        """Level 1's surface plus its tile's error as the cells' bounds (status 3), when
        that error is finite and hides the probed cell (if any)."""
        w, tl = self.w, self.tiles
        terrain = w.terrain
        key = (1, (tx + tl.tx0) >> 1, (ty + tl.ty0) >> 1)
        if terrain.grid.top_level < 1 or key not in terrain.tile_info:
            return False
        err = terrain.tile_info[key]["error"]
        if not math.isfinite(err):
            return False
        zs = terrain.frame.z_scale or 1.0
        with w.lock:
            tile = terrain.tile(*key)  # its heights are NaN where not valid
            blk = w.block(ty, tx) if probe is None else None
        g, zm, lift = terrain.grid, terrain.frame.z_to_m, err / zs * (1 + 1e-12) + 1e-9
        org = (key[2] << g.t, key[1] << g.t)
        if probe is not None:  # the asking cell first: the same test as the sweep's
            r, c, lo, drop, up = probe
            v = _union_jack_one(tile.heights, 1, *org, r + w.r0, int(c) + w.c0)
            if not v * zm + lift - drop + up < lo:
                return False
        a0, a1, b0, b1 = self._cells(ty, tx)
        gy, gx = (ty + tl.ty0) << tl.t, (tx + tl.tx0) << tl.t
        if blk is None:
            with w.lock:
                blk = w.block(ty, tx)
        z = blk[a0 - gy:a1 - gy, b0 - gx:b1 - gx]
        # NaN where level 1 has no data: the sweep then reads level 0 (a void's code)
        _union_jack_into(tile.heights, 1, *org, a0, b0, zm, lift, z)
        tl.status[ty, tx] = 3
        return True


def _scratch(rows: int, cols: int) -> np.ndarray:
    """An uninitialised (rows, cols) float64 array in ordinary pages, mapped afresh (above
    64 KiB): the blocks are written only where a tile is read, numpy's huge pages would
    have the kernel zero 2 MiB at the first touch of each, and memory the allocator kept
    from an earlier viewshed would spare a benchmark's cold run the first touches that
    a viewshed in a fresh process pays."""
    n = rows * cols * 8
    if n < 1 << 16:
        return np.empty((rows, cols))
    m = mmap.mmap(-1, n)
    with contextlib.suppress(AttributeError, OSError):  # not Linux: whatever it gives
        m.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(m, np.float64).reshape(rows, cols)


def level_surface(terrain: TerrainLike, level: int, rows: np.ndarray, cols: np.ndarray,
                  lock: threading.Lock | None = None) -> np.ndarray:
    """The level-L union-jack surface (source units; NaN on cells without data) at the
    full-resolution samples ``rows`` × ``cols`` (ascending runs), which one level-L tile
    holds; its tile is read under ``lock`` where one is given.

    Examples
    --------
    >>> rows = cols = np.arange(0, 9)
    >>> s = level_surface(t, 2, rows, cols)
    >>> bool(s[4, 4] == t.tile(0, 0, 0).heights[4, 4])  # a level-2 sample itself
    True
    """
    g = terrain.grid
    out = np.full((len(rows), len(cols)), np.nan)
    if len(rows) == 0 or len(cols) == 0:
        return out
    R, C = g.level_shape(level)  # S × S, or a root grid's level
    key = (level, int(min(cols[0] >> level, C - 2) >> g.t),
           int(min(rows[0] >> level, R - 2) >> g.t))
    if key not in terrain.tile_info:
        return out
    with lock or contextlib.nullcontext():
        tile = terrain.tile(*key)  # its heights are NaN where not valid
    _union_jack_block(tile.heights, level, key[2] << g.t, key[1] << g.t,
                      np.asarray(rows, np.int64), np.asarray(cols, np.int64), out)
    return out


def _union_jack_one(h: np.ndarray, level: int, a_org: int, b_org: int, row: int,
                    col: int) -> float:
    """:func:`_union_jack_into`'s surface at one sample, in Python: the same float
    operations in the same order (a compiled call costs more than the arithmetic)."""
    n = h.shape[0] - 2
    sz = 1 << level
    a = min((row >> level) - a_org, n)
    di = (row - ((a + a_org) << level)) / sz
    b = min((col >> level) - b_org, n)
    dj = (col - ((b + b_org) << level)) / sz
    z00, z01 = float(h[a, b]), float(h[a, b + 1])
    z10, z11 = float(h[a + 1, b]), float(h[a + 1, b + 1])
    if (a + a_org + b + b_org) % 2 == 0:  # main diagonal (0, 0)–(1, 1)
        if dj >= di:
            return z00 + (z01 - z00) * dj + (z11 - z01) * di
        return z00 + (z10 - z00) * di + (z11 - z10) * dj
    if di + dj <= 1:
        return z00 + (z10 - z00) * di + (z01 - z00) * dj
    return z11 + (z01 - z11) * (1 - di) + (z10 - z11) * (1 - dj)


@njit(cache=True, nogil=True, inline="always")
def _union_jack_cell(h, a, b, main, di, dj):
    """The union-jack surface in cell (a, b) of tile heights ``h`` at fraction (di, dj)
    of the cell: its two triangles split by the main diagonal (0, 0)–(1, 1) when ``main``,
    else by the other (docs/conventions.md)."""
    z00 = h[a, b]
    z01 = h[a, b + 1]
    z10 = h[a + 1, b]
    z11 = h[a + 1, b + 1]
    if main:
        if dj >= di:
            return z00 + (z01 - z00) * dj + (z11 - z01) * di
        return z00 + (z10 - z00) * di + (z11 - z10) * dj
    if di + dj <= 1:
        return z00 + (z10 - z00) * di + (z01 - z00) * dj
    return z11 + (z01 - z11) * (1 - di) + (z10 - z11) * (1 - dj)


@njit(cache=True, nogil=True)
def _union_jack_into(h, level, a_org, b_org, a0, b0, scale, add, out):
    """out[k, m] = the level-L union-jack surface of tile heights ``h`` at full-resolution
    sample (a0 + k, b0 + m) (:func:`_union_jack_block`) × ``scale`` + ``add``: the surface
    in metres lifted by its error, written where the sweep reads it."""
    n = h.shape[0] - 2
    sz = 1 << level
    ncol = out.shape[1]
    bs = np.empty(ncol, np.int64)
    djs = np.empty(ncol)
    for m in range(ncol):
        b = min(((b0 + m) >> level) - b_org, n)
        bs[m] = b
        djs[m] = (b0 + m - ((b + b_org) << level)) / sz
    for k in range(out.shape[0]):
        a = min(((a0 + k) >> level) - a_org, n)
        di = (a0 + k - ((a + a_org) << level)) / sz
        for m in range(ncol):
            b = bs[m]
            dj = djs[m]
            v = _union_jack_cell(h, a, b, (a + a_org + b + b_org) % 2 == 0, di, dj)
            out[k, m] = v * scale + add


@njit(cache=True, nogil=True)
def _union_jack_block(h, level, a_org, b_org, rows, cols, out):
    """out[k, l] = the level-L union-jack surface of tile heights ``h`` (its first sample
    at level-L row ``a_org``, column ``b_org``) at full-resolution sample (rows[k],
    cols[l]) (docs/conventions.md: a cell's diagonal by the parity of its indices; a
    sample on the tile's far edge is read from the tile's last cell, which gives it)."""
    n = h.shape[0] - 2
    sz = 1 << level
    for k in range(rows.shape[0]):
        a = min((rows[k] >> level) - a_org, n)
        di = (rows[k] - ((a + a_org) << level)) / sz
        for m in range(cols.shape[0]):
            b = min((cols[m] >> level) - b_org, n)
            dj = (cols[m] - ((b + b_org) << level)) / sz
            v = _union_jack_cell(h, a, b, (a + a_org + b + b_org) % 2 == 0, di, dj)
            out[k, m] = v

"""Geometry clipmaps' data (seed 000 §2.9, Losasso & Hoppe): what a terrain's clipmaps
derive once (which cells no-data sends to finer levels, the dense tile table, the
spacing) and each level's toroidal height and normal buffers, moved by reading only the
L-shaped band of samples a move exposes (§2.9: "only the new L-shaped region").

:mod:`geoterrain.lod.clipmaps` chooses the levels and regions and draws them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.lod.tiles import TileIndex, tile_index, tile_table

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

# ------------------------------------------------------------------ per-terrain tables
class Tables:
    """What a terrain's clipmaps derive once: per level, which cells must be drawn finer
    (``refine[l]``, level-l cells, True: drawn by level l − 1), the dense tile table, the
    data rectangle, the grid spacing. ``NR`` × ``N``: the samples the levels span (a
    square's N × N, a root grid's extent; ``N`` is also the stride of the keys i·N + j),
    ``tiles[L]``: each level's tiles (across, down)."""

    def __init__(self, terrain: TerrainLike, index: TileIndex, bounded: bool):
        g = terrain.grid
        NR, N = g.extent
        self.N, self.NR, self.n, self.t, self.top = N, NR, g.n, g.t, g.top_level
        self.tiles = [g.tiles(L) for L in g.levels]
        self.H, self.W = g.rows, g.cols
        h, v = terrain.level_heights(0)
        # a cell's closed footprint: any sample valid / any not (the four corners at level 0)
        anyv = v[:-1, :-1] | v[1:, :-1] | v[:-1, 1:] | v[1:, 1:]
        anyi = ~(v[:-1, :-1] & v[1:, :-1] & v[:-1, 1:] & v[1:, 1:])
        self.table, self.base = tile_table(index, g.top_level, g)
        err = index.error
        self.refine = [np.zeros((0, 0), bool)]
        prev = np.zeros(anyv.shape, bool)  # level 0 is never refined
        for lv in range(1, g.n + 1):
            anyv = _or4(anyv)
            anyi = _or4(anyi)
            m = anyv & anyi
            if bounded and lv <= g.top_level:  # cells of tiles with no finite error
                k = index.keys
                rows = np.flatnonzero((k[:, 0] == lv) & ~np.isfinite(err))
                if len(rows):
                    bad = np.zeros(g.tiles(lv)[::-1], bool)  # (down, across)
                    bad[k[rows, 2], k[rows, 1]] = True
                    c = 1 << g.t
                    m |= np.repeat(np.repeat(bad, c, 0), c, 1)[: m.shape[0], : m.shape[1]]
            m |= _or4(prev) | _touches(prev)
            self.refine.append(m)
            prev = m
        del h
        f = terrain.frame
        i = np.array([0, 0, NR - 1])
        j = np.array([0, N - 1, 0])
        x, y = f.xy(i, j)
        self.dx = float(min(np.hypot(x[1] - x[0], y[1] - y[0]) / (N - 1),
                            np.hypot(x[2] - x[0], y[2] - y[0]) / (NR - 1)))
        if f.kind == "geographic":  # the narrowest spacing over the grid, for distances
            step = max(1, max(NR, N) // 64)
            X, Y = f.xy(*np.meshgrid(np.arange(0, NR, step), np.arange(0, N, step),
                                     indexing="ij"))
            sx = np.hypot(np.diff(X, axis=1), np.diff(Y, axis=1)).min()
            sy = np.hypot(np.diff(X, axis=0), np.diff(Y, axis=0)).min()
            self.dx = float(min(sx, sy) / step)


def _or4(a: np.ndarray) -> np.ndarray:
    """The next coarser level's cells: OR of each 2 × 2 group (odd sizes padded False)."""
    r, c = a.shape
    if r % 2 or c % 2:
        a = np.pad(a, ((0, r % 2), (0, c % 2)))
    return a[0::2, 0::2] | a[1::2, 0::2] | a[0::2, 1::2] | a[1::2, 1::2]


def _touches(m: np.ndarray) -> np.ndarray:
    """Coarser cells that share an edge with a finer cell of ``m`` lying on the coarser
    cell's border: those would meet a region two levels finer."""
    r, c = m.shape
    if r % 2 or c % 2:
        m = np.pad(m, ((0, r % 2), (0, c % 2)))
    R, C = m.shape[0] // 2, m.shape[1] // 2
    out = np.zeros((R, C), bool)
    top = m[0::2, 0::2] | m[0::2, 1::2]  # fine cells on each coarse cell's top row
    bot = m[1::2, 0::2] | m[1::2, 1::2]
    left = m[0::2, 0::2] | m[1::2, 0::2]
    right = m[0::2, 1::2] | m[1::2, 1::2]
    out[:-1, :] |= top[1:, :]  # the coarse cell above a top-row fine cell
    out[1:, :] |= bot[:-1, :]
    out[:, :-1] |= left[:, 1:]
    out[:, 1:] |= right[:, :-1]
    return out


def tables(terrain: TerrainLike, bounded: bool) -> Tables:
    """The terrain's :class:`Tables` (built once per terrain and mode).

    Examples
    --------
    >>> tb = tables(t, False)
    >>> len(tb.refine) == t.grid.n + 1
    True
    """
    index = tile_index(terrain)
    return terrain.derived(f"{__name__}.tables{int(bounded)}",
                           lambda: Tables(terrain, index, bounded))


# ------------------------------------------------------------------ toroidal buffers
@dataclass
class Level:
    """One level's toroidal buffers and the region they hold (level-l vertex indices,
    inclusive ``r0 … r1``, ``c0 … c1``)."""

    size: int
    z: np.ndarray = field(default=None)
    normal: np.ndarray = field(default=None)
    r0: int = 0
    r1: int = -1
    c0: int = 0
    c1: int = -1


def _heights(terrain: TerrainLike, index: TileIndex, lv: int, rr: np.ndarray, cc: np.ndarray
             ) -> np.ndarray:
    """Scene z of the level-``lv`` samples rr × cc (level indices), from the stored tiles
    (a level above the top: every 2^(lv − top)-th sample of the top tile)."""
    g = terrain.grid
    top = g.top_level
    L = min(lv, top)
    k = 1 << (lv - L)
    R, C = rr * k, cc * k  # indices at level L
    out = np.full((len(rr), len(cc)), np.nan)
    s = 1 << g.t
    across, down = g.tiles(L)
    ty = np.minimum(R // s, max(down - 1, 0))
    tx = np.minimum(C // s, max(across - 1, 0))
    for y in np.unique(ty).tolist():
        ri = np.flatnonzero(ty == y)
        for x in np.unique(tx).tolist():
            if (L, x, y) not in index.row:
                continue
            ci = np.flatnonzero(tx == x)
            h = terrain.tile(L, x, y).heights
            out[np.ix_(ri, ci)] = h[np.ix_(R[ri] - y * s, C[ci] - x * s)]
    return terrain.frame.z(out)


def _normals(z: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """Unit normals of a height patch by central differences (one-sided at its border)."""
    gy, gx = np.gradient(z, sy, sx)
    nrm = np.stack([-gx, gy, np.ones_like(z)], -1)
    return (nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)).astype(np.float32)


def update_level(terrain: TerrainLike, index: TileIndex, st: Level, lv: int, r0: int, r1: int,
                 c0: int, c1: int, spacing: float) -> tuple[int, int]:
    """Move level ``lv``'s region to r0 … r1 × c0 … c1, reading only the samples it did
    not hold (the L-shaped ring a move exposes) into the toroidal buffers, and
    recomputing the normals there and beside them. Returns (heights, normals) updated."""
    n = st.size
    if st.z is None:
        st.z = np.full((n, n), np.nan)
        st.normal = np.zeros((n, n, 3), np.float32)
    rows = np.arange(r0, r1 + 1)
    cols = np.arange(c0, c1 + 1)
    old_r = (rows >= st.r0) & (rows <= st.r1)
    old_c = (cols >= st.c0) & (cols <= st.c1)
    new = ~(old_r[:, None] & old_c[None, :])
    if not new.any():
        st.r0, st.r1, st.c0, st.c1 = r0, r1, c0, c1
        return 0, 0
    # the exposed samples: whole new rows, and the new columns of the kept rows
    nr = rows[~old_r]
    nc = cols[~old_c]
    if len(nr):
        st.z[np.ix_(nr % n, cols % n)] = _heights(terrain, index, lv, nr, cols)
    kr = rows[old_r]
    if len(nc) and len(kr):
        st.z[np.ix_(kr % n, nc % n)] = _heights(terrain, index, lv, kr, nc)
    n_h = int(new.sum())
    # normals: the exposed samples and those one step inside (their differences changed)
    grow = new.copy()
    grow[1:] |= new[:-1]
    grow[:-1] |= new[1:]
    grow[:, 1:] |= new[:, :-1]
    grow[:, :-1] |= new[:, 1:]
    ii, jj = np.nonzero(grow)
    a0, a1 = max(ii.min() - 1, 0), min(ii.max() + 1, len(rows) - 1)
    b0, b1 = max(jj.min() - 1, 0), min(jj.max() + 1, len(cols) - 1)
    zz = st.z[np.ix_(rows[a0:a1 + 1] % n, cols[b0:b1 + 1] % n)]
    nrm = _normals(zz, spacing, spacing)
    sel = grow[a0:a1 + 1, b0:b1 + 1]
    gi, gj = np.nonzero(sel)
    st.normal[rows[a0 + gi] % n, cols[b0 + gj] % n] = nrm[gi, gj]
    st.r0, st.r1, st.c0, st.c1 = r0, r1, c0, c1
    return n_h, int(sel.sum())


def buffer_heights(st: Level, r: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Heights of level samples (r, c) from the level's toroidal buffer."""
    return st.z[r % st.size, c % st.size]

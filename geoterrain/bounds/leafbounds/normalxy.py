"""The scene x, y a tile's normals are derived from on read (:func:`normal_xy`,
:func:`normal_axes`), and what a reader derives at a level's border rings from them
(:func:`ring_guesses`), which a writer stores the rings' codes as differences from."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["NORMAL_XY_NODES", "NORMAL_XY_TOLERANCE", "normal_axes", "normal_xy",
           "ring_guesses"]


def normal_xy(terrain: TerrainLike, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
    """Scene X, Y (T, T) from which a tile's normals are derived on read.

    In a projected or pixel frame, the preprocess's values (:meth:`Frame.axis_xy`, as
    :meth:`Frame.grid_xy`'s), so the derived codes are its codes. In a geographic frame,
    pyproj at ``NORMAL_XY_NODES`` × ``NORMAL_XY_NODES`` nodes of the tile only (every 8
    samples of a 65² tile), bilinear between them: a sample's own pyproj call would cost
    about 2.6 ms a 65² tile, 20× the stored read. The bilinear positions are off by the
    projection's curvature over a node cell, far under a normal code's resolution
    (tested: a code or its neighbour); the border ring, which the preprocess stores
    from the full map, keeps its exact codes. pyproj at the cells' centres checks the
    interpolation: where it strays (a tile next to a pole, where latitudes clamp, or at
    the scene frame's antipode), the tile's own x, y (:meth:`Terrain.tile_xy`), and so
    the full map's codes.

    Examples
    --------
    >>> X, Y = normal_xy(t, 0, 0, 0)
    >>> X.shape == (t.grid.tile_samples,) * 2
    True
    """
    g = terrain.grid
    if terrain.frame.kind != "geographic":
        # the preprocess's grid_xy values as broadcast views: no T² positions to compute
        # for every tile shaded
        T = g.tile_samples
        xs, ys = normal_axes(terrain, level, x, y)
        return np.broadcast_to(xs[None, :], (T, T)), np.broadcast_to(ys[:, None], (T, T))
    T = g.tile_samples
    m = min(T, NORMAL_XY_NODES)  # nodes a side: every (T − 1) / (m − 1) samples
    w = (T - 1) // (m - 1)
    if w == 1:  # a node on every sample: exact
        return terrain.tile_xy(level, x, y)
    k = np.arange(m) * w
    rows, cols = g.tile_rows(level, y), g.tile_cols(level, x)
    # pyproj at the nodes and at the cells' centres, which check the interpolation
    kc = k[:-1] + w // 2
    pick = np.concatenate([k, kc])
    ii, jj = np.meshgrid(rows[pick], cols[pick], indexing="ij")
    px, py = (np.asarray(v, np.float64) for v in terrain.frame.xy(ii, jj))
    cx, cy = px[:m, :m], py[:m, :m]
    X, Y = _bilinear(cx, k, T), _bilinear(cy, k, T)
    # where the frame bends within a cell (next to a pole, where latitudes clamp, or
    # the scene frame's antipode) the bilinear x, y stray: then the tile's own
    step = min(np.hypot(np.diff(cx, axis=1), np.diff(cy, axis=1)).min(),
               np.hypot(np.diff(cx, axis=0), np.diff(cy, axis=0)).min()) / w
    off = max(np.abs(X[np.ix_(kc, kc)] - px[m:, m:]).max(),
              np.abs(Y[np.ix_(kc, kc)] - py[m:, m:]).max())
    if not (np.isfinite(off) and step > 0 and off <= NORMAL_XY_TOLERANCE * w * step):
        return terrain.tile_xy(level, x, y)
    return X, Y


def normal_axes(terrain: TerrainLike, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
    """A projected or pixel frame's :func:`normal_xy` as its two axes: X (T,) of the
    tile's columns and Y (T,) of its rows (:meth:`Frame.axis_xy`'s values), cached by
    tile column and row (a frame's new tiles share them).

    Examples
    --------
    >>> xs, ys = normal_axes(t, 0, 0, 0)
    >>> xs.shape == ys.shape == (t.grid.tile_samples,)
    True
    """
    g, f = terrain.grid, terrain.frame
    xs = terrain.memo(("normal_x", level, x), lambda: f.axis_xy(
        g.tile_rows(level, 0)[:1], g.tile_cols(level, x))[0][0])
    ys = terrain.memo(("normal_y", level, y), lambda: f.axis_xy(
        g.tile_rows(level, y), g.tile_cols(level, 0)[:1])[1][:, 0])
    return xs, ys


class _Layout:
    """What :func:`normal_xy` and :func:`normal_axes` read of a terrain, for a writer
    that has no store yet: the grid, the frame, a tile's x, y and a memo."""

    def __init__(self, grid, frame) -> None:
        self.grid, self.frame = grid, frame
        self._memo: dict = {}

    def memo(self, key, make):
        got = self._memo.get(key)
        if got is None:
            got = self._memo[key] = make()
        return got

    def tile_xy(self, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
        g = self.grid
        ii, jj = np.meshgrid(g.tile_rows(level, y), g.tile_cols(level, x), indexing="ij")
        return self.frame.xy(ii, jj)


def ring_guesses(grid, frame, level: int, tiles: list[tuple[int, int]], z: np.ndarray,
                 valid: np.ndarray, origins: np.ndarray, bits: int = 8,
                 chunk: int = 64) -> np.ndarray:
    """What a reader derives at the border rings of level ``level``'s tiles ``tiles``
    ((x, y) each) before it sets their stored codes (:func:`geoterrain.bounds.normals.ring_guess`
    on the x, y of :func:`normal_xy`, or :func:`normal_axes` on a projected or pixel
    frame): (k, 4T − 4, 2) codes, from the level's scene heights ``z`` and mask ``valid``
    (a window of its lattice; tile k's first sample at ``origins[k]`` = row, column).
    A writer stores each ring as its difference from them (schema 17).

    Examples
    --------
    >>> from geoterrain.core.grid import Grid
    >>> from geoterrain.core.frame import Frame
    >>> g = Grid(5, 5, 2, 2); z = np.arange(25.0).reshape(5, 5)
    >>> ring_guesses(g, Frame.pixel(5, 5, 1.0), 0, [(0, 0)], z, np.ones((5, 5), bool),
    ...              np.zeros((1, 2), np.int64)).shape
    (1, 16, 2)
    """
    from geoterrain.bounds.normalbytes import ring_index
    from geoterrain.bounds.normals import ring_guess

    T = grid.tile_samples
    lay = _Layout(grid, frame)
    ring = ring_index(T)
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    out = np.empty((len(o), len(ring[0]), 2), np.uint8 if bits == 8 else np.uint16)
    if frame.kind != "geographic":  # x by column, y by row: broadcast, no T² copies
        # every tile's axes in one call (normal_axes' values: X of a column and Y of a row
        # are element-wise affine maps, the same bits whatever the array they are in)
        k = len(o)
        txy = np.asarray(tiles, np.int64).reshape(-1, 2)
        idx = np.arange(T)
        cols = ((txy[:, 0, None] << grid.t) + idx) << level
        rows = ((txy[:, 1, None] << grid.t) + idx) << level
        zero = np.zeros(1, np.int64)  # normal_axes' row 0 for X, column 0 for Y
        xs = frame.axis_xy(zero, cols.ravel())[0][0].reshape(-1, T)
        ys = frame.axis_xy(rows.ravel(), zero)[1][:, 0].reshape(-1, T)
        return ring_guess(z, valid, np.broadcast_to(xs[:, None, :], (k, T, T)),
                          np.broadcast_to(ys[:, :, None], (k, T, T)), ring, bits, o)
    for a in range(0, len(o), chunk):
        b = min(a + chunk, len(o))
        X = np.empty((b - a, T, T))
        Y = np.empty((b - a, T, T))
        for k in range(a, b):
            X[k - a], Y[k - a] = normal_xy(lay, level, *tiles[k])
        out[a:b] = ring_guess(z, valid, X, Y, ring, bits, o[a:b])
    return out


NORMAL_XY_NODES = 9  # pyproj nodes a side of a tile for its derived normals' x, y
# a cell centre's bilinear x, y may be off by this × the cell's width in samples × the
# sample spacing: a parabolic bump that size tilts the tangents by under 10⁻³ rad
NORMAL_XY_TOLERANCE = 2e-4


def _bilinear(c: np.ndarray, k: np.ndarray, T: int) -> np.ndarray:
    """(T, T) values bilinear between node values ``c`` (m, m) at sample offsets ``k``."""
    s = np.arange(T)
    cell = np.minimum(np.searchsorted(k, s, side="right") - 1, len(k) - 2)
    f = (s - k[cell]) / (k[cell + 1] - k[cell])
    a, b = cell[:, None], cell[None, :]
    fa, fb = f[:, None], f[None, :]
    top = c[a, b] + (c[a, b + 1] - c[a, b]) * fb
    bot = c[a + 1, b] + (c[a + 1, b + 1] - c[a + 1, b]) * fb
    return top + (bot - top) * fa

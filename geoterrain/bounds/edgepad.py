"""Padding by edge replication: the second δ that lets the static mesh cross the data's edge.

A DEM of H × W samples sits at the top-left of the padded (2^n+1)² grid (docs/conventions.md).
Its padding is nodata, so every diamond that mixes data and padding has δ = +inf (seed 002
§2.3 with the nodata rule of :mod:`geoterrain.bounds.delta`) and the static mesh is refined to full
resolution all along the DEM's right and bottom edges. At a coarse error that border is
most of the mesh (Fuji at e = 100: 2 296 of 3 770 triangles).

Martini instead pads by repeating the last row and column. This module gives the static
mesh that choice without changing anything else:

- :func:`edge_support` builds the replicated grid: heights and validity of the padding
  copied from the nearest sample of the last data row or column (a nodata sample there
  makes its copies nodata, and the nodata rule applies to them).
- :func:`edge_deltas`: the exact raw δ of seed 002 §2.3 over that grid, set to 0 on the
  vertices whose diamond holds no data sample (their error is never seen: the mesh is
  clipped to the data), then saturated (§2.4). It measures the padding samples of the
  other diamonds too, which only makes it larger than the data alone needs.
- A vertex with δ_edge > 0 lies within twice its diamond's size of the data, but not
  always in a stored tile (the data may end just before a tile boundary; saturation
  lifts a vertex whose diamond misses the data when a child's reaches it).
  :func:`edge_only_tiles` lists the unstored tiles holding such a vertex: they get a
  ``delta_edge`` blob of their own (a whole tile, no parent to read) and nothing else.
- :func:`edge_tiles` lists the stored tiles whose δ_edge, as stored, differs from δ on
  the vertices the tile's blob holds (below the top level, those new at its level; the
  others are its parent's). Only those get a second δ blob (``delta_edge``); a reader
  decodes any other tile's δ blob over its parent's δ_edge, which gives the same values.
  Both are coded with one table, so they agree bit for bit wherever the raw values do,
  and the saturated order of δ_edge holds across the two kinds of tile.

The static mesh of δ_edge > e, with each padding vertex at its replicated height and
clipped to the data's rectangle (:mod:`geoterrain.lod.clip`), has vertical error ≤ e at
every valid sample: the clip keeps each triangle's plane, so a sample is interpolated as
before. Views (every other strategy) keep the nodata rule.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.core.grid import Grid

__all__ = ["edge_deltas", "edge_only_tiles", "edge_support", "edge_tiles", "has_padding",
           "zero_beyond_data"]


def has_padding(grid: Grid) -> bool:
    """Whether the DEM leaves padding in its (2^n+1)² grid (a root grid: its extent).

    Examples
    --------
    >>> has_padding(Grid.for_shape(512, 512)), has_padding(Grid.for_shape(513, 513))
    (True, False)
    >>> has_padding(Grid.for_shape(513, 1025, roots=True))
    False
    """
    R, C = grid.extent
    return grid.rows < R or grid.cols < C


@njit(cache=True, nogil=True, inline="always")
def _reaches_data(i, j, rows, cols):
    """Whether the diamond of vertex (i, j) (inside its box ± h, h the lowest set bit of
    i | j) holds a sample of the data's rows × cols."""
    h = i | j
    if h == 0:
        return True
    h = h & -h
    return i - h <= rows - 1 and j - h <= cols - 1


@njit(cache=True, nogil=True)
def zero_beyond_data(a, rows, cols):
    """Set ``a`` (N, N), or a root grid's extent, to 0 on the padding vertices whose
    diamond holds no data sample."""
    R, C = a.shape
    for i in range(R):
        j0 = cols if i < rows else 0
        for j in range(j0, C):
            if not _reaches_data(i, j, rows, cols):
                a[i, j] = 0


def edge_deltas(Zr: np.ndarray, ok: np.ndarray, grid: Grid) -> np.ndarray:
    """δ_edge (float32 (N, N), rounded up): the exact raw δ over the replicated grid of
    :func:`edge_support`, 0 where a vertex's diamond misses the data, then saturated.

    Examples
    --------
    >>> g = Grid.for_shape(3, 2, tile_size=2)
    >>> Z = g.pad(np.array([[0.0, 0.0], [0.0, 4.0], [0.0, 0.0]]), np.nan)
    >>> Zr, ok = edge_support(Z, np.isfinite(Z), g)
    >>> edge_deltas(Zr, ok, g).tolist()  # (1, 2): the replicated 4 against the chord's 0
    [[0.0, 0.0, 0.0], [0.0, 4.0, 4.0], [0.0, 0.0, 0.0]]
    """
    from geoterrain.bounds.delta import _raw_delta, check_grid, saturate
    from geoterrain.core.threads import cores_for

    zf, okc, n = check_grid(Zr, ok, grid.span)
    with cores_for(zf.size):
        raw = _raw_delta(zf, okc, 1 << n)
        zero_beyond_data(raw, grid.rows, grid.cols)
        return saturate(raw, 1 << n)


def edge_support(Z: np.ndarray, valid: np.ndarray, grid: Grid
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Heights and validity of the padded grid with the padding replicated from the edge.

    Parameters
    ----------
    Z, valid : (N, N) padded heights (any value where invalid) and validity.
    grid : the store's grid (the data is its top-left ``rows × cols``).

    Examples
    --------
    >>> g = Grid.for_shape(2, 2, tile_size=2)
    >>> Z = g.pad(np.array([[1.0, 2.0], [3.0, 4.0]]), np.nan)
    >>> Zr, ok = edge_support(Z, np.isfinite(Z), g)
    >>> Zr.tolist(), bool(ok.all())
    ([[1.0, 2.0, 2.0], [3.0, 4.0, 4.0], [3.0, 4.0, 4.0]], True)
    """
    H, W = grid.rows, grid.cols
    Zr = np.array(Z, np.float64)
    ok = np.array(valid, bool)
    Zr[:H, W:] = Zr[:H, W - 1:W]
    ok[:H, W:] = ok[:H, W - 1:W]
    Zr[H:] = Zr[H - 1]
    ok[H:] = ok[H - 1]
    Zr[~ok] = np.nan
    return Zr, ok


def _holding(mark: np.ndarray, grid: Grid) -> list[np.ndarray]:
    """Per level L, the (tiles down, tiles across) bool of the tiles whose stored
    vertices (below the top level, those new at L; the others are the parent's) include
    a marked sample of the (N, N) ``mark`` (a root grid: its extent; the grid's
    ``tiles(L)`` kept): block ``any`` over each tile's closed footprint on level L's
    lattice."""
    T1 = grid.tile_samples - 1
    out = []
    for L in grid.levels:
        s = 1 << L
        lat = mark[::s, ::s]
        ny, nx = (lat.shape[0] - 1) // T1, (lat.shape[1] - 1) // T1
        if L < grid.top_level:
            lat = lat.copy()
            lat[::2, ::2] = False
        held = lat[:-1, :-1].reshape(ny, T1, nx, T1).any(axis=(1, 3))
        held |= lat[T1::T1, :-1].reshape(ny, nx, T1).any(axis=2)  # each tile's last row
        held |= lat[:-1, T1::T1].reshape(ny, T1, nx).any(axis=1)  # and last column
        held |= lat[T1::T1, T1::T1]
        tx, ty = grid.tiles(L)
        out.append(held[:ty, :tx])
    return out


def edge_tiles(d_codes: np.ndarray, de_codes: np.ndarray, grid: Grid,
               keys: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    """The tiles ``keys`` (L, x, y) whose stored vertices (below the top level, those new
    at the level) have a δ_edge that differs from their δ, as stored (codes of one
    table, or values).

    Examples
    --------
    >>> g = Grid.for_shape(5, 5, tile_size=2)
    >>> d = np.zeros((5, 5), np.uint8); de = d.copy(); de[4, 4] = 1
    >>> edge_tiles(d, de, g, [(0, 0, 0), (0, 1, 1), (1, 0, 0)])
    [(1, 0, 0)]
    >>> de[3, 4] = 1
    >>> edge_tiles(d, de, g, [(0, 0, 0), (0, 1, 1), (1, 0, 0)])
    [(0, 1, 1), (1, 0, 0)]
    """
    held = _holding(d_codes != de_codes, grid)
    return [(L, x, y) for L, x, y in keys if held[L][y, x]]


def edge_only_tiles(de_codes: np.ndarray, grid: Grid,
                    stored: set) -> list[tuple[int, int, int]]:
    """The tiles (L, x, y) not in ``stored`` whose stored vertices hold a δ_edge > 0
    (codes or values): the static mesh may need them.

    Examples
    --------
    >>> g = Grid.for_shape(5, 5, tile_size=2)
    >>> de = np.zeros((5, 5), np.uint8); de[3, 3] = 1
    >>> edge_only_tiles(de, g, {(1, 0, 0)})
    [(0, 1, 1)]
    """
    out = []
    for L, held in enumerate(_holding(de_codes > 0, grid)):
        out += [(L, int(x), int(y)) for y, x in np.argwhere(held) if (L, x, y) not in stored]
    return out

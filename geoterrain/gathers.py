"""Per-vertex arrays and whole grids gathered from a terrain's decoded tiles, as functions
over :class:`~geoterrain.terrainlike.TerrainLike`: each vertex read from the coarsest
tile that holds it, and only the tiles holding what is asked for decoded.

:class:`geoterrain.terrain.Terrain`'s ``vertex_level``, ``gather``, ``tile_stacks``,
``level_heights`` and ``scene_xyz`` forward here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["gather", "level_heights", "scene_xyz", "tile_stacks", "vertex_level"]


# ------------------------------------------------------- per-vertex data
def vertex_level(terrain: TerrainLike, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The coarsest pyramid level holding samples (i, j) (:func:`bintree.vertex_level`).

    Examples
    --------
    >>> t.grid.top_level, vertex_level(t, np.array([0, 4, 5]), np.array([0, 8, 5])).tolist()
    (2, [2, 2, 0])
    """
    from geoterrain.core.bintree import vertex_level

    return vertex_level(i, j, terrain.grid.top_level)


def gather(terrain: TerrainLike, i: np.ndarray, j: np.ndarray,
           kinds: Sequence[str] = ("delta", "radius", "height")) -> dict[str, np.ndarray]:
    """Per-vertex arrays at full-resolution samples (i, j), read from the coarsest tiles.

    ``kinds``: any of delta, radius, height (source units), x, y (scene).
    Only the tiles holding the requested vertices are decoded. Vertices in
    tiles that are not stored (no valid data) get δ = r = 0 and height NaN.

    Examples
    --------
    >>> h, _ = level_heights(t, 0)
    >>> got = gather(t, np.array([3, 64]), np.array([7, 64]), ("height", "delta"))
    >>> got["height"].tolist() == [h[3, 7], h[64, 64]], bool((got["delta"] >= 0).all())
    (True, True)
    """
    g = terrain.grid
    i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
    out = {k: np.full(i.shape, np.nan if k == "height" else 0.0) for k in kinds}
    if i.size == 0:
        return out
    keys, inv, a, b, held = g.vertex_tiles(i, j, vertex_level(terrain, i, j))
    stacks = terrain.tile_stacks(keys, kinds)
    for k in kinds:
        out[k] = np.where(held, stacks[k][inv, a, b], out[k])
    return out


def tile_stacks(terrain: TerrainLike, keys: Sequence[TileKey], kinds: Sequence[str] = ("delta",)
                ) -> dict[str, np.ndarray]:
    """(K, T, T) float64 stacks of per-sample arrays for tiles ``keys``.

    ``kinds``: delta, radius, height (source units, NaN = no data), x, y
    (scene). Tiles that are not stored give δ = r = 0 and height NaN.

    Examples
    --------
    >>> s = tile_stacks(t, t.tile_keys(0)[:2], ("delta", "height"))
    >>> s["height"].shape == (2, t.grid.tile_samples, t.grid.tile_samples)
    True
    >>> bool((s["delta"][1] == t.tile_delta(*t.tile_keys(0)[1])).all())
    True
    """
    T = terrain.grid.tile_samples
    stacks = {k: np.zeros((len(keys), T, T)) for k in kinds}
    if "height" in kinds:
        stacks["height"][:] = np.nan
    for n, key in enumerate(keys):
        if key not in terrain.tile_info:
            continue
        if "delta" in kinds:
            stacks["delta"][n] = terrain.tile_delta(*key)
        if "radius" in kinds:
            stacks["radius"][n] = terrain.tile_radius(*key)
        if "height" in kinds:
            stacks["height"][n] = terrain.tile(*key).heights
        if "x" in kinds:
            stacks["x"][n], stacks["y"][n] = terrain.tile_xy(*key)
    return stacks


# ------------------------------------------------------------ whole grids
def level_heights(terrain: TerrainLike, level: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Heights (source units, NaN = no data) and valid mask of a whole level, padded.

    Examples
    --------
    >>> h, v = level_heights(t, 1)
    >>> h.shape == t.grid.level_shape(1), bool(v.all())
    (True, True)
    """
    g = terrain.grid
    shape = g.level_shape(level)  # (n, n) on a square grid
    h = np.full(shape, np.nan)
    v = np.zeros(shape, bool)
    step = 1 << g.t
    for (L, x, y) in terrain.tile_info:
        if L != level:
            continue
        tl = terrain.tile(L, x, y)
        T = g.tile_samples
        sl = (slice(y * step, y * step + T), slice(x * step, x * step + T))
        h[sl] = tl.heights
        v[sl] = tl.valid
    return h, v


def scene_xyz(terrain: TerrainLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """X, Y, Z (float64, source-grid shaped) in the scene frame; NaN where there is no data.

    This is the frame of every mesh geoterrain makes, so external code can
    measure a mesh's error against it directly.

    Examples
    --------
    >>> X, Y, Z = scene_xyz(t)
    >>> Z.shape == (t.grid.rows, t.grid.cols), bool((Z == t.frame.z(level_heights(t)[0])).all())
    (True, True)
    """
    h, v = terrain.level_heights(0)
    H, W = terrain.grid.rows, terrain.grid.cols
    i, j = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    X, Y = terrain.frame.xy(i, j)
    Z = terrain.frame.z(h[:H, :W])
    return X, Y, Z

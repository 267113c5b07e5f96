"""A terrain's extent, from its tile table, as functions over
:class:`~geoterrain.terrainlike.TerrainLike`: the scene box of its valid data (its top
tiles' rows) and the height that stands in for nodata in the nested spheres.

:class:`geoterrain.terrain.Terrain`'s ``scene_box`` and ``stand_in_z`` forward here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["scene_box", "stand_in_z"]


def scene_box(terrain: TerrainLike) -> tuple[np.ndarray, np.ndarray]:
    """Scene-frame box (lo, hi), each (3,) float64, of the valid data (top tile bounds).

    Examples
    --------
    >>> lo, hi = scene_box(t)
    >>> bool((lo < hi).all())
    True
    """
    rx, ry = terrain.grid.roots  # the top tile, or every root tile of a root grid
    tops = [terrain.tile_info[k] for k in ((terrain.grid.top_level, x, y)
                                           for y in range(ry) for x in range(rx))
            if k in terrain.tile_info]
    los, his = [], []
    for info in tops:
        z0, z1 = info["zmin"], info["zmax"]
        z0 = 0.0 if z0 is None or not np.isfinite(z0) else z0
        z1 = z0 if z1 is None or not np.isfinite(z1) else z1
        los.append([info["xmin"], info["ymin"], z0])
        his.append([info["xmax"], info["ymax"], z1])
    return np.min(np.array(los, np.float64), 0), np.max(np.array(his, np.float64), 0)


def stand_in_z(terrain: TerrainLike) -> float:
    """The scene height that stands in for nodata samples in the nested spheres.

    The middle of the valid height range (scene units), as the preprocess's
    radii used it, so a sphere centred there still nests. Read from the store's
    metadata; stores written before it was recorded derive it from the tile bounds.

    Examples
    --------
    >>> lo, hi = scene_box(t)
    >>> bool(lo[2] <= stand_in_z(t) <= hi[2])
    True
    """
    v = terrain.meta.get("stand_in_z")
    if v is None:
        lo = [t["zmin"] for t in terrain.tile_info.values() if t["zmin"] is not None]
        hi = [t["zmax"] for t in terrain.tile_info.values() if t["zmax"] is not None]
        v = 0.5 * (min(lo) + max(hi)) if lo else 0.0
    return float(v)

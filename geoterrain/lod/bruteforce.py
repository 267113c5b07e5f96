"""Strategy ``bruteforce``: every full-resolution tile in the frustum (the baseline).

Level-0 tiles are culled against the frustum through the tile quadtree and drawn
whole: the mesh does not depend on τ, and its error is zero up to round-off.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import assemble, quadtree_leaves, tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """Every visible level-0 tile (``tau`` and ``morph`` are ignored), and the stats;
    ``occlusion``: cull the tiles hidden behind nearer terrain.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    leaves, stats = quadtree_leaves(terrain, index, view,
                                    lambda nodes, L: np.ones(len(nodes), bool),
                                    hidden_rows(terrain, view, enabled=occlusion))
    return assemble(terrain, index, leaves), stats

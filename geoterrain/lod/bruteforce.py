"""Strategy ``bruteforce``: every full-resolution tile in the frustum (the baseline).

Level-0 tiles are culled against the frustum through the tile quadtree and drawn
whole: the mesh does not depend on τ, and its error is zero up to round-off.
"""

from __future__ import annotations

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import assemble, quadtree_leaves, tile_index


def select(terrain, view: View, tau: float):
    """Every visible level-0 tile (``tau`` is ignored), and the stats.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    leaves, stats = quadtree_leaves(terrain, index, view,
                                    lambda nodes, L: np.ones(len(nodes), bool),
                                    hidden_rows(terrain, view))
    return assemble(terrain, index, leaves), stats

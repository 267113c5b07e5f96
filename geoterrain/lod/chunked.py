"""Strategy ``chunked``: the stored tile quadtree with skirts (seed 000, GPU Terrain
Rendering / Ulrich's chunked LOD).

The tile quadtree is walked level by level on arrays of nodes
(:func:`geoterrain.lod.tiles.quadtree_leaves`). A node is refined while
λ·ε_tile / D_min > τ, with ε_tile the stored error of the tile's uniform surface
against every full-resolution sample of its footprint and D_min the distance
from the eye to the tile's 3-D box, so the measured error of a drawn tile stays
≤ τ. Cracks between tiles of different levels are closed with skirts (seed 000
§skirts) hanging below the tile's edges, as deep as the tile's skirt error plus
the largest skirt error of the drawn tiles.
"""

from __future__ import annotations

import numpy as np

from geoterrain.lod.chunks import assemble_chunks, chunk_error
from geoterrain.lod.tiles import quadtree_leaves, tile_index
from geoterrain.view import View


def select(terrain, view: View, tau: float):
    """The chunked-LOD mesh of ``view`` at pixel tolerance ``tau``, and its stats.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    lam = view.lam
    error = chunk_error(terrain, index)

    def refine(nodes: np.ndarray, L: np.ndarray) -> np.ndarray:
        dmin = view.box_distance(index.lo[nodes], index.hi[nodes])
        err = error[nodes]
        with np.errstate(invalid="ignore"):
            return (lam * err > tau * dmin) | ((dmin == 0) & (err > 0))

    leaves, stats = quadtree_leaves(terrain, index, view, refine)
    depth = None
    if len(leaves):
        # a chunk's edge lies within ε_chunk of the samples (its uniform edge within
        # the stored boundary error), so two drawn edges are at most the sum apart
        be = np.maximum(index.boundary[leaves], error[leaves])
        depth_all = float(np.max(be[np.isfinite(be)], initial=0.0))
        depth = np.where(np.isfinite(be), be, 0.0) + depth_all
    return assemble_chunks(terrain, index, leaves, depth), stats

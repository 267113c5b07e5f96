"""Strategy ``chunked``: the stored tile quadtree with skirts (seed 000, GPU Terrain
Rendering / Ulrich's chunked LOD).

The tile quadtree is walked top-down by a compiled pass
(:func:`geoterrain.lod.chunks.chunk_leaves`). A node is refined while
λ·ε_chunk / D_min > τ, with ε_chunk the error of the tile's simplified chunk
against every full-resolution sample of its footprint (:mod:`geoterrain.lod.chunks`)
and D_min the distance from the eye to the tile's 3-D box, so the measured error
of a drawn chunk stays ≤ τ. Cracks between chunks of different levels are
closed with skirts (seed 000 §skirts) hanging below the chunk's edges, as deep
as its edge error plus the largest edge error of the drawn chunks.
"""

from __future__ import annotations

import numpy as np

from geoterrain.lod.chunks import assemble_chunks, chunk_error, chunk_leaves
from geoterrain.lod.tiles import tile_index
from geoterrain.view import View


def select(terrain, view: View, tau: float):
    """The chunked-LOD mesh of ``view`` at pixel tolerance ``tau``, and its stats.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    error = chunk_error(terrain, index)
    leaves, stats = chunk_leaves(terrain, index, view, tau)
    depth = None
    if len(leaves):
        # a chunk's edge lies within ε_chunk of the samples (its uniform edge within
        # the stored boundary error), so two drawn edges are at most the sum apart
        be = np.maximum(index.boundary[leaves], error[leaves])
        depth_all = float(np.max(be[np.isfinite(be)], initial=0.0))
        depth = np.where(np.isfinite(be), be, 0.0) + depth_all
    return assemble_chunks(terrain, index, leaves, depth), stats

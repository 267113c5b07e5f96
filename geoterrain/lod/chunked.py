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

Geomorphing (``morph=True``, off by default): the walk refines at τ_min = 0.75 τ and a
chunk slides from its parent's surface to its own as its parent's ρ goes from τ_min to τ
(:func:`geoterrain.lod.chunks.morph_heights`; each chunk refines its parent's mesh, so
at t = 0 it draws exactly what its parent drew). Choice: one t per chunk, from the
parent's ρ, as Ulrich's chunked LOD morphs a whole chunk; the skirts, deepened to the
morphing ancestors' errors, cover the steps between neighbours of different t.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.chunks import assemble_counted, chunk_error, chunk_leaves, morph_heights
from geoterrain.lod.morph import MORPH_START
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The chunked-LOD mesh of ``view`` at pixel tolerance ``tau``, and its stats;
    ``occlusion``: cull chunks hidden behind nearer terrain; ``morph``: geomorph (off
    unless True).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    error = chunk_error(terrain, index)
    morph = bool(morph)
    tau_min = MORPH_START * tau if morph else tau
    leaves, stats = chunk_leaves(terrain, index, view, tau_min, occlusion=occlusion)
    depth = zm = None
    if len(leaves):
        # a chunk's edge lies within ε_chunk of the samples (its uniform edge within
        # the stored boundary error), so two drawn edges are at most the sum apart
        be = np.maximum(index.boundary[leaves], error[leaves])
        if morph:
            zm, t, bound = morph_heights(terrain, index, leaves, view.eye, view.lam, tau,
                                         tau_min)
            be = np.maximum(be, bound)  # a morphing edge: within its ancestors' errors
            stats["morphing_chunks"] = int((t < 1.0).sum())
            stats["morph_band"] = (tau_min, tau)
        depth_all = float(np.max(be[np.isfinite(be)], initial=0.0))
        depth = np.where(np.isfinite(be), be, 0.0) + depth_all
    mesh, n_surf, n_skirt = assemble_counted(terrain, index, leaves, depth, zm)
    # counted and elevated while assembled: the selection's finish makes no pass over it
    stats.update(triangles=n_surf, skirt_triangles=n_skirt, elevated=True)
    return mesh, stats

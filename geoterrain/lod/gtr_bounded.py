"""Strategy ``gtr_bounded``: GPU Terrain Rendering's block quadtree (seed 000 §2.8) with
the project's error, so that the measured ρ ≤ τ.

The blocks, skirts and culling are ``gtr``'s (:mod:`geoterrain.lod.gtr`). Two choices
differ from the thesis's rule, each for the bound:

- a block's error is its stored tile error: the exact largest |z − S_L| over every
  full-resolution sample of its footprint (never above eq. 5-2's cumulative δ_b);
- a block is refined while λ·error / D_min > τ, D_min the distance from the eye to the
  block's box (the thesis measures to the centre, assuming a level view), so every
  sample of a drawn block projects within τ.

Geomorphing (``morph=True``, off by default): the walk refines at τ_min = 0.75 τ and a
block slides towards its parent's surface as its parent's ρ goes from τ to τ_min
(:func:`geoterrain.lod.gtrtree.morph_band`): the thesis's per-block morph constant, its
fraction taken over the band where both surfaces keep ρ ≤ τ.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.chunks import parents
from geoterrain.lod.gtrtree import (
    block_mesh,
    morph_band,
    skirt_depth,
    skirt_sides,
    walk,
)
from geoterrain.lod.mesh import empty_parts
from geoterrain.lod.morph import MORPH_START
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The bounded GTR mesh of ``view`` at pixel tolerance ``tau`` and its stats;
    ``morph``: slide each block towards its parent within the bound (off unless True).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["blocks"] > 0 and mesh.n_cells > 0
    True
    """
    index = tile_index(terrain)
    return bounded_blocks(terrain, view, tau, index.error, index.boundary,
                          occlusion=occlusion, morph=bool(morph))


def bounded_blocks(terrain: TerrainLike, view: View, tau: float, error: np.ndarray,
                   edge: np.ndarray, *, occlusion: bool, morph: bool):
    """Blocks refined while λ·error / D_min > τ (τ_min with ``morph``), skirts from the
    per-row edge bounds ``edge``, each morphing block towards its parent by the band."""
    index = tile_index(terrain)
    par = parents(terrain, index)
    tau_min = MORPH_START * tau if morph else tau
    leaves, stats = walk(terrain, view, error, tau_min, rule="box", occlusion=occlusion)
    if not len(leaves):
        return empty_parts(), stats
    s = np.zeros(len(leaves))
    e = edge[leaves].copy()
    if morph:
        p = par[leaves]
        q = np.maximum(p, 0)
        dp = view.box_distance(index.lo[q], index.hi[q])
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where(error[q] > 0, view.lam * error[q] / dp, 0.0)
        s = np.where((p >= 0) & np.isfinite(error[q]), morph_band(rho, tau, tau_min), 0.0)
        e = np.where(s > 0, np.maximum(e, error[q]), e)
        stats.update(morphing_blocks=int((s > 0).sum()), morph_band=(tau_min, tau))
    depth = skirt_depth(e)
    sides = skirt_sides(terrain, index, leaves, view, depth)
    stats.update(blocks=len(leaves), mean_level=float(index.keys[leaves, 0].mean()))
    return block_mesh(terrain, index, leaves, s, depth, sides), stats

"""Strategy ``lauritsen_nielsen``: Lauritsen & Nielsen's "Rendering Very Large, Very
Detailed Terrains" (seed 000 §2.7, eq. 4-23 … 4-27): GeoMipMapping's simplification
inside chunked LOD's quadtree.

- **Chunks**: each quadtree node is an independent regular grid of 2^n + 1 vertices per
  side; a parent drops every other row and column of its children (9×9 → 5×5), so the
  nodes are the store's tiles, drawn whole (:mod:`geoterrain.lod.gtrtree`).
- **Error** δ_b (eq. 4-23): 0 at a leaf, else the largest of the four children's plus
  δ_m, the largest error of the vertices the coarser level removes; monotone up the tree.
- **Selection** (eq. 4-24, 4-25): C = S / (2τ·|tan(fov/2)|) = λ/τ, d_m = δ_b·C, refine
  while the chunk's distance d < d_m. Choice: d is the distance from the eye to the
  chunk's box (the text says "the chunk's distance"), so ρ ≤ λ·δ_b/d ≤ τ at every
  sample of a drawn chunk: registered bounded.
- **Skirts**: each chunk's hangs by δ_b (L1894). Choice: plus the largest δ_b drawn, as
  two neighbours' edges, each within its δ_b, may lie the sum apart: no crack shows.
- **Morph** (``morph=True``; eq. 4-26, 4-27): a chunk's vanishing vertices move by the
  factor f along their stored displacement towards the parent's position (the target of
  :func:`geoterrain.lod.gtrtree.coarse_target`). Choice: f runs linearly in the parent's
  distance between the parent's d_mp at τ and at τ_min = 0.75 τ (the walk refines at
  τ_min), not between the chunk's and its parent's d_m: a chunk leans on its parent only
  where the parent's own surface is within τ, so the bound holds while morphing.
- Left out: the texture morph (eq. 4-28; the pictures are shaded by the renderer's own
  texture atlas, not per chunk) and the runtime detail synthesis beyond the source
  resolution (Kobbelt subdivision with Perlin noise, §2.7): a GIS view draws the DEM,
  and synthesised relief would not be data.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod.gtr_bounded import bounded_blocks
from geoterrain.lod.gtrtree import block_errors
from geoterrain.lod.mesh import empty_parts
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The Lauritsen–Nielsen mesh of ``view`` at pixel tolerance ``tau`` and its stats;
    ``morph``: eq. 4-26/4-27 morphing within the bound (off unless True).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["blocks"] > 0 and mesh.n_cells > 0
    True
    """
    if tile_index(terrain).outside(view):  # (before the errors: nothing to read)
        return empty_parts(), {}
    db = block_errors(terrain).delta_b
    return bounded_blocks(terrain, view, tau, db, db, occlusion=occlusion, morph=bool(morph))

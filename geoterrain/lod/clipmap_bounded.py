"""Strategy ``clipmap_bounded``: geometry clipmaps (seed 000 §2.9) whose finest active
level and region sizes come from the stored tile errors, so that the measured ρ ≤ τ.

The levels, toroidal buffers, transitions and stitching are ``clipmap``'s
(:mod:`geoterrain.lod.clipmaps`). Where the seed fixes every region at n × n and picks
the finest level by the viewer's height, here (:func:`geoterrain.lod.clipmaps._bounded_levels`):

- a level-l cell is within B_l = E_l + E_{l+1} of the samples, E_l the largest stored
  error of the level-l tiles in view (the transition blend and the stitched perimeter
  move the surface by at most E_{l+1});
- the finest level is the coarsest whose whole region lies at least λ·B_l/τ from the eye;
- each region reaches at least λ·B_{l+1}/τ from the viewer (n × n at the least), so the
  next coarser level is drawn only where its B projects within τ;
- cells of tiles whose error is not finite (no-data mixed in) are drawn finer, as the
  no-data rule does.

So the triangle count is no longer constant: it follows τ and the terrain's roughness.
Its rule is the error, not a steady count, so it culls its render regions (each region's
4 rectangles against the frustum and, with ``occlusion``, the horizon, as §2.9), where
``clipmap`` draws its whole rings unless asked to cull.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod import clipmaps

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The bounded geometry-clipmap mesh of ``view`` at pixel tolerance ``tau`` and its
    stats; ``morph``: the transition regions (on unless False).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> mesh.n_cells > 0 and len(stats["region_halves"]) >= 1
    True
    """
    return clipmaps.select(terrain, view, tau, kind="bounded", occlusion=occlusion,
                           morph=morph is None or bool(morph))

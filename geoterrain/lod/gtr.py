"""Strategy ``gtr``: Vistnes' GPU Terrain Rendering as the thesis built it (seed 000
§2.8, §3.2–3.9, eq. 5-2, 5-4 … 5-6).

- **Blocks**: a quadtree of regular blocks of a fixed vertex count, the store's tiles
  (:mod:`geoterrain.lod.gtrtree`): a coarser block covers four at twice the spacing with
  the same (2^t+1)² vertices, drawn as one regular grid.
- **Error** δ_b per block and level (eq. 5-2: max of the children's + the δ_m of the
  vertices that vanish), precomputed once per terrain.
- **Selection**: a block is accepted when the eye's distance d to its centre is at least
  D_n = δ_b·C, C = V_res / (2τ·tan(fov_y/2)) = λ/τ (eq. 5-4 corrected as in seed 000
  §2.4, eq. 5-5, L2522); otherwise its four children are tried. The rule assumes a
  horizontal view direction and measures to the centre, so it gives no bound: ρ is
  measured, not promised (registered unbounded; ``gtr_bounded`` keeps ρ ≤ τ).
- **Skirts** (the thesis's optimised skirts, §3.5 and L2561–2563): none on the terrain's
  border, none outside the frustum for a block that meets its border. Choice: each skirt
  hangs by the block's exact boundary error (the stored max over its border samples,
  tighter than the thesis's cumulative boundary error) plus the largest one drawn, as
  two neighbours' edges may lie the sum of their errors apart (the thesis hangs its own
  only).
- **Geomorphing** (on by default, as Table 6-2's TemporalCoherence): the per-block morph
  constant, integer part the quadtree level and fraction t = (d − D_n)/(D_{n+1} − D_n)
  (eq. 5-6), D_{n+1} the parent's switch distance; only the vertices that vanish at the
  next level move, towards their coarse position. At t = 1 a block draws its parent's
  surface, so the switch does not pop. While a block morphs, its skirt also covers its
  parent's error.
- **Culling**: the stored boxes against the frustum top-down, and with ``occlusion`` the
  horizon (:mod:`geoterrain.lod.occlusion`, the project's form of Fiedler's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.gtrtree import block_errors, block_mesh, skirt_depth, skirt_sides, walk
from geoterrain.lod.mesh import empty_parts
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


SKIRTS = ("optimised", "all", "none")  # Table 6-2's SkirtsOptimized, Skirts, None


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, skirts: str = "optimised"):
    """The GTR mesh of ``view`` at pixel tolerance ``tau`` (switch distances D_n = δ_b·C),
    and its stats; ``morph``: eq. 5-6 geomorphing (on unless False); ``skirts``: the
    thesis's crack treatments (Table 6-2's SpatialCoherence): ``optimised`` (the default),
    ``all`` (every inner side) or ``none`` (cracks left open).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 8.0)
    >>> stats["blocks"] > 0 and mesh.n_cells > 0
    True
    """
    index = tile_index(terrain)
    if index.outside(view):  # (before the errors: a view of nothing reads nothing)
        return empty_parts(), {}
    be = block_errors(terrain)
    leaves, stats = walk(terrain, view, be.delta_b, tau, rule="distance",
                         occlusion=occlusion)
    if not len(leaves):
        return empty_parts(), stats
    C = view.lam / tau  # eq. 5-4: C = V_res / (2τ tan(fov_y / 2))
    d = np.linalg.norm(0.5 * (index.lo[leaves] + index.hi[leaves]) - view.eye, axis=1)
    D = be.delta_b[leaves] * C  # eq. 5-5
    p = be.parent[leaves]
    Dp = np.where(p >= 0, be.delta_b[np.maximum(p, 0)] * C, np.inf)
    t = np.zeros(len(leaves))
    if morph is None or morph:
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.clip((d - D) / (Dp - D), 0.0, 1.0)  # eq. 5-6
        t = np.where(np.isfinite(Dp) & np.isfinite(D), np.nan_to_num(t, nan=0.0), 0.0)
        stats["morphing_blocks"] = int((t > 0).sum())
    edge = index.boundary[leaves].copy()
    edge = np.where(t > 0, np.maximum(edge, be.delta_b[np.maximum(p, 0)]), edge)
    if skirts not in SKIRTS:
        raise ValueError(f"skirts must be one of {', '.join(SKIRTS)}, got {skirts!r}")
    depth = skirt_depth(edge) if skirts != "none" else np.zeros(len(leaves))
    sides = skirt_sides(terrain, index, leaves, view, depth) if skirts == "optimised" else None
    stats.update(blocks=len(leaves), mean_level=float(index.keys[leaves, 0].mean()))
    return block_mesh(terrain, index, leaves, t, depth, sides), stats

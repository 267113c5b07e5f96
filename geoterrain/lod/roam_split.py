"""Strategy ``roam_split``: McNally's split-only ROAM, as in Tread Marks (seed 000 §2.2,
eq. 4-2, Listing 4-1).

Each frame starts from the base triangles (two per root tile) and splits, forced splits
included (:mod:`geoterrain.lod.roam`'s pool and kernels), every triangle whose priority
exceeds τ: no frame coherence, no merge queue. The priority is McNally's: the triangle's
*variance* |c_z − (a_z + b_z)/2| (eq. 4-2; kept as the largest down the tree, as his
code does) times λ over the distance from the eye to its split vertex. A variance is
the largest local error, not a sum of them, and the distance is to one point: no bound,
so ρ is measured (registered unbounded). Frustum culling and the drawn leaves are
``roam``'s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod.roam import run

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """McNally's split-only ROAM mesh of ``view`` at pixel tolerance ``tau`` and its
    stats; ``morph`` is ignored.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["merges"], mesh.n_cells > 0
    (0, True)
    """
    return run(terrain, view, tau, occlusion=occlusion, mode=1, incremental=False,
               fresh=True, owner=f"{__name__}.state")

"""Strategy ``clipmap_gpu``: Asirvatham & Hoppe's GPU-based geometry clipmaps (seed 000
§2.10, Table 4-1), emulated on arrays.

On the GPU the vertex and index buffers are constant: one set of footprints (12 blocks of
m × m vertices, m = (n + 1)/4 = 64, four m × 3 fix-ups, an L-shaped interior trim and a
ring of degenerate triangles) is drawn at every level with a scale and a translation,
the heights come from each level's vertex texture (an n × n toroidal image), and the
transition blend runs in the vertex shader. Here the textures are the toroidal buffers of
:mod:`geoterrain.lod.clipmaps`, sampled at each vertex's (r mod n, c mod n), the blend is
the same per-vertex array operation, and each footprint is culled on its own.

What differs from ``clipmap`` on a CPU renderer: only the culling. This strategy culls
each footprint against the frustum and, with ``occlusion``, the horizon: the footprints
cut a level into 25 rectangles (the 5 × 5 grid of blocks, fix-ups and centre), so few
off-screen triangles are drawn, and the count drawn follows the heading. ``clipmap``
draws its whole rings by default (a constant count, §2.9's steady rendering rate; the
paper's 4 strips per level with ``cull=True``). Before culling the two draw the same
triangles (the degenerate ring is the stitched perimeter, made conforming). Two
choices: the paper's level rule "vertex spacing > 2.5 h" is read as the extent
n·g_l > 2.5 h (the §2.9 rule; seed 000 §2.10 notes the inference); and a region is
shifted inside the DEM as in ``clipmap`` (the paper's terrain is larger than every clip
region, so it never crops).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod import clipmaps

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The GPU-clipmap mesh of ``view`` (``tau`` is not used) and its stats; ``morph``:
    the transition regions (on unless False).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> mesh.n_cells > 0
    True
    """
    return clipmaps.select(terrain, view, tau, kind="gpu", occlusion=occlusion,
                           morph=morph is None or bool(morph))

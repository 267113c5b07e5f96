"""Strategy ``clipmap``: Losasso & Hoppe's geometry clipmaps (seed 000 §2.9, eq. 4-30 …
4-32): m nested, viewer-centred n × n grids (n = 255), toroidal updates, transition
regions, no cracks (:mod:`geoterrain.lod.clipmaps` has the whole method).

The mesh does not depend on τ: a clipmap draws a fixed amount of geometry around the
viewer, its levels chosen by the viewer's position and height only. The seed says its
screen-space error is hard to control; it is not bounded (registered unbounded) and is
measured: see docs/lab/seed000-experiments.md. ``clipmap_bounded`` keeps ρ ≤ τ.

Choice: the whole rings are drawn, with no culling of the render regions, so the count
drawn stays constant along any flight whatever the heading (§2.9's "steady rendering
rate"); only the levels the viewer's height selects (h > 0.4·n·g_l skips a level) change
it. ``cull=True`` is the paper's culling (§2.9: each render region's 4 rectangles against
the frustum and, with ``occlusion``, the horizon): fewer triangles, but a count that
follows the heading (from 38 % to 94 % of the rings on the one-minute loop,
docs/lab/seed000-experiments.md). ``clipmap_gpu`` culls, per footprint: on a CPU renderer
that is the difference between the two (the footprints aside, the same surface).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod import clipmaps

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, cull: bool = False):
    """The geometry-clipmap mesh of ``view`` (``tau`` is not used) and its stats;
    ``morph``: the transition regions (on unless False); ``cull``: the paper's culling of
    the render regions (off: the whole rings; ``occlusion`` is used only with it).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["clipmap_n"], mesh.n_cells > 0
    (255, True)
    """
    return clipmaps.select(terrain, view, tau, kind="clipmap", occlusion=occlusion,
                           morph=morph is None or bool(morph), cull=bool(cull))

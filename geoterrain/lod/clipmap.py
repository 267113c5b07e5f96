"""Strategy ``clipmap``: Losasso & Hoppe's geometry clipmaps (seed 000 §2.9, eq. 4-30 …
4-32): m nested, viewer-centred n × n grids (n = 255), toroidal updates, transition
regions, no cracks (:mod:`geoterrain.lod.clipmaps` has the whole method).

The mesh does not depend on τ: a clipmap draws a fixed amount of geometry around the
viewer, its levels chosen by the viewer's position and height only. The seed says its
screen-space error is hard to control; it is not bounded (registered unbounded) and is
measured: see docs/benchmarks.md. ``clipmap_bounded`` keeps ρ ≤ τ.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod import clipmaps

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The geometry-clipmap mesh of ``view`` (``tau`` is not used) and its stats;
    ``morph``: the transition regions (on unless False).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["clipmap_n"], mesh.n_cells > 0
    (255, True)
    """
    return clipmaps.select(terrain, view, tau, kind="clipmap", occlusion=occlusion,
                           morph=morph is None or bool(morph))

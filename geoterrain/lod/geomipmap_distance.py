"""Strategy ``geomipmap_distance``: GeoMipMapping with the thesis's precomputed switch
distances (seed 000 §2.4, eq. 4-8 … 4-11).

A block takes the coarsest level n whose switch distance D_n = δ_n·C, C = λ/τ
(= V_res / (2τ·tan(fov_y/2)), eq. 4-9 … 4-11 with |t| = near·tan(fov_y/2)), is
within the eye's distance to the block centre. The rule assumes a horizontal view
direction and measures to the centre, not the nearest point, so it gives no bound on
the measured error; the mesh (blocks, stitching) is :mod:`geoterrain.lod.geomipmap`'s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.lod import geomipmap

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The GeoMipMapping mesh with the distance rule D_n = δ_n·C, and its stats.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["blocks"] > 0
    True
    """
    return geomipmap.select(terrain, view, tau, occlusion=occlusion, rule="distance")

"""Questions asked of a store: heights and normals at points, profiles, areas and
volumes, line of sight, viewsheds and contours, each with its error stated and the tiles
it decoded reported.

Every function takes a terrain first (a :class:`~geoterrain.terrainlike.TerrainLike`,
what :func:`geoterrain.open` returns) and points in the DEM's CRS, or in another CRS
with ``crs=`` (``"lonlat"`` for longitude, latitude); answers come in the same form.
"""

from geoterrain.analysis.heights import Heights, Normals, height_at, normal_at
from geoterrain.analysis.visibility import (
    LineOfSight,
    Viewshed,
    line_of_sight,
    viewshed,
    write_viewshed,
)

__all__ = ["Heights", "LineOfSight", "Normals", "Viewshed", "height_at", "line_of_sight",
           "normal_at", "viewshed", "write_viewshed"]

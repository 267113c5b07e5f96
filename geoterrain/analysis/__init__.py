"""Questions asked of a store: heights and normals at points, profiles, areas and
volumes, line of sight, viewsheds and contours, each with its error stated and the tiles
it decoded reported.

Every function takes a terrain first (a :class:`~geoterrain.terrainlike.TerrainLike`,
what :func:`geoterrain.open` returns) and points in the DEM's CRS, or in another CRS
with ``crs=`` (``"lonlat"`` for longitude, latitude); answers come in the same form.
"""

from geoterrain.analysis.areas import Area, Plane, Volume, surface_area, volume
from geoterrain.analysis.contours import Contours, contours, write_contours
from geoterrain.analysis.heights import Heights, Normals, height_at, normal_at
from geoterrain.analysis.profile import Profile, plot_profile, profile, write_profile_csv
from geoterrain.analysis.visibility import (
    LineOfSight,
    Viewshed,
    line_of_sight,
    viewshed,
    write_viewshed,
)

__all__ = ["Area", "Contours", "Heights", "LineOfSight", "Normals", "Plane", "Profile", "Viewshed",
           "Volume", "height_at", "line_of_sight", "normal_at", "plot_profile", "profile",
           "surface_area", "viewshed", "volume", "write_contours", "write_profile_csv",
           "write_viewshed", "contours"]

"""Questions asked of a store: heights and normals at points, profiles, areas and
volumes, line of sight, viewsheds and contours, each with its error stated and the tiles
it decoded reported.

Every function takes a terrain first (a :class:`~geoterrain.terrainlike.TerrainLike`,
what :func:`geoterrain.open` returns) and points in the DEM's CRS, or in another CRS
with ``crs=`` (``"lonlat"`` for longitude, latitude); answers come in the same form.
"""

from geoterrain.analysis.heights import Heights, Normals, height_at, normal_at

__all__ = ["Heights", "Normals", "height_at", "normal_at"]

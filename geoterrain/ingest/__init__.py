"""Ingest: read a DEM (any GDAL raster, a mosaic, a Terrain-RGB/Terrarium PNG tile)
with its units, or make a synthetic one.
"""

__all__ = ["mosaic", "raster", "synth", "units"]

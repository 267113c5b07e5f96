"""Products for other tools: mesh files (glTF, OBJ, PLY, STL, VTK), streamed static
meshes, Cesium quantized-mesh tile sets and GeoTIFF rasters.
"""

__all__ = ["formats", "meshfiles", "meshstream", "qmesh", "rasters"]

"""The HTTP tile server and its pages (`geoterrain serve`): quantized-mesh, Terrain-RGB,
Terrarium and imagery tiles cut on request from stores, for CesiumJS and MapLibre.

The top of the stage order: it reads terrains through :mod:`geoterrain.export` and
:mod:`geoterrain.rendering`, and nothing below imports it.
"""

from geoterrain.serve.app import ServedStore, create_app, find_assets, open_stores

__all__ = ["ServedStore", "create_app", "find_assets", "open_stores"]

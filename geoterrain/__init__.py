"""geoterrain: turn real elevation data into fast, accurate 3-D terrain.

Examples
--------
>>> import geoterrain
>>> geoterrain.__version__
'0.1.0'
"""

__version__ = "0.1.0"

from geoterrain.exceptions import GeoterrainError  # noqa: E402
from geoterrain.preprocess import preprocess  # noqa: E402
from geoterrain.rendering import render  # noqa: E402
from geoterrain.terrain import Terrain, open  # noqa: E402,A004
from geoterrain.viewer import show  # noqa: E402

__all__ = ["GeoterrainError", "Terrain", "__version__", "open", "preprocess", "render", "show"]

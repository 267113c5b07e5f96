"""geoterrain: turn real elevation data into fast, accurate 3-D terrain.

The top level is light: names are imported on first use, so ``import geoterrain``
(and ``geoterrain --help``) pays for neither numba nor VTK.

Examples
--------
>>> import geoterrain
>>> geoterrain.__version__
'0.1.0'
>>> geoterrain.View((0, -1000, 500), (0, 0, 0)).size
(1280, 720)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from geoterrain._version import __version__
from geoterrain.core import _fork  # noqa: F401  (the fork hook, before any kernel runs)
from geoterrain.exceptions import GeoterrainError

if TYPE_CHECKING:
    from geoterrain.core.view import View
    from geoterrain.preprocessing.pipeline import preprocess
    from geoterrain.rendering.animation import orbit
    from geoterrain.rendering.scene import default_view, render
    from geoterrain.rendering.viewer import show
    from geoterrain.terrain import Terrain, edit, open  # noqa: A004

# public name → the module that defines it
_LAZY = {
    "preprocess": "geoterrain.preprocessing.pipeline",
    "open": "geoterrain.terrain",
    "edit": "geoterrain.terrain",
    "Terrain": "geoterrain.terrain",
    "View": "geoterrain.core.view",
    "render": "geoterrain.rendering.scene",
    "default_view": "geoterrain.rendering.scene",
    "orbit": "geoterrain.rendering.animation",
    "show": "geoterrain.rendering.viewer",
}

__all__ = ["GeoterrainError", "Terrain", "View", "__version__", "default_view", "edit", "open",
           "orbit", "preprocess", "render", "show"]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'geoterrain' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

"""The globe's LOD strategies, by name (one today: seed 001's planetary CDLOD).

The flat strategies' seam (:mod:`geoterrain.lod.registry`) is ``select(terrain, view,
tau)`` over one :class:`~geoterrain.terrainlike.TerrainLike` in scene metres; a globe
strategy selects over the 30 quadtrees of a :class:`~geoterrain.globe.Globe` (many stores
and a base layer) in ECEF metres, with its own pools and request queue. It does not fit
that seam, so the globe keeps this small registry of its own, light to import like the
flat one.

Examples
--------
>>> GLOBE_STRATEGIES, GLOBE_DEFAULT
(('cdlod',), 'cdlod')
>>> globe_strategy("cdlod").__name__
'select'
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from geoterrain.exceptions import UsageError

__all__ = ["GLOBE_STRATEGIES", "GLOBE_DEFAULT", "globe_strategy"]

_MODULES = {"cdlod": "geoterrain.globe.cdlod"}
GLOBE_STRATEGIES = tuple(_MODULES)
GLOBE_DEFAULT = "cdlod"


def globe_strategy(name: str) -> Callable:
    """The ``select(globe, view, tau, **options) -> GlobeSelection`` of strategy ``name``.

    Examples
    --------
    >>> globe_strategy("rtin")
    Traceback (most recent call last):
    ...
    geoterrain.exceptions.UsageError: unknown globe strategy 'rtin'; use one of cdlod
    """
    if name not in _MODULES:
        raise UsageError(f"unknown globe strategy {name!r}; use one of "
                         f"{', '.join(GLOBE_STRATEGIES)}")
    return importlib.import_module(_MODULES[name]).select

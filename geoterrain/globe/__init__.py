"""The globe: DEM stores placed on the WGS 84 ellipsoid (or seed 001's sphere), drawn by
seed 001's planetary CDLOD over the 30 quadtrees of a rhombic triacontahedron.

Modules, in the order the data flows:

- :mod:`~geoterrain.globe.polyhedron`: the base polyhedron, its face grids, distortion;
- :mod:`~geoterrain.globe.model`: the sphere and the ellipsoid, pyproj's geodetic ↔ ECEF,
  each vertex on its own ray;
- :mod:`~geoterrain.globe.noise`: seed 001's 12-octave procedural planet and its bounds;
- :mod:`~geoterrain.globe.layers`: stores read at geodetic positions, the base layer;
- :mod:`~geoterrain.globe.surface`: which value every lattice point takes;
- :mod:`~geoterrain.globe.nodes`: node keys, six-plane bounds, distance, frustum, horizon;
- :mod:`~geoterrain.globe.payload`: a node's node-relative float32 mesh and normals;
- :mod:`~geoterrain.globe.errors`: node errors (measured over stores, bounded elsewhere)
  and the view ranges;
- :mod:`~geoterrain.globe.pool`, :mod:`~geoterrain.globe.queue`: pools, eviction, the
  request queue;
- :mod:`~geoterrain.globe.cdlod`: selection, morph, the frame's mesh;
- :mod:`~geoterrain.globe.globe`: :class:`Globe`, collision meshes, cameras;
- :mod:`~geoterrain.globe.registry`: the globe's strategies, by name.
"""

from __future__ import annotations

import importlib

__all__ = ["Globe", "camera_view"]


def __getattr__(name: str):
    if name in __all__:
        return getattr(importlib.import_module("geoterrain.globe.globe"), name)
    raise AttributeError(f"module 'geoterrain.globe' has no attribute {name!r}")

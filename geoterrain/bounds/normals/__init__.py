"""Normal maps computed from full-resolution geometry, and their octahedral codes.

Seed 000 (sections 2.9 and 3.9): lighting uses a per-pixel normal map built from the
full-resolution geometry, so it does not change with the level of detail. The thesis uses
a Sobel filter on a regular heightmap; here the tangents come from the 3-D scene
positions, so curvilinear (geographic) grids and vertical exaggeration are handled.

One module per job:

- :mod:`~geoterrain.bounds.normals.maps`: :func:`normal_map` (unit normals (N, N, 3)
  float32, central differences or Horn/Sobel weights of the positions, parallel compiled
  kernel, float64 arithmetic) and :func:`level_normal_maps` (every pyramid level's map
  from its own samples: what a store holds, and what its reader derives).
- :mod:`~geoterrain.bounds.normals.octahedral`: :func:`encode_octahedral` /
  :func:`decode_octahedral`, 2-component octahedral packing (8 or 16 bits), with their
  measured error bounds.
- :mod:`~geoterrain.bounds.normals.codes`: :func:`level_normal_codes` (a band of rows at
  a time), :func:`ring_normal_codes` and :class:`RingCodes` (the tiles' border rings),
  :func:`derived_codes` and :func:`ring_guess` (the maps derived on read).
- :mod:`~geoterrain.bounds.normals.averaged`: :func:`normal_pyramid` and
  :func:`level_normals`, coarse maps averaged from the full map (what stores held before;
  kept for comparison).

The blobs' bytes are :mod:`geoterrain.bounds.normalbytes`'; a stored tile's read back,
:mod:`geoterrain.bounds.tilereads`'.
"""

from geoterrain.bounds.normals.averaged import level_normals, normal_pyramid
from geoterrain.bounds.normals.codes import (
    RingCodes,
    derived_codes,
    level_normal_codes,
    ring_guess,
    ring_normal_codes,
)
from geoterrain.bounds.normals.maps import level_normal_maps, normal_map
from geoterrain.bounds.normals.octahedral import (
    OCTAHEDRAL_MAX_ERROR_DEG,
    OCTAHEDRAL_MAX_ERROR_DEG_PRECISE,
    decode_octahedral,
    encode_octahedral,
)

__all__ = [
    "normal_map",
    "level_normal_maps",
    "level_normal_codes",
    "ring_normal_codes",
    "RingCodes",
    "level_normals",
    "normal_pyramid",
    "encode_octahedral",
    "decode_octahedral",
    "derived_codes",
    "ring_guess",
    "OCTAHEDRAL_MAX_ERROR_DEG",
    "OCTAHEDRAL_MAX_ERROR_DEG_PRECISE",
]

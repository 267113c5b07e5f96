"""A terrain's tiles' normal codes read from its store, as functions over
:class:`~geoterrain.terrainlike.TerrainLike`: a tile stored whole read as stored, one on a
level whose maps are derived on read its border ring as stored and the rest derived from
its decoded heights (every such tile in one compiled call), each read counted in
``decoded_normals``.

:meth:`geoterrain.terrain.Terrain.normal_codes` forwards here with its blob reader
(``read_blob(key, kind)``: the tile's checksummed blob); the blobs' bytes are decoded by
:mod:`geoterrain.bounds.tilereads`, imported on first use (its decoders load numba).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["normal_codes"]

BlobReader = Callable[["TileKey", str], bytes]  # (tile key, blob kind) → the checked blob


def normal_codes(terrain: TerrainLike, keys: Sequence[TileKey], read_blob: BlobReader
                 ) -> np.ndarray:
    """The octahedral codes (n, T, T, 2) of tiles ``keys``' normals (``normal_bits``
    bits each; :func:`~geoterrain.bounds.normals.decode_octahedral` unpacks them):
    the one door to a tile's normals. A tile stored whole is read as stored; one on a
    level in ``normals_derived`` has its border ring as stored and the rest derived
    from its decoded heights, all such tiles in one compiled call
    (:func:`~geoterrain.bounds.normals.derived_codes`). Not cached: each tile read
    counts a decode (``decoded_normals``).

    Examples
    --------
    >>> keys = t.tile_keys(0)[:2]
    >>> codes = normal_codes(t, keys, t.reader.get_blob)
    >>> codes.shape == (2, t.grid.tile_samples, t.grid.tile_samples, 2)
    True
    """
    from geoterrain.bounds.normalbytes import normals_from_bytes

    T, bits = terrain.grid.tile_samples, terrain.meta["normal_bits"]
    out = np.empty((len(keys), T, T, 2), np.uint8 if bits == 8 else np.uint16)
    derived = _derived_normal_levels(terrain)
    on_read = []
    for n, key in enumerate(keys):
        if key[0] in derived:
            on_read.append(n)
            continue
        raw, planar = _normal_bytes(terrain, key, read_blob)
        out[n] = (normals_from_bytes(raw, T) if planar
                  else np.frombuffer(raw, out.dtype).reshape(T, T, 2))
    if on_read:
        out[on_read] = _derive_normals(terrain, [keys[n] for n in on_read], bits, read_blob)
    return out


def _normal_bytes(terrain: TerrainLike, key: TileKey, read_blob: BlobReader
                  ) -> tuple[bytes, bool]:
    """A whole stored normal map's codes (:func:`geoterrain.bounds.tilereads.normal_bytes`)."""
    from geoterrain.bounds.tilereads import normal_bytes

    out = normal_bytes(terrain, key, read_blob(key, "normals"))
    terrain.decoded_normals += 1
    return out


def _normal_ring(terrain: TerrainLike, key: TileKey, n: int, read_blob: BlobReader
                 ) -> np.ndarray:
    """A derived level's tile's stored border ring
    (:func:`~geoterrain.bounds.tilereads.normal_ring`)."""
    from geoterrain.bounds.tilereads import normal_ring

    return normal_ring(terrain, key, read_blob(key, "normals"), n)


def _derive_normals(terrain: TerrainLike, keys: list[TileKey], bits: int,
                    read_blob: BlobReader) -> np.ndarray:
    """The codes of tiles on derived levels
    (:func:`~geoterrain.bounds.tilereads.derive_normals`)."""
    from geoterrain.bounds.tilereads import derive_normals

    out = derive_normals(terrain, keys, bits, partial(_normal_ring, terrain,
                                                      read_blob=read_blob))
    terrain.decoded_normals += len(keys)
    return out


def _derived_normal_levels(terrain: TerrainLike) -> tuple[int, ...]:
    # the levels whose normal maps are derived on read (a store's ``normals_derived``)
    return tuple(terrain.meta.get("normals_derived", ()))

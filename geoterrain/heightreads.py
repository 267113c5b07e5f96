"""A terrain's tile decoded from its store, as a function over
:class:`~geoterrain.terrainlike.TerrainLike`: the tile's codes and valid mask from its blob
and its parent's decoded codes (:func:`geoterrain.codec.pyramid.decode_tile_valid`), then
its heights (NaN where not valid), checked against the scene box its tile row records.

:class:`geoterrain.terrain.Terrain` decodes every tile through :func:`decode_heights`
(the only place that decodes heights), with its blob reader (``read_blob(key, kind)``:
the tile's checksummed blob). The decoders load numba, so they are imported on first use:
opening a store never loads them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import zstandard

from geoterrain.exceptions import StoreCorruptError
from geoterrain.terrainlike import Tile

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["decode_heights"]


def decode_heights(terrain: TerrainLike, key: TileKey,
                   read_blob: Callable[[TileKey, str], bytes], blob: bytes | None = None
                   ) -> Tile:
    """Tile ``key`` decoded from ``blob`` (read with ``read_blob`` when None), its parent
    taken from ``terrain.tile`` (decoded first when not cached); a blob that does not
    decode, or heights outside the tile row's box, raise :class:`StoreCorruptError`.

    Examples
    --------
    >>> tile = decode_heights(t, (0, 0, 0), t.reader.get_blob)
    >>> bool((tile.heights == t.tile(0, 0, 0).heights).all())
    True
    """
    L, x, y = key
    parent = terrain.tile(L + 1, x // 2, y // 2).codes if L < terrain.grid.top_level else None
    if blob is None:
        blob = read_blob(key, "heights")
    from geoterrain.codec.pyramid import decode_tile_valid
    from geoterrain.codec.quantize import tile_heights

    try:
        codes, valid = decode_tile_valid(blob, parent, (x % 2, y % 2), t=terrain.grid.t,
                                         bins=terrain.quantizer.bins)
    except (ValueError, zstandard.ZstdError):
        raise StoreCorruptError(f"{terrain.path}: tile {key} heights cannot be decoded; "
                                "re-run `geoterrain preprocess`") from None
    terrain.decoded_tiles += 1
    # the heights (NaN where not valid) and their scene z range, in one pass: the
    # decoded heights must lie in the tile row's box (a bound checksum on its own
    # cannot tell an edited quantizer or frame from the truth)
    h, zlo, zhi, nv = tile_heights(codes, valid, terrain.quantizer,
                                   terrain.frame.z_to_m * terrain.frame.z_scale)
    info = terrain.tile_info[key]
    tol = 1e-9 * max(1.0, abs(info["zmin"]), abs(info["zmax"]))
    if nv != 0 and not (zlo >= info["zmin"] - tol and zhi <= info["zmax"] + tol):
        raise StoreCorruptError(f"{terrain.path}: tile {key} heights lie outside the tile's "
                                "recorded bounds: the file is damaged; re-run "
                                "`geoterrain preprocess`")
    return Tile(key, codes, h, valid)

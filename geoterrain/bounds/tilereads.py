"""A stored tile's bounds and normals read back: δ, δ_edge and r decoded from their blobs
(with their parents' shared vertices and the guesses from the tile's decoded heights), a
normal map's stored codes, and the normal maps of the levels derived on read.

:class:`geoterrain.terrain.Terrain` reads a tile's blob and hands it here; what these
functions need of the terrain more (its grid, frame, metadata, decoded heights and
parents' bounds) they read through :class:`~geoterrain.terrainlike.TerrainLike`. The
decoders (numba) are imported on first use: opening a store never loads them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import zstandard

from geoterrain.core import zstdsafe
from geoterrain.exceptions import StoreCorruptError

if TYPE_CHECKING:
    from collections.abc import Callable

    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["block_errors", "decode_tile_bounds", "derive_normals", "normal_bytes",
           "normal_ring"]


def decode_tile_bounds(terrain: TerrainLike, key: TileKey, kind: str, stored: str,
                       blob: bytes) -> np.ndarray:
    """Tile ``key``'s ``kind`` (``delta``, ``delta_edge`` or ``radius``), float32 (T, T),
    decoded from its stored ``blob`` of kind ``stored`` (``delta`` for a δ_edge the tile
    does not store apart): what the blob holds, with its parent's shared vertices, the
    rest derived or guessed from the tile's decoded heights
    (:mod:`geoterrain.bounds.vertexdata`'s layouts; :class:`~geoterrain.terrain.Terrain`'s
    ``tile_delta``, ``tile_delta_edge`` and ``tile_radius`` read it). A decoded δ is
    checked against its vertices' own errors.

    Examples
    --------
    >>> key = (0, 0, 0)
    >>> d = decode_tile_bounds(t, key, "delta", "delta", t.reader.get_blob(key, "delta"))
    >>> bool((d == t.tile_delta(*key)).all())
    True
    """
    from geoterrain.bounds.leafbounds import (
        tile_centre_guess,
        tile_centre_radius,
        tile_edge_own_codes,
        tile_leaf_bounds,
        tile_mids_codes,
        tile_own_codes,
    )
    from geoterrain.bounds.vertexdata import (
        DIFF,
        NEW_ONLY,
        PRED,
        RING,
        VERSION_2,
        decode_bounds,
    )

    T = terrain.grid.tile_samples
    L, x, y = key
    parent = None
    if blob[:1] == bytes([VERSION_2]) and blob[1:2] and blob[1] & NEW_ONLY:
        if L >= terrain.grid.top_level:
            raise StoreCorruptError(f"{terrain.path}: tile {key} {kind} has no parent to "
                                    "read; re-run `geoterrain preprocess`")
        # the vertices shared with the parent are stored once, in the parent
        parent = {"delta": terrain.tile_delta, "radius": terrain.tile_radius,
                  "delta_edge": terrain.tile_delta_edge}[kind](L + 1, x // 2, y // 2)
    derive = None
    # a RING blob: the rest from the heights (a geographic store's δ only, with its
    # slack: r would need pyproj's x, y of every sample)
    # A MIDS blob (derive called without rows; a projected or pixel store's r above
    # level 0): its cell centres from the heights and the other samples' codes
    if (L == 0 and stored == "delta") or (stored == "radius"
                                          and terrain.frame.kind != "geographic"):
        def derive(rows, cols, ring, log8, e, slack):
            if rows is None:
                if L == 0:
                    raise ValueError("a level-0 r is a ring, not mids")
                return tile_centre_radius(terrain, key, ring, e)
            if L != 0:
                raise ValueError("a ring is for level 0")
            return tile_leaf_bounds(terrain, key, stored, log8, e, rows, cols, ring, slack)
    # a stored tile's own δ_edge blob may hold differences from its δ codes
    base = (terrain.tile_delta(*key) if stored == "delta_edge" and len(blob) > 1
            and blob[1] & DIFF and key in terrain.tile_info else None)
    if kind == "delta_edge" and stored == "delta" and parent is not None \
            and blob[1] & PRED:
        # a PRED blob's new vertices follow its parent's δ codes, not δ_edge's: the
        # tile's δ there, the parent's δ_edge on the vertices shared with it
        out = terrain.tile_delta(*key).copy()
        h = (T - 1) // 2
        out[::2, ::2] = parent[(y & 1) * h: (y & 1) * h + h + 1,
                               (x & 1) * h: (x & 1) * h + h + 1]
        return out
    # a CENTRES PRED blob (a geographic level-0 r): its centres from the heights' guess;
    # a MIDS PRED one (a geographic r above level 0, schema 20): every new vertex
    guess = None
    if stored == "radius" and key in terrain.tile_info:
        def guess(e, *payload):
            if (L == 0) != (not payload):
                raise ValueError("a level-0 r guesses its centres, a coarser one its mids")
            if not payload:
                return tile_centre_guess(terrain, key, e)
            return tile_mids_codes(terrain, key, e, *payload)
    # a schema-20 δ blob: guessed from the own errors on the tile's heights (the top
    # tile's, schema 23: of its samples ``step`` apart, a level inside it)
    ring = len(blob) > 1 and bool(blob[1] & RING)  # the border's guesses only
    own = ((lambda e, step=1: tile_own_codes(terrain, key, e, ring, step))
           if stored == "delta" and key in terrain.tile_info else None)
    if stored == "delta_edge" and key in terrain.tile_info:
        # a schema-23 δ_edge: guessed from the heights, the padding replicated
        def own(e, step=1):
            return tile_edge_own_codes(terrain, key, e, step)
    try:
        out = decode_bounds(blob, (T, T), parent, (x % 2, y % 2), derive, base, guess,
                            own)
    except (ValueError, zstandard.ZstdError):
        raise StoreCorruptError(f"{terrain.path}: tile {key} {kind} cannot be decoded; "
                                "re-run `geoterrain preprocess`") from None
    if kind == "delta" and key in terrain.tile_info:
        # δ(v) ≥ v's own error on the decoded heights: a δ table swapped with another
        # tile's (checksums recomputed) or edited down fails it (bounds/delta.py)
        from geoterrain.bounds.delta import below_own_error  # loads numba: not on open

        tile = terrain.tile(*key)
        bad = below_own_error(out, terrain.frame.z(tile.heights), tile.valid)
        if bad is not None:
            raise StoreCorruptError(f"{terrain.path}: tile {key} δ is below the error of its "
                                    f"vertex {bad} (bounds swapped or edited): the file "
                                    "is damaged; re-run `geoterrain preprocess`")
    return out


def normal_bytes(terrain: TerrainLike, key: TileKey, blob: bytes) -> tuple[bytes, bool]:
    """A whole stored normal map's codes, decompressed: T·T·2 components, and whether
    they are two planes of 2-D differences (8-bit ``normals_layout`` 2,
    :func:`~geoterrain.bounds.normalbytes.normals_to_bytes`) rather than pairs."""
    T, bits = terrain.grid.tile_samples, terrain.meta["normal_bits"]
    try:  # bounded: exactly T × T × 2 components, never a decompression bomb
        raw = zstdsafe.decompress(blob, T * T * 2 * (bits // 8), exact=True)
    except ValueError:
        raise StoreCorruptError(f"{terrain.path}: tile {key} normals cannot be decoded; "
                                "re-run `geoterrain preprocess`") from None
    from geoterrain.bounds.normalbytes import NORMALS_PLANAR_DXDY

    return raw, bits == 8 and terrain.meta.get("normals_layout", 1) == NORMALS_PLANAR_DXDY


def normal_ring(terrain: TerrainLike, key: TileKey, blob: bytes, n: int) -> np.ndarray:
    """The stored border ring (n = 4T − 4, 2) of a tile on a derived level, in
    :func:`~geoterrain.bounds.normalbytes.ring_index`'s order."""
    from geoterrain.bounds.normalbytes import ring_from_bytes

    try:  # bounded: exactly the ring's 4T − 4 pairs
        return ring_from_bytes(zstdsafe.decompress(blob, 2 * n, exact=True),
                               terrain.meta.get("normals_ring_residual") is True)
    except ValueError:
        raise StoreCorruptError(f"{terrain.path}: tile {key} normals cannot be decoded; "
                                "re-run `geoterrain preprocess`") from None


def derive_normals(terrain: TerrainLike, keys: list[TileKey], bits: int,
                   ring: Callable[[TileKey, int], np.ndarray]) -> np.ndarray:
    """The codes of tiles on derived levels: the normal map of each one's decoded
    heights (the preprocess's central differences of the level's samples, seed 000's
    normal-map lighting, :func:`~geoterrain.bounds.normals.level_normal_maps`: they
    read no sample outside the tile there), encoded as the preprocess encodes, with
    its stored border ring."""
    from geoterrain.bounds.leafbounds import normal_axes, normal_xy
    from geoterrain.bounds.normalbytes import ring_index
    from geoterrain.bounds.normals import derived_codes

    T, n = terrain.grid.tile_samples, len(keys)
    rr, cc = ring_index(T)
    h = np.empty((n, T, T))
    valid = np.empty((n, T, T), bool)
    rings = np.empty((n, len(rr), 2), np.uint8 if bits == 8 else np.uint16)
    axes = terrain.frame.kind != "geographic"  # x by column, y by row: broadcast views
    X = np.zeros((n, T) if axes else (n, T, T))
    Y = np.zeros((n, T) if axes else (n, T, T))
    for k, key in enumerate(keys):
        tile = terrain.tile(*key)
        h[k], valid[k] = tile.heights, tile.valid
        rings[k] = ring(key, len(rr))
        X[k], Y[k] = normal_axes(terrain, *key) if axes else normal_xy(terrain, *key)
    if axes:
        X = np.broadcast_to(X[:, None, :], (n, T, T))
        Y = np.broadcast_to(Y[:, :, None], (n, T, T))
    # schema 17: a ring code stored as its difference from the derived one
    return derived_codes(h, terrain.frame.z_to_m * terrain.frame.z_scale, valid, X, Y, rings,
                         (rr, cc), bits, terrain.meta.get("normals_ring_residual") is True)


def block_errors(terrain: TerrainLike, read_blob: Callable[[TileKey, str], bytes]
                 ) -> np.ndarray | None:
    """Every GeoMipMapping block's exact δ_n (seed 000 §2.4), (nb, nb, levels) indexed
    [y, x, n], nb the level-0 tiles per side (a root grid: its level-0 tiles down,
    across), n = 0 … min(t, top level) (see
    :func:`geoterrain.bounds.tilebounds.tile_and_block_errors`); None for a store written
    before the table was.

    Examples
    --------
    >>> block_errors(t, t.reader.get_blob).shape[:2] == t.grid.tiles(0)[::-1]
    True
    """
    levels = terrain.meta.get("block_delta_levels")
    if levels is None:
        return None

    def make():
        nb = terrain.grid.tiles(0)[::-1]
        key = (terrain.grid.top_level, 0, 0)
        try:
            from geoterrain.bounds.tilebounds import unpack_block_errors

            table = unpack_block_errors(read_blob(key, "block_delta"), nb, levels)
            table.setflags(write=False)  # shared through the cache
            return table
        except ValueError as exc:
            raise StoreCorruptError(f"{terrain.path}: the block δ_n table is damaged "
                                    f"({exc}); re-run `geoterrain preprocess`") from None

    return terrain.memo(("block_delta",), make)

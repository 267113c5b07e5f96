"""A store's keys: tiles and blobs named by one small integer each (schemas 3 and 4).

A tile's (level, x, y) packs as the Morton number of (x, y) times 32 plus the level, a
blob's place as its tile's key times 8 plus its kind's number. Near tiles get near
numbers, so the tile table's sorted key columns are small differences (docs/store.md).
The blob kinds and their numbers live here too: stores hold the numbers, so they never
change.

Examples
--------
>>> unpack_blob_key(blob_key((2, 5, 9), "radius"))
((2, 5, 9), 'radius')
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["BLOB_KINDS", "BLOCK_KIND", "EDGE_KIND", "KIND_CODES", "blob_key", "pack_blob_key",
           "pack_tile_key", "tile_key",
           "unpack_blob_key", "unpack_tile_key", "unpack_tile_keys"]

BLOB_KINDS = ("heights", "delta", "radius", "normals")
# optional: a second δ (padding replicated, geoterrain/bounds/edgepad.py) on the tiles that the
# metadata's "delta_edge" list names, and on no other
EDGE_KIND = "delta_edge"
# optional: every GeoMipMapping block's exact δ_n (geoterrain/bounds/tilebounds.py), one table
# for the whole grid, on the root tile, when the metadata has "block_delta_levels"
BLOCK_KIND = "block_delta"
# every kind's number in a blob key (never renumber: stores hold them)
KIND_CODES = {k: i for i, k in enumerate((*BLOB_KINDS, EDGE_KIND, BLOCK_KIND))}
_KINDS = {i: k for k, i in KIND_CODES.items()}
_COORD_BITS = 26  # x, y < 2^26 tiles a side: keys stay below 2^62


_SPREAD8 = [sum(((b >> i) & 1) << (2 * i) for i in range(8)) for b in range(256)]
_GATHER8 = [sum(((b >> (2 * i)) & 1) << i for i in range(4)) for b in range(256)]


def _spread(v: int) -> int:
    """The bits of ``v`` (< 2^32) moved to the even positions (Morton order's half)."""
    return (_SPREAD8[v & 255] | _SPREAD8[(v >> 8) & 255] << 16
            | _SPREAD8[(v >> 16) & 255] << 32 | _SPREAD8[(v >> 24) & 255] << 48)


def _gather(m: int) -> int:
    """The inverse of :func:`_spread`: the even bits of ``m``, packed."""
    out, bit = 0, 0
    while m:
        out |= _GATHER8[m & 255] << bit
        m >>= 8
        bit += 4
    return out


def pack_tile_key(key: tuple[int, int, int]) -> int:
    """:func:`tile_key` without its cache: what a writer packs, each key once (the cache's
    65 536 entries held 17.5 MB traced through a 16385² store's writing, docs/lab/streaming.md).

    Examples
    --------
    >>> pack_tile_key((2, 1, 0)) == tile_key((2, 1, 0))
    True
    """
    level, x, y = (int(v) for v in key)
    if not (0 <= level < 32 and 0 <= x < 1 << _COORD_BITS and 0 <= y < 1 << _COORD_BITS):
        raise ValueError(f"tile key {key} out of range")
    return ((_spread(x) | _spread(y) << 1) << 5) | level


@lru_cache(maxsize=1 << 16)  # a reader packs the same few keys over and over
def tile_key(key: tuple[int, int, int]) -> int:
    """A tile's (level, x, y) as one small integer: the Morton number of (x, y) times
    32, plus the level (< 32). Tiles near each other get near numbers, and level-L
    keys stay below 32 · 4^(top − L).

    Examples
    --------
    >>> tile_key((0, 0, 0)), tile_key((2, 1, 0)), tile_key((0, 1, 1))
    (0, 34, 96)
    >>> unpack_tile_key(tile_key((3, 5, 9)))
    (3, 5, 9)
    """
    return pack_tile_key(key)


def unpack_tile_key(k: int) -> tuple[int, int, int]:
    """(level, x, y) of a :func:`tile_key`; ValueError for a negative number."""
    if k < 0:
        raise ValueError(f"tile key {k} is negative")
    m = k >> 5
    return k & 31, _gather(m), _gather(m >> 1)


def _gather_even(m: np.ndarray) -> np.ndarray:
    """The even bits of each ``m`` (uint64), packed: :func:`_gather` on whole arrays."""
    m = m & np.uint64(0x5555555555555555)
    for shift, mask in ((1, 0x3333333333333333), (2, 0x0F0F0F0F0F0F0F0F),
                        (4, 0x00FF00FF00FF00FF), (8, 0x0000FFFF0000FFFF),
                        (16, 0x00000000FFFFFFFF)):
        m = (m | (m >> np.uint64(shift))) & np.uint64(mask)
    return m.astype(np.int64)


def unpack_tile_keys(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(level, x, y) arrays of many :func:`tile_key` numbers at once (int64); ValueError
    where one is negative.

    Examples
    --------
    >>> L, x, y = unpack_tile_keys(np.array([tile_key((3, 5, 9)), tile_key((0, 1, 1))]))
    >>> L.tolist(), x.tolist(), y.tolist()
    ([3, 0], [5, 1], [9, 1])
    """
    k = np.asarray(keys, np.int64)
    if k.size and int(k.min()) < 0:
        raise ValueError(f"tile key {int(k.min())} is negative")
    m = (k >> 5).astype(np.uint64)
    return k & 31, _gather_even(m), _gather_even(m >> np.uint64(1))


def pack_blob_key(key: tuple[int, int, int], kind: str) -> int:
    """:func:`blob_key` through :func:`pack_tile_key` (no cache): a writer's.

    Examples
    --------
    >>> pack_blob_key((1, 2, 3), "normals") == blob_key((1, 2, 3), "normals")
    True
    """
    return pack_tile_key(key) << 3 | KIND_CODES[kind]


def blob_key(key: tuple[int, int, int], kind: str) -> int:
    """A blob's place as one small integer: its :func:`tile_key` times 8 plus the kind's
    number (:data:`KIND_CODES`).

    Examples
    --------
    >>> blob_key((0, 0, 0), "delta"), unpack_blob_key(blob_key((1, 2, 3), "normals"))
    (1, ((1, 2, 3), 'normals'))
    """
    return tile_key(key) << 3 | KIND_CODES[kind]


def unpack_blob_key(k: int) -> tuple[tuple[int, int, int], str]:
    """((level, x, y), kind) of a :func:`blob_key`; KeyError for an unknown kind,
    ValueError for a negative number."""
    return unpack_tile_key(k >> 3), _KINDS[k & 7]

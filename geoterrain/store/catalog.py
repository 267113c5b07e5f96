"""The two rows of a store's ``catalog`` table: the metadata and the tile table.

Row :data:`META_ID` is the metadata, one JSON object (names sorted), zstd-compressed.
Row :data:`TILES_ID` is the tile table (:func:`pack_tiles`): every tile's packed key
(:func:`geoterrain.store.keys.tile_key`) and numbers (:data:`TILE_COLUMNS`), and every
blob's packed key (:func:`geoterrain.store.keys.blob_key`) and row id in ``blobs``,
column by column: a 9-byte head (format: 0 raw, 1 zstd; tile count n; blob count m),
then the n tile keys as int64 differences, 11 float64 columns of n numbers with each
column's bytes shuffled (the first byte of every number, then the second, ...), the m
blob keys and the m ids as int64 differences.

Both rows come from a file that may come from a stranger. Each is bound to its id by a
CRC-32 (:func:`catalog_crc`); the metadata decodes to at most 1 MB; the tile table's
head must fit the file (every tile owns at least 4 blob rows, a blob row at least
:data:`MIN_BLOB_ROW_BYTES` of it), and a zstd table may not decode to more than
:data:`RATIO_CAP` times its bytes, so a small file cannot ask for much memory. The
writer stores a table that compresses further than that raw. See docs/store.md.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass

import numpy as np
import zstandard

from geoterrain.core import zstdsafe
from geoterrain.store.keys import BLOB_KINDS

META_ID, TILES_ID = 0, 1  # the catalog rows of the metadata and of the tile table
TILE_COLUMNS = ("nvalid", "zmin", "zmax", "error", "boundary_error",
                "xmin", "xmax", "ymin", "ymax", "delta_max", "radius_max")
RATIO_CAP = 256  # a zstd tile table decodes to at most this many times its bytes + 64 kB
MIN_BLOB_ROW_BYTES = 6  # a blobs row's least share of a file: cell pointer, header, rowid
META_MAX_BYTES = 1 << 20  # metadata is a few kB; more is not a store of ours
KEY_LIMIT = 1 << 62  # every packed key is below this (storekeys)
_RATIO_SLACK = 1 << 16
_HEAD = struct.Struct("<BII")  # format (0 raw, 1 zstd), tiles, blobs
_ZSTD_STRONG = 19  # a few kB of numbers in most stores: the strongest level costs little
_ZSTD_STRONG_MAX = 1 << 20  # ... up to a table of this many bytes (see pack_tiles)

__all__ = ["KEY_LIMIT", "META_ID", "META_MAX_BYTES", "MIN_BLOB_ROW_BYTES", "RATIO_CAP",
           "TILES_ID", "TILE_COLUMNS", "TileTable", "catalog_crc", "pack_metadata",
           "pack_stream", "pack_tiles", "table_columns", "unpack_metadata", "unpack_tiles"]


def catalog_crc(row_id: int, data: bytes) -> int:
    """CRC-32 of a catalog row bound to its id.

    Examples
    --------
    >>> catalog_crc(0, b"x") != catalog_crc(1, b"x")
    True
    """
    return zlib.crc32(data, zlib.crc32(struct.pack("<q", row_id)))


@dataclass(frozen=True)
class TileTable:
    """The catalog's tile table: every tile and every blob, ascending by key.

    ``numbers`` is (tiles, len(TILE_COLUMNS)) float64 in the order of
    :data:`TILE_COLUMNS`, NaN where a number is absent (an empty tile's bounds).
    """

    tiles: np.ndarray  # int64 packed tile keys (tile_key)
    numbers: np.ndarray  # float64 (tiles, 11)
    blobs: np.ndarray  # int64 packed blob keys (blob_key)
    ids: np.ndarray  # int64 their rowids in ``blobs``


def _ascending(raw: memoryview, n: int) -> np.ndarray:
    # a delta-coded key column back: every step > 0 and every key in [0, KEY_LIMIT); a
    # sum past 2^63 wraps to a negative number (each step is below 2^63), which the
    # range test refuses
    d = np.frombuffer(raw, "<i8", n)
    a = np.cumsum(d, dtype=np.int64)
    if n and ((d[1:] <= 0).any() or a[0] < 0 or (a < 0).any() or a[-1] >= KEY_LIMIT):
        raise ValueError("keys not ascending or out of range")
    return a


def _delta_chunks(chunks):
    # int64 differences of an ascending column given in chunks (the first from 0)
    last = np.int64(0)
    for c in chunks:
        c = np.asarray(c, np.int64)
        if len(c):
            yield np.diff(c, prepend=last).astype("<i8").tobytes()
            last = c[-1]


def _shuffled(col: np.ndarray) -> bytes:
    # a float64 column's bytes by significance: every value's first byte, then second...
    return np.ascontiguousarray(col, "<f8").view(np.uint8).reshape(len(col), 8).T.tobytes()


def table_columns(keys, columns, blob_keys, blob_ids):
    """The tile table's bytes in pieces, for :func:`pack_stream`: ``keys`` (chunks of
    ascending tile keys), ``columns`` (the 11 number columns, each whole, in key order),
    ``blob_keys`` and ``blob_ids`` (chunks, in blob key order); iterables, read lazily."""
    yield from _delta_chunks(keys)
    for col in columns:
        yield _shuffled(col)
    yield from _delta_chunks(blob_keys)
    yield from _delta_chunks(blob_ids)


def pack_stream(n: int, m: int, pieces, fast: bool = False) -> bytes:
    """The tile table's catalog row for n tiles and m blobs whose bytes ``pieces()``
    gives (:func:`table_columns`; called again for a raw row): zstd (level 19 up to
    1 MiB, whose compressor then needs a few MB; 3 above, where 19 would need about
    100 MB; 3 when ``fast``), or raw when zstd would pass :data:`RATIO_CAP`."""
    size = 8 * (n * (1 + len(TILE_COLUMNS)) + 2 * m)
    level = _ZSTD_STRONG if size <= _ZSTD_STRONG_MAX and not fast else 3
    z = zstandard.ZstdCompressor(level=level).compressobj(size=size)
    packed = zstdsafe.strip_magic(b"".join([z.compress(c) for c in pieces()] + [z.flush()]))
    if size > RATIO_CAP * len(packed) + _RATIO_SLACK:
        return _HEAD.pack(0, n, m) + b"".join(pieces())
    return _HEAD.pack(1, n, m) + packed


def pack_tiles(table: TileTable, fast: bool = False) -> bytes:
    """The tile table's catalog row (see the module docstring). ``fast``: zstd level 3,
    not 19 (an edit rewrites the row: on a 4097² store's 5461 tiles, 9 ms for 135 kB
    against 0.26 s for 109 kB).

    Examples
    --------
    >>> t = TileTable(np.array([0, 64]), np.ones((2, 11)), np.arange(8), np.arange(1, 9))
    >>> u = unpack_tiles(pack_tiles(t))
    >>> [np.array_equal(getattr(t, f), getattr(u, f)) for f in ("tiles", "numbers", "blobs", "ids")]
    [True, True, True, True]
    """
    nums = np.asarray(table.numbers, np.float64).reshape(len(table.tiles), len(TILE_COLUMNS))
    return pack_stream(len(table.tiles), len(table.blobs), lambda: table_columns(
        [table.tiles], nums.T, [table.blobs], [table.ids]), fast)


def unpack_tiles(data: bytes, file_bytes: int | None = None) -> TileTable:
    """The :class:`TileTable` of its catalog row; ValueError for anything malformed
    (sizes, keys not strictly ascending or out of range, fewer than 4 blobs a tile, more
    blobs than a file of ``file_bytes`` can hold, a zstd frame past :data:`RATIO_CAP`),
    before decoding what the head claims."""
    if len(data) < _HEAD.size:
        raise ValueError("too short")
    fmt, n, m = _HEAD.unpack_from(data)
    if len(BLOB_KINDS) * n > m or (file_bytes is not None and MIN_BLOB_ROW_BYTES * m > file_bytes):
        raise ValueError(f"{n} tiles and {m} blobs cannot be a store of this size")
    body = memoryview(data)[_HEAD.size:]
    size = 8 * (n * (1 + len(TILE_COLUMNS)) + 2 * m)
    if fmt == 1:
        if size > RATIO_CAP * len(body) + _RATIO_SLACK:
            raise ValueError("claims too many rows for its size")
        body = memoryview(zstdsafe.decompress(body, size, exact=True))
    elif fmt != 0 or len(body) != size:
        raise ValueError("of an unknown format or size")
    tiles = _ascending(body[:8 * n], n)
    off, nb = 8 * n, 8 * n * len(TILE_COLUMNS)
    numbers = (np.frombuffer(body[off:off + nb], np.uint8).reshape(len(TILE_COLUMNS), 8, n)
               .transpose(2, 0, 1).copy().view("<f8").reshape(n, len(TILE_COLUMNS)))
    off += nb
    blobs = _ascending(body[off:off + 8 * m], m)
    ids = np.cumsum(np.frombuffer(body[off + 8 * m:], "<i8", m), dtype=np.int64)
    return TileTable(tiles, numbers.astype(np.float64), blobs, ids)


def pack_metadata(items: dict) -> bytes:
    """The metadata's catalog row: its JSON (names sorted), zstd-compressed.

    Examples
    --------
    >>> unpack_metadata(pack_metadata({"b": 1, "a": [2.5, None]}))
    {'a': [2.5, None], 'b': 1}
    """
    text = json.dumps(items, sort_keys=True)
    # the one frame kept whole, with zstd's magic number (4 bytes a store): a geoterrain
    # from before schema 10 then reads the schema version and says to upgrade, rather
    # than calling the file damaged
    return zstandard.ZstdCompressor(level=_ZSTD_STRONG).compress(text.encode())


def unpack_metadata(data: bytes) -> dict:
    """The metadata of its catalog row; ValueError (saying why) for anything but a JSON
    object of at most 1 MB whose names are distinct at any depth."""
    try:
        items = json.loads(zstdsafe.decompress(data, META_MAX_BYTES),
                           object_pairs_hook=_unique_names)
    except RecursionError:
        raise ValueError("nested too deep") from None
    except UnicodeDecodeError:
        raise ValueError("not UTF-8 text") from None
    except json.JSONDecodeError:
        raise ValueError("not JSON") from None
    if not isinstance(items, dict):
        raise ValueError("not a JSON object")
    return items


def _unique_names(pairs: list) -> dict:
    out = dict(pairs)
    if len(out) != len(pairs):
        raise ValueError("it names an entry twice")
    return out

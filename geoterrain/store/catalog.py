"""The two rows of a store's ``catalog`` table: the metadata and the tile table.

Row :data:`META_ID` is the metadata, one JSON object (names sorted), zstd-compressed.
Row :data:`TILES_ID` is the tile table (:func:`pack_tiles`): every tile's packed key
(:func:`geoterrain.store.keys.tile_key`) and numbers (:data:`TILE_COLUMNS`), and every
blob's packed key (:func:`geoterrain.store.keys.blob_key`) and row id in ``blobs``,
column by column: a 10-byte head (format: 0 raw, 1 zstd; tile count n; blob count m;
the ids' width w: 2, 4 or 8 bytes), then the n tile keys as int64 differences, the 11
number columns, the m blob keys as int64 differences and the m ids (w bytes each,
shuffled: every id's first byte, then the second...). Schema 17's columns are predicted
from what a reader already knows (:func:`column_bytes`), and each is stored as n int64
residuals, shuffled likewise:

* ``nvalid``, ``error``, ``boundary_error``, ``delta_max``, ``radius_max``: the numbers'
  float64 bits;
* ``zmin`` and ``zmax``: a tile's range holds its footprint's valid samples, and a
  parent's footprint is the union of its children's, so a tile with stored children is
  predicted as their union, exactly: the residual is 0 (bits in an order-preserving
  integer map, so the prediction is integer arithmetic, the same on any machine);
* ``xmin`` … ``ymax``: the box rounded outward to a multiple of :data:`BOX_STEP` (2^-12
  scene units: a box holds its tile's samples, larger by less than a step, the same step
  wherever the scene lies), as integers; a tile with stored children is their union
  (residual 0), and each level-0 tile, in key order, the one before it moved by its key's
  steps in x and y (two integers per column, stored before it: the median steps);
  residuals zigzag-coded. A column with a number that is not finite or past
  :data:`BOX_LIMIT` is stored as ``zmin`` is, exactly (a flag byte says which).

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
from dataclasses import dataclass, field

import numpy as np
import zstandard

from geoterrain.core import zstdsafe
from geoterrain.core.limits import BOX_STEP  # the stored boxes are rounded outward to it
from geoterrain.store.keys import BLOB_KINDS

META_ID, TILES_ID = 0, 1  # the catalog rows of the metadata and of the tile table
TILE_COLUMNS = ("nvalid", "zmin", "zmax", "error", "boundary_error",
                "xmin", "xmax", "ymin", "ymax", "delta_max", "radius_max")
RATIO_CAP = 256  # a zstd tile table decodes to at most this many times its bytes + 64 kB
MIN_BLOB_ROW_BYTES = 6  # a blobs row's least share of a file: cell pointer, header, rowid
META_MAX_BYTES = 1 << 20  # metadata is a few kB; more is not a store of ours
KEY_LIMIT = 1 << 62  # every packed key is below this (storekeys)
BOX_LIMIT = 2.0 ** 38  # |coordinate| up to which a box column is stored so (SCENE_LIMIT: 1e8)
_RATIO_SLACK = 1 << 16
# format (0 raw, 1 zstd), tiles, blobs, the ids' width, the boxes' coding (0 exact, 1 on
# BOX_STEP's grid), the level-0 grid's holes (positions without a tile)
_HEAD = struct.Struct("<BIIBBI")
_ZSTD_STRONG = 19  # a few kB of numbers in most stores: the strongest level costs little
_ZSTD_STRONG_MAX = 1 << 20  # ... up to a table of this many bytes (see pack_tiles)
# each column's prediction: "union" (min or max of the stored children), "box" (union,
# and level 0 from the tile before it, on a grid of BOX_STEP), or the bits as they are
_UNION = {"zmin": np.minimum, "zmax": np.maximum}
_BOXES = {"xmin": (np.minimum, np.floor), "xmax": (np.maximum, np.ceil),
          "ymin": (np.minimum, np.floor), "ymax": (np.maximum, np.ceil)}
_HOLES = (4, 4096)  # the level-0 grid is at most 4 × its tiles + 4096 positions
_SIGN = np.int64(0x7FFFFFFFFFFFFFFF)

__all__ = ["BOX_LIMIT", "BOX_STEP", "KEY_LIMIT", "META_ID", "META_MAX_BYTES",
           "MIN_BLOB_ROW_BYTES", "Packed", "RATIO_CAP", "TILES_ID", "TILE_COLUMNS", "TileTable",
           "box_coding", "catalog_crc", "column_bytes", "pack_metadata", "pack_stream",
           "pack_tiles", "stored_numbers", "table_columns", "table_layout", "unpack_metadata",
           "unpack_tiles"]


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
    # what packing a table of these tiles again can take from the row it was unpacked
    # from (unpack_tiles; pack_tiles checks it applies): an edit's table
    packed: Packed | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Packed:
    """What :func:`unpack_tiles` keeps of a row for :func:`pack_tiles` to pack a table of
    the same tiles again without the work (an edit's, issue 52): the tiles' ``tree``
    (:class:`_Tree`), and the stored bytes of the box columns (``boxes``: the numbers
    ``numbers[:, j]`` the bytes of column j, on BOX_STEP's grid, are of), the dearest to
    code (union and planar predictions) and the ones an edit that keeps every sample's
    validity leaves as they are: about 50 bytes a tile, held with the table."""

    tree: _Tree
    numbers: np.ndarray
    boxes: dict  # column index → its stored bytes (column_bytes with boxes=1)


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
    # a column's bytes by significance: every value's first byte, then second...
    c = np.ascontiguousarray(col, col.dtype.newbyteorder("<"))
    return c.view(np.uint8).reshape(len(c), c.dtype.itemsize).T.tobytes()


def _unshuffled(raw, n: int, dtype: str) -> np.ndarray:
    w = np.dtype(dtype).itemsize
    return np.frombuffer(raw, np.uint8, w * n).reshape(w, n).T.copy().view(dtype).ravel()


def _ordered(bits: np.ndarray) -> np.ndarray:
    # float64 bits (int64) to integers in the numbers' order, and back (an involution)
    return np.where(bits < 0, bits ^ _SIGN, bits)


def _zigzag(v: np.ndarray) -> np.ndarray:
    # in place: v's sign spread over every bit, xor v shifted left
    sign = v >> 63
    v <<= 1
    v ^= sign
    return v


def _unzigzag(u: np.ndarray) -> np.ndarray:
    return (u.view(np.uint64) >> np.uint64(1)).view(np.int64) ^ -(u & 1)


def _id_width(ids: np.ndarray) -> int:
    lo, hi = (int(ids.min()), int(ids.max())) if len(ids) else (0, 0)
    return 8 if lo < 0 else 2 if hi < 1 << 16 else 4 if hi < 1 << 32 else 8


class _Tree:
    """The tiles' quadtree from their sorted keys: each tile's level, its parent's index
    (−1: not stored), and level 0's tiles (``zero``, key order) on their grid: row and
    column from the smallest y and x (``gy``, ``gx``), the grid's ``shape`` and ``area``."""

    def __init__(self, keys: np.ndarray):
        self.keys = keys = np.asarray(keys, np.int64)
        self.n = n = len(keys)
        # indices in 4 bytes where they fit: a 16385² pyramid's 87 381 tiles are packed
        # at the end of a streamed preprocess, whose peak memory is held to a bound
        idx = np.int32 if n < 1 << 31 else np.int64
        self.level = (keys & 31).astype(np.int8)
        # the parent (L + 1, x >> 1, y >> 1): the Morton number shifted by one place
        pk = ((keys >> 7) << 5) | (self.level + 1)
        at = np.minimum(np.searchsorted(keys, pk), max(n - 1, 0)).astype(idx)
        ok = (keys[at] == pk) & (self.level < 31) if n else np.zeros(0, bool)
        del pk
        self.kids = np.flatnonzero(ok).astype(idx)  # the tiles whose parent is stored
        self.kid_parent = at[self.kids]  # ... and its index
        del at, ok
        self.top = int(self.level.max()) if n else 0
        self.zero = np.flatnonzero(self.level == 0).astype(idx)
        self.shape, self.area = (0, 0), 0
        self.gx = self.gy = np.zeros(0, idx)
        if len(self.zero):
            from geoterrain.store.keys import _gather_even

            # (any int64: a writer packs whatever it is given, the reader refuses it)
            m = (keys[self.zero] >> 5).view(np.uint64)
            x, y = _gather_even(m), _gather_even(m >> np.uint64(1))
            gx, gy = x - x.min(), y - y.min()
            self.shape = (int(gy.max()) + 1, int(gx.max()) + 1)
            self.area = self.shape[0] * self.shape[1]
            # (a grid past grid_fits is never built: its positions may not fit idx)
            self.gx, self.gy = (gx.astype(idx), gy.astype(idx)) if self.grid_fits() else (gx, gy)

    def grid_fits(self) -> bool:
        """Whether level 0's grid is small enough to code the boxes on (_HOLES)."""
        return self.area <= _HOLES[0] * len(self.zero) + _HOLES[1]

    def _union(self, v: np.ndarray, op, kids: np.ndarray, par: np.ndarray) -> tuple:
        # the union of v over ``kids`` into their parents ``par``: (prediction, has a kid)
        info = np.iinfo(np.int64)
        pred = np.full(self.n, info.max if op is np.minimum else info.min, np.int64)
        op.at(pred, par, v[kids])
        has = np.zeros(self.n, bool)
        has[par] = True
        return pred, has

    def union(self, v: np.ndarray, op) -> np.ndarray:
        """Every tile's prediction from its children's values ``v`` (int64; ``op``
        np.minimum or np.maximum): their union, 0 for a tile without a stored child."""
        pred, has = self._union(v, op, self.kids, self.kid_parent)
        pred[~has] = 0
        return pred

    def ununion(self, res: np.ndarray, op) -> np.ndarray:
        """Values from :meth:`union`'s residuals ``res`` (level 0's already values),
        level by level, each from the finer level's values."""
        v = res.copy()
        lv = self.level[self.kids]
        for L in range(self.top):
            sel = lv == L
            if not sel.any():
                continue
            pred, has = self._union(v, op, self.kids[sel], self.kid_parent[sel])
            v[has] = res[has] + pred[has]  # int64, wrapping as the writer's difference
        return v

    def planar(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Level 0's values ``v`` (int64, key order) on their grid (0 at holes) as the
        planar predictor's residuals a − left − up + up-left (LOCO-I's plane, seed-free
        and exact in int64): at the tiles (key order) and at the holes (row order)."""
        a = np.zeros(self.shape, np.int64)
        a[self.gy, self.gx] = v
        r = a.copy()
        r[:, 1:] -= a[:, :-1]
        r[1:, :] -= a[:-1, :]
        r[1:, 1:] += a[:-1, :-1]
        hole = np.ones(self.shape, bool)
        hole[self.gy, self.gx] = False
        return r[self.gy, self.gx], r[hole]

    def unplanar(self, at_tiles: np.ndarray, at_holes: np.ndarray) -> np.ndarray:
        """:meth:`planar`'s inverse: two prefix sums over the grid."""
        r = np.zeros(self.shape, np.int64)
        hole = np.ones(self.shape, bool)
        hole[self.gy, self.gx] = False
        r[hole] = at_holes
        r[self.gy, self.gx] = at_tiles
        return np.cumsum(np.cumsum(r, 0, dtype=np.int64), 1, dtype=np.int64)[self.gy, self.gx]


def _box_ints(col: np.ndarray, rnd) -> np.ndarray | None:
    """A box column as integer multiples of BOX_STEP rounded outward, or None when a
    number is not finite or past BOX_LIMIT (the column is then stored exactly)."""
    col = np.asarray(col, np.float64)
    if not (np.abs(col) <= BOX_LIMIT).all():  # NaN fails too
        return None
    return rnd(col / BOX_STEP).astype(np.int64)


def stored_numbers(keys: np.ndarray, numbers: np.ndarray) -> np.ndarray:
    """The numbers of the tiles ``keys`` as a reader gets them back from
    :func:`pack_tiles`: the four box columns rounded outward to multiples of
    :data:`BOX_STEP` where :func:`box_coding` codes them so (every box number finite and
    within :data:`BOX_LIMIT`, level 0's tiles filling enough of their grid), every other
    number as it is.

    Examples
    --------
    >>> nums = np.zeros((1, 11))
    >>> nums[0, 5:9] = [-1.00001, 1.00001, 0.5, 2.0]
    >>> stored_numbers(np.array([0]), nums)[0, 5:9].tolist()
    [-1.000244140625, 1.000244140625, 0.5, 2.0]
    """
    out = np.array(numbers, np.float64).reshape(-1, len(TILE_COLUMNS))
    if box_coding(_Tree(keys), lambda j: out[:, j])[0]:
        for c, (_, rnd) in _BOXES.items():
            j = TILE_COLUMNS.index(c)
            out[:, j] = _box_ints(out[:, j], rnd) * BOX_STEP
    return out


def box_coding(tree: _Tree, column) -> tuple[int, int]:
    """(1, the level-0 grid's holes) when the four box columns (``column(j)``) are coded on
    BOX_STEP's grid: every number finite and within BOX_LIMIT, and level 0's grid within
    _HOLES; else (0, 0), each stored exactly."""
    ok = tree.grid_fits() and all(
        _box_ints(column(TILE_COLUMNS.index(c)), rnd) is not None
        for c, (_, rnd) in _BOXES.items())
    return (1, tree.area - len(tree.zero)) if ok else (0, 0)


def column_bytes(tree: _Tree, name: str, col: np.ndarray, boxes: int = 1) -> bytes:
    """One number column of the tile table as stored (see the module docstring;
    ``boxes``: :func:`box_coding`'s first value)."""
    col = np.asarray(col, np.float64)
    if name in _BOXES and boxes:
        op, rnd = _BOXES[name]
        q = _box_ints(col, rnd)
        res = tree.union(q, op)
        np.subtract(q, res, out=res)
        res[tree.zero], holes = tree.planar(q[tree.zero])
        del q
        res = np.concatenate([res, holes])
        del holes
        return _shuffled(_zigzag(res))
    bits = col.view(np.int64)
    op = _UNION.get(name) or _BOXES.get(name, (None,))[0]
    if op is not None:
        u = _ordered(bits)
        pred = tree.union(u, op)
        np.subtract(u, pred, out=pred)
        del u
        return _shuffled(pred)
    return _shuffled(bits)


def _column(tree: _Tree, name: str, raw, boxes: int, holes: int) -> np.ndarray:
    # column_bytes' inverse (raw: exactly its bytes)
    n = tree.n
    if name in _BOXES and boxes:
        op, _ = _BOXES[name]
        res = _unzigzag(_unshuffled(raw, n + holes, "<i8"))
        v = res[:n].copy()
        v[tree.zero] = tree.unplanar(v[tree.zero], res[n:])
        return tree.ununion(v, op).astype(np.float64) * BOX_STEP
    v = _unshuffled(raw, n, "<i8")
    op = _UNION.get(name) or _BOXES.get(name, (None,))[0]
    if op is not None:
        v = _ordered(tree.ununion(v, op))
    return v.view(np.float64)


def _column_size(name: str, n: int, holes: int) -> int:
    return 8 * (n + (holes if name in _BOXES else 0))


def _table_size(n: int, m: int, w: int, holes: int) -> int:
    return 8 * n + sum(_column_size(c, n, holes) for c in TILE_COLUMNS) + (8 + w) * m


def table_layout(keys, column, tree: _Tree | None = None) -> tuple[_Tree, int, int]:
    """What :func:`table_columns` and :func:`pack_stream` need first: the tiles' tree of
    ``keys`` (ascending, whole; ``tree``: theirs, built already) and :func:`box_coding`
    of the columns ``column(j)``."""
    tree = _Tree(keys) if tree is None else tree
    return (tree, *box_coding(tree, column))


def table_columns(tree: _Tree, column, blob_keys, blob_ids, width: int, boxes: int,
                  known=None):
    """The tile table's bytes in pieces, for :func:`pack_stream`: the tree's keys
    (:func:`table_layout`), ``column(j)`` (number column j, whole, in key order),
    ``blob_keys`` and ``blob_ids`` (chunks, in blob key order; iterables, read lazily),
    ``width`` the ids' (2, 4 or 8 bytes), ``boxes`` the boxes' coding; ``known(j, col)``:
    column j's bytes where known already (None where not)."""
    yield from _delta_chunks([tree.keys])
    for j, name in enumerate(TILE_COLUMNS):
        col = column(j)
        got = None if known is None else known(j, col)
        yield column_bytes(tree, name, col, boxes) if got is None else got
    yield from _delta_chunks(blob_keys)
    dtype = f"<i{width}" if width == 8 else f"<u{width}"
    yield _shuffled(np.concatenate([np.asarray(c, np.int64).astype(dtype) for c in blob_ids]
                                   + [np.zeros(0, dtype)]))


def pack_stream(n: int, m: int, width: int, boxes: int, holes: int, pieces,
                fast: bool = False) -> bytes:
    """The tile table's catalog row for n tiles and m blobs (ids ``width`` bytes each;
    ``boxes`` and ``holes`` of :func:`table_layout`) whose bytes ``pieces()`` gives
    (:func:`table_columns`; called again for a raw row): zstd (level 19 up to 1 MiB,
    whose compressor then needs a few MB; 3 above, where 19 would need about 100 MB; 3
    when ``fast``), or raw when zstd would pass :data:`RATIO_CAP`."""
    size = _table_size(n, m, width, holes)
    level = _ZSTD_STRONG if size <= _ZSTD_STRONG_MAX and not fast else 3
    z = zstandard.ZstdCompressor(level=level).compressobj(size=size)
    packed = zstdsafe.strip_magic(b"".join([z.compress(c) for c in pieces()] + [z.flush()]))
    if size > RATIO_CAP * len(packed) + _RATIO_SLACK:
        return _HEAD.pack(0, n, m, width, boxes, holes) + b"".join(pieces())
    return _HEAD.pack(1, n, m, width, boxes, holes) + packed


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
    ids = np.asarray(table.ids, np.int64)
    width = _id_width(ids)

    def column(j: int) -> np.ndarray:
        return nums[:, j]

    # a table of the tiles of a row unpacked (an edit's): their tree, and the box columns
    # it leaves as they were, from that row (the same bytes: functions of those)
    p = table.packed
    if p is not None and not np.array_equal(p.tree.keys, table.tiles):
        p = None
    tree, boxes, holes = table_layout(table.tiles, column, None if p is None else p.tree)

    def known(j: int, col: np.ndarray) -> bytes | None:
        if p is None or not boxes or j not in p.boxes:
            return None
        old = p.numbers[:, j]
        return p.boxes[j] if np.array_equal(old.view(np.int64), col.view(np.int64)) else None

    return pack_stream(len(table.tiles), len(table.blobs), width, boxes, holes,
                       lambda: table_columns(tree, column, [table.blobs], [ids], width,
                                             boxes, known), fast)


def unpack_tiles(data: bytes, file_bytes: int | None = None) -> TileTable:
    """The :class:`TileTable` of its catalog row; ValueError for anything malformed
    (sizes, keys not strictly ascending or out of range, fewer than 4 blobs a tile, more
    blobs than a file of ``file_bytes`` can hold, a zstd frame past :data:`RATIO_CAP`,
    an unknown id width or box coding, holes that are not the level-0 grid's), before
    decoding what the head claims."""
    if len(data) < _HEAD.size:
        raise ValueError("too short")
    fmt, n, m, width, boxes, holes = _HEAD.unpack_from(data)
    if len(BLOB_KINDS) * n > m or (file_bytes is not None and MIN_BLOB_ROW_BYTES * m > file_bytes):
        raise ValueError(f"{n} tiles and {m} blobs cannot be a store of this size")
    if width not in (2, 4, 8) or boxes not in (0, 1) or (holes and not boxes):
        raise ValueError("of an unknown layout")
    if holes > _HOLES[0] * n + _HOLES[1]:
        raise ValueError("claims a level-0 grid larger than its tiles allow")
    body = memoryview(data)[_HEAD.size:]
    size = _table_size(n, m, width, holes)
    if fmt == 1:
        if size > RATIO_CAP * len(body) + _RATIO_SLACK:
            raise ValueError("claims too many rows for its size")
        body = memoryview(zstdsafe.decompress(body, size, exact=True))
    elif fmt != 0 or len(body) != size:
        raise ValueError("of an unknown format or size")
    tiles = _ascending(body[:8 * n], n)
    tree = _Tree(tiles)
    if boxes and (not tree.grid_fits() or holes != tree.area - len(tree.zero)):
        raise ValueError("its level-0 grid does not match its tiles")
    off = 8 * n
    numbers = np.empty((n, len(TILE_COLUMNS)), np.float64)
    box_bytes = {}
    for j, name in enumerate(TILE_COLUMNS):
        k = _column_size(name, n, holes)
        numbers[:, j] = _column(tree, name, body[off:off + k], boxes, holes)
        if boxes and name in _BOXES:
            box_bytes[j] = bytes(body[off:off + k])
        off += k
    blobs = _ascending(body[off:off + 8 * m], m)
    off += 8 * m
    ids = _unshuffled(body[off:], m, f"<i{width}" if width == 8 else f"<u{width}")
    return TileTable(tiles, numbers, blobs, ids.astype(np.int64),
                     Packed(tree, numbers, box_bytes))


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

"""A store's rows by tile key, through SQL: for tests that damage, edit or compare stores.

Schema 4 keeps blob rows bare and finds them through the tile table, a compressed row
of ``catalog`` (geoterrain/store/catalog.py); these helpers address them by
``(level, x, y, kind)`` as the tests think of them. Edits of the catalog rewrite its
rows with valid checksums (a stranger's file may be consistent and still wrong).
"""

from __future__ import annotations

import numpy as np

from geoterrain.store.catalog import (
    META_ID,
    TILE_COLUMNS,
    TILES_ID,
    TileTable,
    catalog_crc,
    pack_metadata,
    pack_tiles,
    unpack_metadata,
    unpack_tiles,
)
from geoterrain.store.keys import blob_key, tile_key, unpack_blob_key, unpack_tile_key


def _row(con, row_id: int) -> bytes:
    return con.execute("SELECT data FROM catalog WHERE id = ?", (row_id,)).fetchone()[0]


def _put_row(con, row_id: int, data: bytes) -> None:
    con.execute("UPDATE catalog SET data = ?, crc32 = ? WHERE id = ?",
                (data, catalog_crc(row_id, data), row_id))


def read_table(con) -> TileTable:
    """The tile table as stored."""
    return unpack_tiles(_row(con, TILES_ID))


def write_table(con, t: TileTable) -> None:
    """Replace the tile table (valid checksum)."""
    _put_row(con, TILES_ID, pack_tiles(t))


def read_meta(con) -> dict:
    """The metadata as stored."""
    return unpack_metadata(_row(con, META_ID))


def write_meta(con, meta: dict) -> None:
    """Replace the metadata (valid checksum)."""
    _put_row(con, META_ID, pack_metadata(meta))


def blob_id(con, k: tuple) -> int | None:
    """The rowid of blob ``k`` = (level, x, y, kind), or None."""
    t = read_table(con)
    hit = np.flatnonzero(t.blobs == blob_key(k[:3], k[3]))
    return int(t.ids[hit[0]]) if len(hit) else None


def blob_keys(con, kind: str | None = None) -> list[tuple[int, int, int, str]]:
    """Every blob's (level, x, y, kind), in key order (only ``kind``'s if given)."""
    out = []
    for k in read_table(con).blobs.tolist():
        key, knd = unpack_blob_key(k)
        if kind is None or knd == kind:
            out.append((*key, knd))
    return out


def read_blob(con, k: tuple, cols: str = "data") -> tuple:
    """Columns ``cols`` of blob ``k`` = (level, x, y, kind)."""
    return con.execute(f"SELECT {cols} FROM blobs WHERE rowid = ?", (blob_id(con, k),)).fetchone()


def update_blob(con, k: tuple, **cols) -> None:
    """Set columns of blob ``k`` (``data=...``, ``crc32=...``)."""
    sets = ", ".join(f"{c}=?" for c in cols)
    con.execute(f"UPDATE blobs SET {sets} WHERE rowid = ?", (*cols.values(), blob_id(con, k)))


def _drop_key(con, k: tuple) -> None:
    t = read_table(con)
    keep = t.blobs != blob_key(k[:3], k[3])
    write_table(con, TileTable(t.tiles, t.numbers, t.blobs[keep], t.ids[keep]))


def delete_blob(con, k: tuple, row: bool = True, key: bool = False) -> None:
    """Delete blob ``k``'s row (``row``) and/or its entry in the tile table (``key``)."""
    if row:
        con.execute("DELETE FROM blobs WHERE rowid = ?", (blob_id(con, k),))
    if key:
        _drop_key(con, k)


def remove_blob(con, k: tuple) -> None:
    """Remove blob ``k`` as if it had never been written: its row and key go, and the
    last row takes its rowid (a store's rows fill their rowid range)."""
    gap = blob_id(con, k)
    delete_blob(con, k, key=True)
    (top,) = con.execute("SELECT MAX(rowid) FROM blobs").fetchone()
    if top is not None and top > gap:
        con.execute("UPDATE blobs SET rowid = ? WHERE rowid = ?", (gap, top))
        t = read_table(con)
        write_table(con, TileTable(t.tiles, t.numbers, t.blobs,
                                   np.where(t.ids == top, gap, t.ids)))


def all_blobs(con) -> dict[tuple[int, int, int, str], bytes]:
    """Every blob's bytes by (level, x, y, kind)."""
    t = read_table(con)
    data = dict(con.execute("SELECT rowid, data FROM blobs"))
    pairs = zip(t.blobs.tolist(), t.ids.tolist(), strict=True)
    return {(*key, kind): bytes(data[i]) for key, kind, i in
            ((*unpack_blob_key(k), i) for k, i in pairs)}


def all_tiles(con) -> dict[tuple[int, int, int], tuple]:
    """Every tile's numbers (in the order of TILE_COLUMNS, None where absent, so that
    tuples compare) by (level, x, y)."""
    t = read_table(con)
    return {unpack_tile_key(k): tuple(None if v != v else v for v in r)
            for k, r in zip(t.tiles.tolist(), t.numbers.tolist(), strict=True)}


def tile_row(con, key: tuple) -> tuple:
    """The numbers of tile (level, x, y), in the order of TILE_COLUMNS."""
    return all_tiles(con)[tuple(key)]


def put_tile(con, key: tuple, numbers: tuple) -> None:
    """Add (or replace) tile (level, x, y) with ``numbers`` (valid checksum)."""
    t = read_table(con)
    k = tile_key(key)
    keep = t.tiles != k
    tiles = np.append(t.tiles[keep], k)
    row = np.array([np.nan if v is None else v for v in numbers], np.float64)
    nums = np.vstack([t.numbers[keep], row.reshape(1, len(TILE_COLUMNS))])
    order = np.argsort(tiles)
    write_table(con, TileTable(tiles[order], nums[order], t.blobs, t.ids))


def delete_tile(con, key: tuple) -> None:
    """Remove tile (level, x, y) from the tile table (its blobs stay; valid checksum)."""
    t = read_table(con)
    keep = t.tiles != tile_key(key)
    write_table(con, TileTable(t.tiles[keep], t.numbers[keep], t.blobs, t.ids))

"""A store's rows by tile key, through SQL: for tests that damage, edit or compare stores.

Schema 3 keeps blob rows bare and finds them through ``blob_keys`` (geoterrain/store.py);
these helpers address them by ``(level, x, y, kind)`` as the tests think of them.
"""

from __future__ import annotations

from geoterrain.store import blob_key, tile_key, unpack_blob_key, unpack_tile_key

BLOB = "rowid = (SELECT blob FROM blob_keys WHERE key = ?)"  # one blob row, by its key


def blob_keys(con, kind: str | None = None) -> list[tuple[int, int, int, str]]:
    """Every blob's (level, x, y, kind), in key order (only ``kind``'s if given)."""
    out = []
    for (k,) in con.execute("SELECT key FROM blob_keys ORDER BY key"):
        key, knd = unpack_blob_key(k)
        if kind is None or knd == kind:
            out.append((*key, knd))
    return out


def read_blob(con, k: tuple, cols: str = "data") -> tuple:
    """Columns ``cols`` of blob ``k`` = (level, x, y, kind)."""
    return con.execute(f"SELECT {cols} FROM blobs WHERE {BLOB}",
                       (blob_key(k[:3], k[3]),)).fetchone()


def update_blob(con, k: tuple, **cols) -> None:
    """Set columns of blob ``k`` (``data=...``, ``crc32=...``)."""
    sets = ", ".join(f"{c}=?" for c in cols)
    con.execute(f"UPDATE blobs SET {sets} WHERE {BLOB}", (*cols.values(), blob_key(k[:3], k[3])))


def delete_blob(con, k: tuple, row: bool = True, key: bool = False) -> None:
    """Delete blob ``k``'s row (``row``) and/or its entry in blob_keys (``key``)."""
    bk = blob_key(k[:3], k[3])
    if row:
        con.execute(f"DELETE FROM blobs WHERE {BLOB}", (bk,))
    if key:
        con.execute("DELETE FROM blob_keys WHERE key = ?", (bk,))


def remove_blob(con, k: tuple) -> None:
    """Remove blob ``k`` as if it had never been written: its row and key go, and the
    last row takes its rowid (a store's rows fill their rowid range)."""
    bk = blob_key(k[:3], k[3])
    (gap,) = con.execute("SELECT blob FROM blob_keys WHERE key = ?", (bk,)).fetchone()
    delete_blob(con, k, key=True)
    (top,) = con.execute("SELECT MAX(rowid) FROM blobs").fetchone()
    if top is not None and top > gap:
        con.execute("UPDATE blobs SET rowid = ? WHERE rowid = ?", (gap, top))
        con.execute("UPDATE blob_keys SET blob = ? WHERE blob = ?", (gap, top))


def all_blobs(con) -> dict[tuple[int, int, int, str], bytes]:
    """Every blob's bytes by (level, x, y, kind)."""
    rows = con.execute("SELECT k.key, b.data FROM blob_keys k JOIN blobs b ON b.rowid = k.blob")
    return {(*key, kind): bytes(d) for key, kind, d in
            ((*unpack_blob_key(k), d) for k, d in rows)}


def all_tiles(con) -> dict[tuple[int, int, int], tuple]:
    """Every tile row's numbers and checksum by (level, x, y)."""
    return {unpack_tile_key(r[0]): tuple(r[1:]) for r in con.execute("SELECT * FROM tiles")}


def tile_row(con, key: tuple) -> tuple:
    """The tile row of (level, x, y), its packed key first."""
    return con.execute("SELECT * FROM tiles WHERE key = ?", (tile_key(key),)).fetchone()


def delete_tile(con, key: tuple) -> None:
    con.execute("DELETE FROM tiles WHERE key = ?", (tile_key(key),))

"""A store changed in place, all or nothing: one SQLite transaction (issue 52).

An edit (:mod:`geoterrain.preprocessing.edit`) rewrites a few of a store's rows: the
blobs it changes, the tile table and the metadata. Writing a whole new store beside the
old one and publishing it (:class:`geoterrain.store.writer.StoreWriter`) would rewrite
every byte; here only the rows that change are written, in one transaction of SQLite's
rollback journal (``STORE-journal``, the old pages, synced before a page of the store
changes). A process killed at any point leaves either the old store with a hot journal,
which SQLite rolls back when the store is next opened (:class:`StoreReader` does so),
or the new one.

Blob row ids stay what the tile table says: a rewritten blob keeps its row, a new blob
takes a freed row or the next id, and a removed blob's row is refilled from the end of
the table, so the ids still fill one range (the reader checks that).
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import numpy as np

from geoterrain.exceptions import StoreError, WriteError
from geoterrain.store.catalog import (
    META_ID,
    TILE_COLUMNS,
    TILES_ID,
    TileTable,
    catalog_crc,
    pack_metadata,
    pack_tiles,
    unpack_metadata,
)
from geoterrain.store.keys import blob_key, tile_key, unpack_blob_key
from geoterrain.store.reader import StoreReader
from geoterrain.store.schema import TABLE_SQL, blob_crc, schema_version

__all__ = ["StoreEditor", "BUSY_SECONDS"]

BUSY_SECONDS = 30.0  # how long an edit waits for readers to finish a read, or another edit

BlobKey = tuple[tuple[int, int, int], str]  # ((level, x, y), kind)


class StoreEditor:
    """One all-or-nothing change of a store's rows.

    ``expect`` is the metadata the change was planned against: if another edit committed
    since, nothing is written and :class:`StoreError` says to retry.
    ``known``: a reader of the store whose tile table is parsed (the edit's terrain's),
    taken instead of unpacking the row again where the row is the one it parsed.

    Examples
    --------
    >>> import tempfile, os, numpy as np
    >>> from geoterrain.store.writer import StoreWriter
    >>> p = os.path.join(tempfile.mkdtemp(), "s.geoterrain")
    >>> with StoreWriter(p) as w:
    ...     w.put_blobs("heights", {(0, 0, 0): b"old"})
    ...     for kind in ("delta", "radius", "normals"):
    ...         w.put_blob((0, 0, 0), kind, b"-")
    ...     w.put_tiles({(0, 0, 0): (1,) + (0.0,) * 10})
    ...     w.put_metadata({"note": "a"})
    ...     _ = w.commit()
    >>> with StoreEditor(p) as e:
    ...     e.apply({((0, 0, 0), "heights"): b"new"}, set(), None, {"note": "b"})["rows"]
    3
    >>> r = StoreReader(p); r.get_blob((0, 0, 0), "heights"), r.metadata["note"]
    (b'new', 'b')
    """

    def __init__(self, path: str | Path, expect: dict | None = None,
                 known: StoreReader | None = None):
        self.path = Path(path)
        # ``known`` opened this store and checked it (schema, catalog, metadata), and
        # ``expect`` is the metadata it read: where nothing lies beside the store (no
        # journal to roll back, no -wal), the schema is checked again inside the
        # transaction and the metadata compared with ``expect`` there, instead of
        # opening a reader of its own (1 ms)
        vetted = known is not None and expect is not None and \
            Path(known.path) == self.path and not _beside(self.path)
        if not vetted:
            reader = StoreReader(self.path)  # rolls back an interrupted edit, checks the file
            reader.close()
        try:
            self.con = sqlite3.connect(self.path, isolation_level=None, timeout=BUSY_SECONDS)
        except sqlite3.Error as exc:
            raise WriteError(f"cannot edit {self.path}: {exc}") from None
        self._done = False
        try:
            self.con.execute("PRAGMA trusted_schema=OFF")
            # the store was written without a journal; an edit keeps the old pages in one
            # (the default DELETE mode: the file's format does not change), synced first
            self.con.execute("PRAGMA journal_mode=DELETE")
            self.con.execute("PRAGMA synchronous=FULL")
            self.con.execute("BEGIN IMMEDIATE")  # one editor at a time
        except sqlite3.OperationalError as exc:
            self.con.close()
            if "locked" in str(exc) or "busy" in str(exc):
                raise StoreError(f"{self.path} is being edited by another process; retry "
                                 "when it is done") from None
            if "readonly" in str(exc) or "read-only" in str(exc):
                raise WriteError(f"cannot edit {self.path}: read-only; copy it somewhere "
                                 "writable") from None
            raise WriteError(f"cannot edit {self.path}: {exc}") from None
        if vetted:
            self._check_schema()
        # the catalog as it is now, inside the transaction: no other edit can commit
        rows = {i: (d, c) for i, d, c in self.con.execute("SELECT id, data, crc32 FROM catalog")}
        try:  # (damaged since ``known`` read it: not ``expect``, and a rerun's reader says so)
            self.metadata = unpack_metadata(rows[META_ID][0])
        except (ValueError, KeyError):
            self.metadata = None
        if expect is not None and (self.metadata != expect or TILES_ID not in rows):
            self.abort()
            raise StoreError(f"{self.path} was changed by another edit while this one was "
                             "planned; run it again")
        from geoterrain.store.catalog import unpack_tiles

        data, crc = rows[TILES_ID]
        # ``known``: a reader of this store whose tile table is parsed already (the
        # edit's terrain's); its table is taken where the row is the one it parsed (the
        # same checksum and size), not unpacked again (2-3 ms on a 4097² store)
        stamp = getattr(known, "table_stamp", None)
        if stamp is not None and stamp == (crc, len(data)):
            self.table: TileTable = known.table()
        else:
            self.table = unpack_tiles(data)

    def _check_schema(self) -> None:
        """Exactly the two plain tables, as the writer declares them (StoreReader's check,
        inside the transaction: the file cannot change under it)."""
        try:
            seen = self.con.execute("SELECT type, name, sql FROM sqlite_master").fetchall()
        except (sqlite3.Error, UnicodeDecodeError):
            seen = None
        if seen is None or sorted(seen) != sorted(("table", n, sql)
                                                  for n, sql in TABLE_SQL.items()):
            self.abort()
            raise StoreError(f"{self.path}: not a geoterrain store (its schema changed "
                             "since it was opened); refusing to edit it")

    def apply(self, puts: dict[BlobKey, bytes], deletes: set[BlobKey],
              tiles: dict[tuple[int, int, int], tuple] | None, metadata: dict,
              all_tiles: bool = True) -> dict:
        """Write the blobs ``puts`` (new or rewritten), remove ``deletes``, replace the
        tile rows (``tiles``: every tile's numbers in :data:`TILE_COLUMNS` order, or with
        ``all_tiles`` False those that change or are new; None keeps them) and the
        metadata, and commit. Returns what was written: ``{"rows": rows written,
        "blob_bytes": their bytes, "catalog_bytes": the catalog's}``."""
        if tiles is not None and not all_tiles:
            tiles = self._merged(tiles)
        try:
            return self._apply(puts, deletes, tiles, metadata)
        except sqlite3.Error as exc:
            self.abort()
            msg = str(exc)
            if "full" in msg:
                raise WriteError(f"disk full while editing {self.path}; nothing was "
                                 "changed; free space and retry") from None
            raise WriteError(f"cannot edit {self.path}: {msg}; nothing was changed") from None

    def _merged(self, rows: dict) -> tuple[np.ndarray, np.ndarray]:
        """The tile table's keys and numbers (key order) with ``rows`` replacing or adding
        theirs."""
        t = self.table
        keys = np.array([tile_key(k) for k in rows], np.int64)
        vals = _numbers([rows[k] for k in rows])
        at = np.searchsorted(t.tiles, keys)
        if len(t.tiles) and (at < len(t.tiles)).all() and (t.tiles[np.minimum(
                at, len(t.tiles) - 1)] == keys).all():
            # every row replaces a stored one (a local edit's): the same keys, the
            # table's own array (pack_tiles then takes what the row it came from knows)
            nums = np.array(t.numbers, np.float64).reshape(len(t.tiles), len(TILE_COLUMNS))
            nums[at] = vals  # (each key once: ``rows`` is a dict)
            return t.tiles, nums
        allk = np.concatenate([np.asarray(t.tiles, np.int64), keys])
        allv = np.concatenate([np.asarray(t.numbers, np.float64).reshape(-1, len(TILE_COLUMNS)),
                               vals])
        # each key's last row: the new one where there is one
        uniq, first = np.unique(allk[::-1], return_index=True)
        return uniq, allv[len(allk) - 1 - first]

    def _apply(self, puts, deletes, tiles, metadata) -> dict:
        t = self.table
        if not deletes and puts:  # blobs rewritten in place only: the blob keys stay
            rewrite = _rewrites(t, puts)
            if rewrite is not None:
                # the statements in the key order the general path takes (the order
                # frees and takes overflow pages: the file's bytes depend on it)
                self.con.executemany("UPDATE blobs SET data = ?, crc32 = ? WHERE id = ?",
                                     rewrite)
                nbytes = sum(len(r[0]) for r in rewrite)
                return self._commit(t.blobs, t.ids, len(rewrite), nbytes, tiles, metadata)
        ids = dict(zip(t.blobs.tolist(), t.ids.tolist(), strict=True))
        new_keys = {blob_key(k, kind): (k, kind) for k, kind in puts}
        gone = sorted(ids.pop(blob_key(k, kind)) for k, kind in deletes
                      if blob_key(k, kind) in ids)
        written = 0
        nbytes = 0
        free = list(gone)  # rows freed by removed blobs, filled first
        for bk, (k, kind) in sorted(new_keys.items()):
            data = puts[(k, kind)]
            crc = blob_crc(k, kind, data)
            if bk in ids:
                self.con.execute("UPDATE blobs SET data = ?, crc32 = ? WHERE id = ?",
                                 (data, crc, ids[bk]))
            else:
                if free:
                    rid = free.pop(0)
                    self.con.execute("DELETE FROM blobs WHERE id = ?", (rid,))
                else:
                    rid = max(ids.values(), default=0) + 1
                self.con.execute("INSERT INTO blobs VALUES (?, ?, ?)", (rid, data, crc))
                ids[bk] = rid
            written += 1
            nbytes += len(data)
        # rows still free: delete them, and move the last rows into the holes so the ids
        # fill one range
        for rid in free:
            self.con.execute("DELETE FROM blobs WHERE id = ?", (rid,))
        by_id = {v: k for k, v in ids.items()}
        for rid in sorted(free):
            last = max(by_id)
            if last < rid:
                continue
            self.con.execute("UPDATE blobs SET id = ? WHERE id = ?", (rid, last))
            bk = by_id.pop(last)
            by_id[rid] = bk
            ids[bk] = rid
            written += 1
        keys = np.array(sorted(ids), np.int64)
        return self._commit(keys, np.array([ids[k] for k in keys.tolist()], np.int64),
                            written, nbytes, tiles, metadata)

    def _commit(self, keys: np.ndarray, rowids: np.ndarray, written: int, nbytes: int,
                tiles, metadata: dict) -> dict:
        """The catalog's rows (the tile table with blob keys ``keys`` at rows ``rowids``,
        the metadata) written, and the transaction committed."""
        t = self.table
        if tiles is None:
            tk, nums = t.tiles, t.numbers
        elif isinstance(tiles, tuple):  # merged already (_merged)
            tk, nums = tiles
        else:
            order = sorted(tiles, key=tile_key)
            tk = np.array([tile_key(k) for k in order], np.int64)
            nums = _numbers([tiles[k] for k in order])
        table = TileTable(tk, nums, keys, rowids, t.packed if tk is t.tiles else None)
        meta = dict(metadata)
        levels = np.bincount(tk & 31, minlength=32) if len(tk) else np.zeros(32, np.int64)
        meta["tile_counts"] = {str(L): int(c) for L, c in enumerate(levels) if c}
        meta["schema_version"] = schema_version(meta.get("grid", {}), meta.get("frame"))
        meta["complete"] = True
        # the tile table at zstd's fast level: its strongest one took most of a small
        # edit's time (catalog.pack_tiles)
        rows = {TILES_ID: pack_tiles(table, fast=True), META_ID: pack_metadata(meta)}
        for i, d in rows.items():
            self.con.execute("UPDATE catalog SET data = ?, crc32 = ? WHERE id = ?",
                             (d, catalog_crc(i, d), i))
        self.con.execute("COMMIT")  # the journal is synced, then the store, then deleted
        self._done = True
        self.con.close()
        return {"rows": written + len(rows), "blob_bytes": nbytes,
                "catalog_bytes": sum(map(len, rows.values()))}

    def abort(self) -> None:
        """Roll back: the store is left as it was."""
        if self._done:
            return
        self._done = True
        try:
            self.con.execute("ROLLBACK")
        except sqlite3.Error:
            pass
        self.con.close()

    def __enter__(self) -> StoreEditor:
        return self

    def __exit__(self, *exc) -> None:
        self.abort()


def _beside(path: Path) -> bool:
    """Whether SQLite's journal or write-ahead log lies beside the store (an edit killed
    or running, or a stranger's file): a reader of its own then rolls back or refuses it,
    as on any open."""
    return any(os.path.lexists(f"{path}{side}") for side in ("-journal", "-wal"))


def _rewrites(table: TileTable, puts: dict) -> list | None:
    """``(data, crc32, row id)`` of each put in blob key order, where every put's blob is
    stored already (None where one is new)."""
    order = sorted((blob_key(k, kind), k, kind) for k, kind in puts)
    bk = np.array([o[0] for o in order], np.int64)
    at = np.searchsorted(table.blobs, bk)
    if (at >= len(table.blobs)).any() or (table.blobs[np.minimum(at, len(table.blobs) - 1)]
                                           != bk).any():
        return None
    rowids = table.ids[at].tolist()
    out = []
    for (_, k, kind), rid in zip(order, rowids, strict=True):
        data = puts[(k, kind)]
        out.append((data, blob_crc(k, kind, data), rid))
    return out


def _numbers(rows: list) -> np.ndarray:
    """Tile rows (None: NaN) as a (n, columns) float64 array."""
    return np.array([[np.nan if v is None else float(v) for v in r] for r in rows],
                    np.float64).reshape(len(rows), len(TILE_COLUMNS))


def blob_kinds_of(table: TileTable) -> set[BlobKey]:
    """Every blob's ((level, x, y), kind) of a tile table."""
    return {unpack_blob_key(int(k)) for k in table.blobs}


def journal_of(path: str | Path) -> Path:
    """The rollback journal SQLite keeps beside a store during an edit."""
    return Path(os.fspath(path) + "-journal")

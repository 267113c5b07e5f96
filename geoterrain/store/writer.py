"""The store's writer: :class:`StoreWriter`, and :class:`StoreThread` (the same on a
thread of its own).

A store is written to a hidden temporary file in the destination folder and
published only after the metadata (with its ``complete`` flag) is committed, so an
interrupted write never leaves a file that opens as a valid store. Without
``overwrite`` the publish is a create-if-absent (a hard link), so of two racing
writers exactly one wins. The blob rows are inserted in the order that fills SQLite's
leaf pages (:mod:`geoterrain.store.pagepack`); the tables and rules written are
:mod:`geoterrain.store.schema`'s.
"""

from __future__ import annotations

import json
import os
import sqlite3
import threading
import weakref
from pathlib import Path

import numpy as np

from geoterrain.core.atomicfiles import publish, remove_stale_partials
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.store.catalog import (
    META_ID,
    TILE_COLUMNS,
    TILES_ID,
    catalog_crc,
    pack_metadata,
    pack_stream,
    table_columns,
    table_layout,
)
from geoterrain.store.keys import pack_blob_key, pack_tile_key
from geoterrain.store.pagepack import LEAF_HEADER, blob_cell_sizes, pack_order
from geoterrain.store.schema import (
    APPLICATION_ID,
    PAGE_SIZE,
    SMALL_PAGE_SIZE,
    TABLE_SQL,
    blob_crc,
    schema_version,
)

PACK_BYTES = 4 << 20  # blob bytes a writer holds before inserting them, packed (pagepack)
_SCHEMA = "".join(f"{sql};\n" for sql in TABLE_SQL.values())
# the writer's staging of the tile table (an attached file beside the partial store,
# never the store's own file)
_STAGING = ("CREATE TABLE staging.staged_tiles (key INTEGER PRIMARY KEY, "
            + ", ".join(f"n{j} REAL" for j in range(len(TILE_COLUMNS))) + ");\n"
            "CREATE TABLE staging.staged_blobs (key INTEGER PRIMARY KEY, "
            "blob INTEGER NOT NULL);\n")


def _unlink_all(paths: tuple[Path, ...]) -> None:
    """Remove ``paths`` that exist (a writer's partial store and staging file)."""
    for f in paths:
        try:
            f.unlink()
        except OSError:
            pass



class StoreWriter:
    """Write a store atomically: use as a context manager, then :meth:`commit`.

    Examples
    --------
    >>> import tempfile, os
    >>> dst = os.path.join(tempfile.mkdtemp(), "a.geoterrain")
    >>> with StoreWriter(dst) as w:
    ...     w.put_metadata({"note": "hi"})
    ...     w.put_blob((0, 0, 0), "heights", b"x")
    ...     _ = w.commit()
    >>> from geoterrain.store.reader import StoreReader
    >>> StoreReader(dst).metadata["note"]
    'hi'
    """

    def __init__(self, dst: str | Path, overwrite: bool = False, page_size: int = PAGE_SIZE):
        # a regular file or nothing, replaced only with overwrite (core/paths.py)
        self.dst = check_output(dst, overwrite)
        if page_size not in (SMALL_PAGE_SIZE, PAGE_SIZE):
            raise ValueError(f"a store's pages are {SMALL_PAGE_SIZE} or {PAGE_SIZE} bytes")
        self.page_size = page_size
        parent = self.dst.parent if str(self.dst.parent) else Path(".")
        remove_stale_partials(parent)
        self.tmp = parent / f".{self.dst.name}.partial-{os.getpid()}"
        # the tile table's staging file, in the same folder: a full disk is the store's
        # disk, and a killed writer's file is a partial that the next run removes (the
        # suffix after the pid: no other output's partial can have this name)
        self.staging = self.tmp.with_name(self.tmp.name + ".staging")
        # a writer dropped without commit or abort leaves neither file behind
        self._cleanup = weakref.finalize(self, _unlink_all, (self.tmp, self.staging))
        self.overwrite = overwrite
        self._meta: dict = {}
        self._rows: list[tuple] = []  # blob rows not yet inserted (see _flush)
        self._row_bytes = 0
        self._rowid = 0  # rows inserted so far: the next one's rowid is this + 1
        self._committed = False
        try:
            for f in (self.tmp, self.staging):
                if f.exists():
                    f.unlink()
            self.con = sqlite3.connect(self.tmp, isolation_level=None)
        except (OSError, sqlite3.Error) as exc:
            raise WriteError(
                f"cannot write in {parent}: {exc}; choose a writable -o path") from None
        self._guard(self._init)

    def _init(self) -> None:
        # The temporary file is not the store; durability comes from fsync + rename.
        # Small pages: a tile blob of a few kB overflows into whole pages, and 4 kB pages
        # left ~30 % of a store as slack (docs/lab/store-size.md); readers take any size.
        self.con.execute(f"PRAGMA page_size={self.page_size}")
        self.con.execute("PRAGMA journal_mode=OFF")
        self.con.execute("PRAGMA synchronous=OFF")
        self.con.execute(f"PRAGMA application_id={APPLICATION_ID}")
        self.con.executescript(_SCHEMA)
        # the tile table is staged in a database file of its own beside the partial
        # store (deleted at commit or abort; its pages cached in at most 2 MB), so a
        # large pyramid's table costs the writer no memory until commit, and then a
        # column at a time (pack_tiles). SQLite's temporary files would put it on
        # another disk (or in RAM on a tmpfs), and a full disk there would be reported
        # as this store's.
        self.con.execute("ATTACH DATABASE ? AS staging", (str(self.staging),))
        self.con.execute("PRAGMA staging.journal_mode=OFF")
        self.con.execute("PRAGMA staging.synchronous=OFF")
        self.con.execute("PRAGMA staging.cache_size=-2000")
        self.con.executescript(_STAGING)
        self.con.execute("BEGIN")

    def _guard(self, fn, *args):
        try:
            return fn(*args)
        except UsageError:
            self.abort()
            raise
        except (OSError, sqlite3.Error) as exc:
            self.abort()
            msg = str(exc)
            if "full" in msg or getattr(exc, "errno", None) == 28:
                raise WriteError(
                    f"disk full while writing {self.dst}; free space and retry") from None
            if "readonly" in msg or "read-only" in msg or "permission" in msg.lower():
                raise WriteError(
                    f"cannot write {self.dst}: read-only location; choose another -o path"
                ) from None
            raise WriteError(f"cannot write {self.dst}: {msg}") from None

    def put_metadata(self, items: dict) -> None:
        """Add metadata entries (JSON values)."""
        for k, v in items.items():
            self._meta[k] = json.loads(json.dumps(v))  # a copy, and JSON now or never

    def put_blob(self, key: tuple[int, int, int], kind: str, data: bytes) -> None:
        self.put_blobs(kind, {key: data})

    def put_blobs(self, kind: str, blobs: dict[tuple[int, int, int], bytes]) -> None:
        """Add blobs of one kind. They are inserted in batches of about
        :data:`PACK_BYTES`, each in the order that fills SQLite's leaf pages
        (:mod:`geoterrain.store.pagepack`), so a store's bytes depend on the sequence of rows
        given, not on how it is split into calls."""
        for k, d in blobs.items():
            self._rows.append((pack_blob_key(k, kind), d, blob_crc(k, kind, d)))
            self._row_bytes += len(d)
            if self._row_bytes >= PACK_BYTES:
                self._guard(self._flush)

    def _flush(self) -> None:
        """Insert the buffered blob rows, packed into leaf pages (pagepack.pack_order),
        and keep their keys and rowids for the catalog."""
        rows, self._rows, self._row_bytes = self._rows, [], 0
        if not rows:
            return
        last = self._rowid + len(rows)  # cells are sized with the batch's largest rowid
        sizes = blob_cell_sizes([len(r[1]) for r in rows], [r[2] for r in rows], last,
                                self.page_size).tolist()
        order = pack_order(sizes, self.page_size - LEAF_HEADER)
        self.con.executemany("INSERT INTO blobs VALUES (NULL,?,?)",
                             (rows[i][1:] for i in order))
        self.con.executemany("INSERT INTO staging.staged_blobs VALUES (?,?)", (
            (rows[i][0], rowid) for rowid, i in enumerate(order, self._rowid + 1)))
        self._rowid = last

    def put_tiles(self, rows: dict[tuple[int, int, int], tuple]) -> None:
        """Per-tile numbers, in the order of :data:`TILE_COLUMNS` (``nvalid`` a count)."""
        for r in rows.values():
            if len(r) != len(TILE_COLUMNS) or not (isinstance(r[0], int | np.integer)
                                                   and r[0] >= 0):
                raise ValueError(f"a tile row holds {len(TILE_COLUMNS)} numbers, the "
                                 "first a count of valid samples")
        marks = ", ".join("?" * (1 + len(TILE_COLUMNS)))
        self._guard(self.con.executemany,
                    f"INSERT INTO staging.staged_tiles VALUES ({marks})",
                    ((pack_tile_key(k), int(r[0]), *r[1:]) for k, r in rows.items()))

    def _staged(self, sql: str, dtype=np.int64):
        # one column of a staging table, in key order, in chunks (SQL NULL as NaN:
        # SQLite stores no NaN)
        cur = self.con.execute(sql)
        while chunk := cur.fetchmany(1 << 16):
            yield np.fromiter((np.nan if v is None else v for (v,) in chunk), dtype,
                              len(chunk))

    def _tile_table(self) -> bytes:
        """The tile table's catalog row, streamed from the staging tables a column at a
        time, and the metadata's tile counts."""
        counts = self.con.execute("SELECT key & 31, COUNT(*) FROM staging.staged_tiles "
                                  "GROUP BY 1 ORDER BY 1").fetchall()
        self._meta["tile_counts"] = {str(L): c for L, c in counts}
        (m,) = self.con.execute("SELECT COUNT(*) FROM staging.staged_blobs").fetchone()

        def column(name: str) -> np.ndarray:
            return np.concatenate([*self._staged(f"SELECT {name} FROM "
                                                 "staging.staged_tiles ORDER BY key",
                                                 np.float64), np.zeros(0)])

        width = 2 if self._rowid < 1 << 16 else 4 if self._rowid < 1 << 32 else 8
        keys = np.concatenate([*self._staged("SELECT key FROM staging.staged_tiles "
                                             "ORDER BY key"), np.zeros(0, np.int64)])
        tree, boxes, holes = table_layout(keys, lambda j: column(f"n{j}"))
        return pack_stream(len(keys), m, width, boxes, holes, lambda: table_columns(
            tree, lambda j: column(f"n{j}"),
            self._staged("SELECT key FROM staging.staged_blobs ORDER BY key"),
            self._staged("SELECT blob FROM staging.staged_blobs ORDER BY key"), width, boxes))

    def commit(self) -> Path:
        """Finish: write the catalog, the metadata with its complete flag, fsync,
        rename into place."""

        def _finish():
            self._flush()
            rows = {TILES_ID: self._tile_table()}
            self._meta["schema_version"] = schema_version(self._meta.get("grid", {}),
                                                          self._meta.get("frame"))
            self._meta["complete"] = True
            rows[META_ID] = pack_metadata(self._meta)
            self.con.executemany("INSERT INTO catalog VALUES (?,?,?)",
                                 ((i, d, catalog_crc(i, d)) for i, d in sorted(rows.items())))
            self.con.execute("COMMIT")
            self.con.close()
            self.staging.unlink(missing_ok=True)
            fd = os.open(self.tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            publish(self.tmp, self.dst, self.overwrite)
            dfd = os.open(self.dst.parent if str(self.dst.parent) else ".", os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)

        self._guard(_finish)
        self._committed = True
        self._cleanup.detach()  # published: nothing of this writer's is left to remove
        return self.dst

    def abort(self) -> None:
        """Drop the temporary file; the destination is untouched."""
        try:
            self.con.close()
        except Exception:  # noqa: BLE001 - closing a broken connection
            pass
        self._cleanup()  # both files, once

    def __enter__(self) -> StoreWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if not self._committed:
            self.abort()


class StoreThread:
    """A :class:`StoreWriter` on a thread of its own: its calls (``put_blobs``,
    ``put_tiles``, ``put_metadata``) run there in the order given, while the caller
    goes on (the rows of blobs already made are inserted while the next are coded);
    :meth:`commit` waits for them and publishes the store, the same bytes as the same
    calls on a :class:`StoreWriter`. After a failed call none runs (so no commit follows
    a failure); :meth:`commit` raises its error. :meth:`abort` (or leaving the ``with``
    block without a commit) drops the partial file.

    Examples
    --------
    >>> import tempfile, os
    >>> dst = os.path.join(tempfile.mkdtemp(), "a.geoterrain")
    >>> with StoreThread(dst) as w:
    ...     w.put_metadata({"note": "hi"})
    ...     w.put_blob((0, 0, 0), "heights", b"x")
    ...     _ = w.commit()
    >>> from geoterrain.store.reader import StoreReader
    >>> StoreReader(dst).metadata["note"]
    'hi'
    """

    def __init__(self, dst: str | Path, overwrite: bool = False, page_size: int = PAGE_SIZE):
        import queue

        self._calls: queue.SimpleQueue = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._done: Path | None = None
        self._thread = threading.Thread(target=self._run, args=(dst, overwrite, page_size),
                                        name="geoterrain-store", daemon=True)
        self._thread.start()

    def _run(self, dst, overwrite, page_size) -> None:
        try:
            with StoreWriter(dst, overwrite=overwrite, page_size=page_size) as w:
                while (call := self._calls.get()) is not None:
                    name, args = call
                    out = getattr(w, name)(*args)
                    if name == "commit":
                        self._done = out
                        return
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's commit
            self._error = exc

    def _call(self, name: str, *args) -> None:
        if self._error is None and self._thread.is_alive():
            self._calls.put((name, args))

    def put_metadata(self, items: dict) -> None:
        self._call("put_metadata", json.loads(json.dumps(items)))  # a copy, now

    def put_blob(self, key: tuple[int, int, int], kind: str, data: bytes) -> None:
        self.put_blobs(kind, {key: data})

    def put_blobs(self, kind: str, blobs: dict[tuple[int, int, int], bytes]) -> None:
        self._call("put_blobs", kind, blobs)

    def put_tiles(self, rows: dict[tuple[int, int, int], tuple]) -> None:
        self._call("put_tiles", rows)

    def commit(self) -> Path:
        """Wait for every call, then commit and publish (:meth:`StoreWriter.commit`)."""
        self._call("commit")
        self._calls.put(None)  # ends the thread if a failure stopped the calls
        self._thread.join()
        if self._error is not None:
            raise self._error
        if self._done is None:
            raise WriteError("the store's writer stopped before its commit")
        return self._done

    def abort(self) -> None:
        """Stop the thread; the partial file is dropped, the destination untouched."""
        self._calls.put(None)
        self._thread.join()

    def __enter__(self) -> StoreThread:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._thread.is_alive():
            self.abort()


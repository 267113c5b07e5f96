"""The store: one SQLite file, written atomically, every row checksummed.

Schema (version :data:`SCHEMA_VERSION`), two plain tables::

    catalog(id INTEGER PRIMARY KEY, data BLOB, crc32)  -- 0: metadata; 1: tile table
    blobs(id INTEGER PRIMARY KEY, data BLOB, crc32)    -- per-tile arrays, by id

The catalog's rows, their formats and checks are :mod:`geoterrain.store.catalog`'s: the
metadata (compressed JSON) and the tile table (every tile's numbers, every blob's
packed key, :mod:`geoterrain.store.keys`, and row id; schema 3's SQL tables of a row
each were a fifth of a small store, docs/lab/store-size.md). The blob rows are bare,
so the writer inserts them in the order that fills SQLite's leaf pages
(:mod:`geoterrain.store.pagepack`); the tile table finds them.

``kind`` is one of ``heights`` (residual-coded heights and valid mask),
``delta`` (per-vertex errors δ), ``radius`` (nested sphere radii) and
``normals`` (octahedral normal map); optionally ``delta_edge`` (a second δ, on the
tiles the metadata lists) and ``block_delta`` (every GeoMipMapping block's δ_n, one
table on the root tile). See docs/store.md.

A store is written to a hidden temporary file in the destination folder and
published only after the metadata (with its ``complete`` flag) is committed, so an
interrupted write never leaves a file that opens as a valid store. Without
``overwrite`` the publish is a create-if-absent (a hard link), so of two racing
writers exactly one wins.

A reader never writes beside a store: :class:`StoreReader` opens it read-only (no
journal, no ``-wal`` or ``-shm`` file is ever created beside it, so a store in a
read-only folder or on a read-only medium reads the same; a store in WAL mode, which
geoterrain never writes, is opened with SQLite's ``immutable=1``), and refuses one with a
non-empty write-ahead log, or a journal that no running edit holds and that is not one
to roll back, beside it (changes the file alone lacks, which reading without writing
cannot apply). Its one write: an edit killed in its transaction
(:mod:`geoterrain.store.editor`) leaves SQLite's hot journal, which the next reader rolls
back, restoring the old store byte for byte. Stores are published by a rename, and edited
in place in one transaction, whose locks keep a reader's view whole.

A store may come from a stranger: :class:`StoreReader` opens it read-only with
SQLite's ``trusted_schema`` off and refuses any schema object but the two plain
tables (no views, triggers or virtual tables), so reading runs no SQL of the file's.
Checksums bind each blob to its (level, x, y, kind) and each catalog row to its id;
the tile table's size is bounded by the file's (storecatalog), and it must match the
metadata's tile counts.
"""

from __future__ import annotations

import contextlib
import json
import os
import sqlite3
import struct
import threading
import weakref
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from geoterrain.core.atomicfiles import publish, remove_stale_partials
from geoterrain.core.osreads import EXACT, ReadMeter
from geoterrain.core.paths import STORE_SUFFIX, check_output, input_problem
from geoterrain.exceptions import (
    StoreCorruptError,
    StoreError,
    UsageError,
    WriteError,
)
from geoterrain.store.catalog import (  # noqa: F401 - the catalog's rows are the store's API
    META_ID,
    RATIO_CAP,
    TILE_COLUMNS,
    TILES_ID,
    TileTable,
    catalog_crc,
    pack_metadata,
    pack_stream,
    pack_tiles,
    table_columns,
    table_layout,
    unpack_metadata,
    unpack_tiles,
)
from geoterrain.store.keys import (  # noqa: F401 - the kinds and keys are the store's API
    BLOB_KINDS,
    BLOCK_KIND,
    EDGE_KIND,
    KIND_CODES,
    blob_key,
    pack_blob_key,
    pack_tile_key,
    tile_key,
    unpack_blob_key,
    unpack_tile_key,
    unpack_tile_keys,
)
from geoterrain.store.pagepack import LEAF_HEADER, blob_cell_sizes, pack_order

_KIND_NAMES = {i: k for k, i in KIND_CODES.items()}  # a blob key's kind number → its name

# the schema's history, 2: checksums bound to their tile and kind; per-level key digests;
#                    3: packed integer keys, bare blob rows found through blob_keys;
#                    4: metadata, tile numbers and blob keys in compressed catalog rows;
#                    5: height blobs of version 2 (range-coded, geoterrain/codec/entropy.py);
#                    6: δ and r blobs may hold cell centres only (vertexdata.CENTRES);
#                    8: height blobs of version 3 (cell centres predicted from both
#                       directions, geoterrain/codec/predict.py);
#                   10: zstd frames without their magic number (core/zstdsafe.py);
#                   12: r blobs above level 0 without their cell centres, derived on
#                       read (vertexdata.MIDS; projected and pixel frames);
#                   14: δ and r blobs above level 0 as differences from their parents'
#                       codes (vertexdata.PRED);
#                   17: the tile table's columns predicted (boxes on a 2^-12 grid,
#                       parents as their children's union; catalog.py), blob crc32s
#                       signed; a geographic level-0 r's cell centres as differences
#                       from their guess from the heights (vertexdata.CENTRES with PRED),
#                       and the normals' border rings as differences from the tile's
#                       derived map (metadata normals_ring_residual)
#                   20: a geographic r above level 0 as differences from guesses from the
#                       tile's heights (vertexdata.MIDS with PRED); δ blobs guessed from
#                       the tile's heights: PRED payloads in the order of their own-error
#                       gaps (PRED with SLACK), level-0 rings as differences from the own
#                       errors' codes (RING with PRED; ownguess.own_codes)
#                   23: the frame without its aeqd_wkt (rebuilt on read from crs_wkt and
#                       origin_crs, Frame.aeqd_wkt); a small grid's shaped payloads at
#                       zstd 15 (vertexdata.shaped_zstd_level; any zstd decoder reads them)
SCHEMA_VERSION = 23
ROOTS_SCHEMA_VERSION = 24  # a grid of root tiles (grid.layout "roots"); 7 before schema 8,
#                            9 before schema 10, 11 before 12, 13 before 14, 15 before 17,
#                            18 before 20, 21 before 23
LATTICE_SCHEMA_VERSION = 25  # a root grid whose geographic frame has proxy positions past
#                              level 0's lattice (frame.lattice, Frame.xy): an older
#                              reader would place its padding by pyproj, not where its
#                              bounds were computed (16 before schema 17, 19 before 20,
#                              22 before 23)
#: every version this geoterrain reads
SCHEMA_VERSIONS = (SCHEMA_VERSION, ROOTS_SCHEMA_VERSION, LATTICE_SCHEMA_VERSION)


def schema_version(grid: dict, frame: dict | None = None) -> int:
    """The schema version a store of this grid and frame (its metadata's ``grid`` and
    ``frame``) is written in: :data:`LATTICE_SCHEMA_VERSION` for a frame with a
    ``lattice``, :data:`ROOTS_SCHEMA_VERSION` for another grid of root tiles, else
    :data:`SCHEMA_VERSION` (square stores are the bytes they always were, and so are
    root grids without proxies).

    Examples
    --------
    >>> schema_version({"rows": 9, "cols": 9, "n": 3, "t": 2})
    23
    >>> roots = {"layout": "roots"}
    >>> schema_version(roots), schema_version(roots, {"lattice": [9, 17]})
    (24, 25)
    """
    if isinstance(frame, dict) and frame.get("lattice") is not None:
        return LATTICE_SCHEMA_VERSION
    return ROOTS_SCHEMA_VERSION if grid.get("layout") == "roots" else SCHEMA_VERSION


PAGE_SIZE = 1024  # bytes per SQLite page of a written store (SMALL_PAGE_SIZE: small ones)
SMALL_PAGE_SIZE = 512  # a grid of at most SMALL_GRID samples: its blobs' tails waste less
SMALL_GRID = 3 << 16  # 196 608: srtm3 (131 753) gains at 512 B, Fuji (2^18) loses
PACK_BYTES = 4 << 20  # blob bytes a writer holds before inserting them, packed (pagepack)
APPLICATION_ID = 0x47545252  # "GTRR" in the SQLite header: `file` can identify a store

# The only schema objects a store may hold: these two tables, their SQL word for word
# (a reader compares it), and no index, view or trigger. Each id is the rowid (an
# INTEGER PRIMARY KEY, so VACUUM keeps it: the catalog holds the blob ids).
_TABLE_SQL = {
    "catalog": "CREATE TABLE catalog (id INTEGER PRIMARY KEY, data BLOB NOT NULL, "
               "crc32 INTEGER NOT NULL)",
    "blobs": "CREATE TABLE blobs (id INTEGER PRIMARY KEY, data BLOB NOT NULL, "
             "crc32 INTEGER NOT NULL)",
}
_SCHEMA = "".join(f"{sql};\n" for sql in _TABLE_SQL.values())
# the writer's staging of the tile table (an attached file beside the partial store,
# never the store's own file)
_STAGING = ("CREATE TABLE staging.staged_tiles (key INTEGER PRIMARY KEY, "
            + ", ".join(f"n{j} REAL" for j in range(len(TILE_COLUMNS))) + ");\n"
            "CREATE TABLE staging.staged_blobs (key INTEGER PRIMARY KEY, "
            "blob INTEGER NOT NULL);\n")
# the tables of schema versions 1 to 3 (a reader still finds their version)
_OLD_TABLES = ("metadata", "tiles", "blobs", "blob_keys")
_OLD_METADATA_SQL = ("CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT NOT NULL)",
                     "CREATE TABLE metadata (name TEXT NOT NULL, value TEXT NOT NULL)")
# a damaged schema's SQLite error message may not even decode as UTF-8
_DB_ERRORS = (sqlite3.DatabaseError, UnicodeDecodeError)
REBUILD = "rebuild it with `geoterrain preprocess DEM --overwrite`"


def blob_crc(key: tuple[int, int, int], kind: str, data: bytes) -> int:
    """CRC-32 of a blob bound to its place: (level, x, y, kind) then the bytes, as a
    signed 32-bit number (schema 17; an unsigned one above 2^31 took SQLite 6 bytes).

    Examples
    --------
    >>> blob_crc((0, 0, 0), "delta", b"x") != blob_crc((0, 1, 0), "delta", b"x")
    True
    """
    c = zlib.crc32(data, zlib.crc32(struct.pack("<3q", *key) + kind.encode()))
    return c - (c >> 31 << 32)  # signed 32 bits: SQLite stores it in 4 bytes, not 6


def is_store(path: str | Path) -> bool:
    """True when ``path`` is a geoterrain store (by suffix, or by its first bytes).

    Examples
    --------
    >>> is_store("dem.geoterrain"), is_store("no-such.tif")
    (True, False)
    """
    if str(path).endswith(STORE_SUFFIX):
        return True
    try:
        with open(path, "rb") as fh:
            return fh.read(16).startswith(b"SQLite format 3")
    except OSError:
        return False


def _unlink_all(paths: tuple[Path, ...]) -> None:
    """Remove ``paths`` that exist (a writer's partial store and staging file)."""
    for f in paths:
        try:
            f.unlink()
        except OSError:
            pass


def page_size_for(rows: int, cols: int) -> int:
    """The SQLite page size a store of a ``rows`` × ``cols`` grid is written with:
    :data:`SMALL_PAGE_SIZE` (512 B) up to :data:`SMALL_GRID` (3 · 2^16) samples, where a
    blob's overflow tail and the catalog's pages are a large part of the file
    (roi_epsg3089: 14 336 → 12 288 B, srtm3 72 704 → 72 192 B; docs/lab/store-size.md),
    else :data:`PAGE_SIZE` (larger stores' B-trees stay shallow and a blob takes fewer
    page reads; Fuji's 2^18 samples: 356 352 B, 361 984 at 512 B). Readers take any size.

    Examples
    --------
    >>> page_size_for(100, 70), page_size_for(359, 367), page_size_for(513, 513)
    (512, 512, 1024)
    """
    return SMALL_PAGE_SIZE if int(rows) * int(cols) <= SMALL_GRID else PAGE_SIZE


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


class StoreReader:
    """Read a store, verifying schema, completeness and checksums.

    The file is untrusted input: it is opened read-only with ``trusted_schema``
    off, and refused unless its schema holds exactly the two plain tables, declared
    as the writer declares them (so no view, trigger or virtual table can run while
    reading).

    Examples
    --------
    >>> try:
    ...     StoreReader("missing.geoterrain")
    ... except StoreError as e:
    ...     print(str(e).split(";")[0])
    missing.geoterrain: no such store
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        why = input_problem(self.path)
        if why == "no such file":
            raise StoreError(f"{self.path}: no such store; run `geoterrain preprocess DEM` first")
        if why is not None:
            raise StoreError(f"{self.path}: {why}; give a .geoterrain store")
        _roll_back_interrupted_edit(self.path)  # the one write: restoring the old store
        for side in ("-journal", "-wal"):
            try:
                with open(f"{self.path}{side}", "rb") as fh:
                    head = fh.read(len(JOURNAL_MAGIC))
            except OSError:
                continue
            # a journal left now is an edit's still running (it holds its lock, and
            # SQLite's locks keep this reader's view whole), or one that is not SQLite's
            if head and not (side == "-journal" and _writer_active(self.path)):
                raise StoreError(f"{self.path}: SQLite's {self.path.name}{side} beside it holds "
                                 "changes the store file lacks, which geoterrain cannot apply "
                                 "without writing; re-run `geoterrain preprocess`")
        # every byte this reader reads from the file, opening included (bytes_read)
        self.meter = ReadMeter()
        self._payload_bytes = 0
        # read-only: no journal, -wal or -shm file is created beside the store; a store in
        # WAL mode (not one geoterrain writes) is opened immutable, as it would need a -shm
        # file otherwise. Others take SQLite's shared locks (the file is not written), so
        # a reader waits out another process's edit and sees it (data_version)
        path = self.path

        def connect() -> sqlite3.Connection:
            uri = path.resolve().as_uri() + "?mode=ro" + ("&immutable=1" if _wal_mode(path)
                                                          else "")
            return sqlite3.connect(uri, uri=True, check_same_thread=False, timeout=30.0)

        try:
            self.con = self.meter.call(connect)
        except (sqlite3.Error, ValueError, OSError):
            raise StoreError(f"{self.path}: cannot open the store read-only") from None
        try:
            self.meter.call(self._open)
        except BaseException:
            self.con.close()
            raise
        self.open_bytes = self.bytes_read  # what opening read
        self.blob_reads = 0  # how many blobs were read (tests count them)
        self._table: TileTable | None = None
        self.table_stamp: tuple[int, int] | None = None  # the parsed row's (crc32, bytes)
        self._lock = threading.Lock()
        self._snapshot = 0  # how deep in snapshot() (one read transaction while > 0)
        self._snapshot_version: int | None = None  # data_version read inside it

    def _open(self) -> None:
        # the schema, the catalog's two rows, the metadata: every check of opening
        try:
            # damaged text never raises: it decodes with U+FFFD and then fails a check
            self.con.text_factory = lambda b: b.decode("utf-8", "replace")
            self.con.execute("PRAGMA trusted_schema=OFF")
            self.con.execute("PRAGMA query_only=ON")
            self._check_schema()
            rows = self.con.execute("SELECT id, data, crc32 FROM catalog "
                                    f"WHERE id IN ({META_ID}, {TILES_ID})").fetchall()
            (n,) = self.con.execute("SELECT COUNT(*) FROM catalog").fetchone()
        except _DB_ERRORS:
            raise StoreError(f"{self.path}: not a geoterrain store (or damaged); "
                             "re-run `geoterrain preprocess`") from None
        if n != len(rows):
            raise self._foreign("its catalog holds rows of no meaning")
        if not all(type(i) is int and isinstance(d, bytes) for i, d, _ in rows):
            raise self._foreign("its catalog holds rows that are not numbered blobs")
        self._catalog = {i: (d, c) for i, d, c in rows}  # until parsed
        if META_ID not in self._catalog:
            raise StoreError(
                f"{self.path}: incomplete store (interrupted write); re-run preprocess")
        data, crc = self._catalog.pop(META_ID)
        if catalog_crc(META_ID, data) != crc:
            raise self._corrupt("metadata checksum mismatch")
        try:
            self.metadata = unpack_metadata(data)
        except ValueError as exc:
            raise self._corrupt(f"its metadata cannot be read ({exc})") from None
        if self.metadata.get("complete") is not True:
            raise StoreError(
                f"{self.path}: incomplete store (interrupted write); re-run preprocess")
        version = self.metadata.get("schema_version")
        if version not in SCHEMA_VERSIONS or type(version) is not int:
            raise StoreError(f"{self.path}: store schema version {_show(version)}, this "
                             f"geoterrain reads version {SCHEMA_VERSION} (and "
                             f"{ROOTS_SCHEMA_VERSION} and {LATTICE_SCHEMA_VERSION}, root "
                             f"grids); {REBUILD}")

    def _foreign(self, why: str) -> StoreError:
        return StoreError(f"{self.path}: not a geoterrain store ({why}); refusing to read it")

    def _check_schema(self) -> None:
        """Exactly the two plain tables, as the writer declares them, nothing else."""
        seen = self.con.execute("SELECT type, name, tbl_name, sql FROM sqlite_master").fetchall()
        tables = set()
        for typ, name, _tbl, sql in seen:
            if typ == "table" and name in _TABLE_SQL and sql == _TABLE_SQL[name]:
                tables.add(name)
                continue
            self._older_schema(seen)
            if typ == "table" and name in _TABLE_SQL:
                raise self._foreign(f"table {name} has other columns")
            raise self._foreign(f"it holds a {typ} {_show(name)}: views, triggers and "
                                "other objects are refused")
        if tables != set(_TABLE_SQL):
            raise self._foreign(f"tables {', '.join(sorted(set(_TABLE_SQL) - tables))} missing")

    def _older_schema(self, seen: list) -> None:
        """A store of an older schema (versions 1 to 3: plain tables and their
        primary-key indexes, the metadata table declared as then) says how to rebuild
        it, rather than "not a geoterrain store". Its schema_version is read only when
        the file holds nothing else, so no SQL of the file's can run."""
        plain = all(typ == "table" and name in _OLD_TABLES
                    and str(sql).startswith(f"CREATE TABLE {name} (")
                    or typ == "index" and sql is None and name == f"sqlite_autoindex_{tbl}_1"
                    for typ, name, tbl, sql in seen)
        if not plain or not any(("table", "metadata", "metadata", sql) in seen
                                for sql in _OLD_METADATA_SQL):
            return
        row = self.con.execute(
            "SELECT value FROM metadata WHERE name = 'schema_version'").fetchone()
        try:
            version = json.loads(row[0]) if row else None
        except (ValueError, TypeError, RecursionError):
            return
        if type(version) is int and 0 < version < SCHEMA_VERSION:
            raise StoreError(f"{self.path}: store schema version {version}, this geoterrain "
                             f"reads version {SCHEMA_VERSION}; {REBUILD}")

    def _corrupt(self, why: str) -> StoreCorruptError:
        return StoreCorruptError(f"{self.path}: {why}: the file is damaged; "
                                 "re-run `geoterrain preprocess`")

    def _damaged(self, what: str) -> StoreCorruptError:
        return self._corrupt(f"checksum mismatch in {what}")

    def table(self) -> TileTable:
        """The tile table, checksum-verified and parsed (once; thread-safe)."""
        if self._table is not None:
            return self._table
        with self._lock:
            if self._table is None:
                if TILES_ID not in self._catalog:
                    raise self._corrupt("the tile table is missing")
                data, crc = self._catalog[TILES_ID]
                if catalog_crc(TILES_ID, data) != crc:
                    raise self._damaged("the tile table")
                try:
                    self._table = unpack_tiles(data, self.path.stat().st_size)
                except (ValueError, OSError) as exc:
                    raise self._corrupt(f"the tile table cannot be read ({exc})") from None
                self.table_stamp = (crc, len(data))  # an editor compares its row with it
                del self._catalog[TILES_ID]  # its bytes are not needed again
            return self._table

    def _rowid_of(self, key: int) -> int | None:
        t = self.table()
        i = int(np.searchsorted(t.blobs, key))
        return int(t.ids[i]) if i < len(t.blobs) and t.blobs[i] == key else None

    def get_blob(self, key: tuple[int, int, int], kind: str) -> bytes | None:
        """A tile's blob, checksum-verified (bound to key and kind), or None when not stored."""
        return self.get_blob_version(key, kind, False)[0]

    def get_blob_version(self, key: tuple[int, int, int], kind: str, version: bool = True
                         ) -> tuple[bytes | None, int]:
        """:meth:`get_blob` and, read right after it in the same metered call, the
        :meth:`version` (−1 unless ``version``): a reader that checks each blob against
        the version it opened pays one look at the I/O counters for both.

        Examples
        --------
        >>> r = StoreReader(t.path)
        >>> blob, v = r.get_blob_version((0, 0, 0), "heights")
        >>> blob == r.get_blob((0, 0, 0), "heights"), v == r.version()
        (True, True)
        >>> r.close()
        """
        rowid = self._rowid_of(blob_key(key, kind))
        if rowid is None:
            return None, self.version() if version else -1

        def read():
            row = self.con.execute("SELECT data, crc32 FROM blobs WHERE rowid = ?",
                                   (rowid,)).fetchone()
            if not version:
                return row, -1
            if self._snapshot_version is not None:  # no commit can come in between
                return row, self._snapshot_version
            with self._lock:
                v = int(self.con.execute("PRAGMA data_version").fetchone()[0])
                if self._snapshot:  # the read above began the snapshot's transaction
                    self._snapshot_version = v
                return row, v

        try:
            row, ver = self.meter.call(read)
        except (*_DB_ERRORS, OverflowError):
            raise self._damaged(f"tile {key} {kind}") from None
        if row is None:
            raise self._damaged(f"tile {key} {kind} (its row is missing)")
        self.blob_reads += 1
        data, crc = row
        self._payload_bytes += len(data) if isinstance(data, bytes) else 0
        if not isinstance(data, bytes) or blob_crc(key, kind, data) != crc:
            raise self._damaged(f"tile {key} {kind}")
        return data, ver

    def tiles(self) -> dict[tuple[int, int, int], dict]:
        """Every stored tile's numbers, checksum-verified, checked against the tile counts.

        Every tile must hold one blob of each kind, and no blob may lack its tile. The
        table is checked as arrays first, so a damaged one costs no per-tile objects.
        """
        t = self.table()
        damaged = self._corrupt("the blobs do not match the tile table (blobs missing or added)")
        levels = np.bincount(t.tiles & 31, minlength=32) if len(t.tiles) else np.zeros(32)
        if {str(L): int(c) for L, c in enumerate(levels) if c} != self.metadata.get(
                "tile_counts"):
            raise self._corrupt("the tile table does not match the recorded tile counts "
                                "(rows missing or added)")
        nvalid = t.numbers[:, 0]
        if not np.isfinite(nvalid).all() or (nvalid < 0).any() or (nvalid % 1 != 0).any():
            raise self._corrupt("the tile table holds an impossible count of valid samples")
        # the blob keys: one of each kind per tile, the δ_edge tiles', the root's table
        try:
            edge = np.array([blob_key(k, EDGE_KIND) for k in self.edge_keys()], np.int64)
        except ValueError:  # a key out of any grid's range
            raise self._damaged("the delta_edge list") from None
        want = [(t.tiles[:, None] << 3 | np.arange(len(BLOB_KINDS))).ravel(), edge]
        if "block_delta_levels" in self.metadata and len(t.tiles):
            want.append(np.array([blob_key((int(levels.nonzero()[0][-1]), 0, 0), BLOCK_KIND)]))
        want = np.sort(np.concatenate(want))  # distinct: no two equal neighbours (not
        # np.unique: numpy 2's imports numpy.ma, 8 ms of an edit's or info's start)
        if (want[1:] == want[:-1]).any() or not np.array_equal(want, t.blobs):
            raise damaged
        # the ids are distinct and fill the blob table's rowid range exactly, so every
        # row is named once (a missing row in the range reads as "missing"; a row's
        # checksum binds it to its key, so an id moved to another row fails)
        try:
            # the rowid range only, one aggregate a query: SQLite reads one root-to-leaf
            # path for each (its min/max shortcut takes a query of a single min or max;
            # both in one query, or counting the rows, read every leaf page of the blobs)
            lo, hi = self.meter.call(lambda: tuple(
                self.con.execute(f"SELECT {f}(rowid) FROM blobs").fetchone()[0]
                for f in ("MIN", "MAX")))
        except _DB_ERRORS:
            raise self._damaged("the blob table") from None
        ids = t.ids
        if len(ids) and ((lo, hi) != (int(ids.min()), int(ids.max())) or hi - lo + 1 != len(ids)
                         or (np.diff(np.sort(ids)) == 0).any()):
            raise damaged
        if not len(ids) and lo is not None:
            raise damaged
        out = {}
        L, x, y = (a.tolist() for a in unpack_tile_keys(t.tiles))  # whole arrays
        for key, r in zip(zip(L, x, y, strict=True), t.numbers.tolist(), strict=True):
            vals = [None if v != v else v for v in r]  # NaN: an absent number
            vals[0] = int(vals[0])
            out[key] = dict(zip(TILE_COLUMNS, vals, strict=True))
        return out

    def edge_keys(self) -> dict[tuple[int, int, int], float]:
        """The tiles with a ``delta_edge`` blob and the largest δ_edge of their stored
        vertices (+inf where stored as None), from the metadata; {} when it has none. A
        key may name a tile that is not stored (then the blob is all it has); the
        terrain checks it lies in the grid."""
        rows = self.metadata.get("delta_edge", [])
        out = {}
        if not isinstance(rows, list):
            raise self._damaged("the delta_edge list")
        for r in rows:
            if not (isinstance(r, list) and len(r) == 4 and all(type(v) is int for v in r[:3])
                    and (r[3] is None or (type(r[3]) in (int, float) and r[3] >= 0))):
                raise self._damaged("the delta_edge list")
            key = tuple(r[:3])
            if min(key) < 0 or key in out:
                raise self._damaged("the delta_edge list")
            out[key] = float("inf") if r[3] is None else float(r[3])
        return out

    def blob_bytes_by_kind_level(self) -> dict[tuple[str, int], int]:
        """Blob bytes per (kind, level) (``info``'s split); a key without its row is
        damage."""
        try:
            sizes = dict(self.meter.call(lambda: self.con.execute(
                "SELECT rowid, LENGTH(data) FROM blobs").fetchall()))
        except _DB_ERRORS:
            raise self._damaged("the blob table") from None
        # whole arrays: a 4097² store has some 55 000 blobs
        t = self.table()
        if not len(t.ids):
            return {}
        ids = np.fromiter(sizes, np.int64, len(sizes))
        n = np.fromiter((-1 if v is None else v for v in sizes.values()), np.int64, len(sizes))
        order = np.argsort(ids)
        at = order[np.minimum(np.searchsorted(ids[order], t.ids), max(len(ids) - 1, 0))]
        kind, level = t.blobs & 7, (t.blobs >> 3) & 31
        if not (len(ids) and (ids[at] == t.ids).all() and (n[at] >= 0).all()
                and (t.blobs >= 0).all() and np.isin(kind, list(_KIND_NAMES)).all()):
            raise self._damaged("the blob table")  # a key without its row, a NULL blob
        code = kind * 32 + level
        per = np.bincount(code, weights=n[at])
        return {(_KIND_NAMES[int(c) >> 5], int(c) & 31): int(per[c])
                for c in np.unique(code)}

    @contextlib.contextmanager
    def snapshot(self) -> Iterator[None]:
        """Reads inside it make one read transaction: SQLite takes its shared lock at the
        first read and holds it to the end, so no other connection commits meanwhile
        (an edit waits for it) and the :meth:`version` read with the first blob holds
        for every later one (:meth:`get_blob_version` asks for it once). Each statement
        then skips its own lock, unlock and change-counter check. Nestable; a store
        opened immutable (WAL) reads the same either way.

        Examples
        --------
        >>> r = StoreReader(t.path)
        >>> with r.snapshot():
        ...     a = r.get_blob_version((0, 0, 0), "heights")
        ...     b = r.get_blob_version((0, 1, 0), "heights")
        >>> a[1] == b[1] == r.version(), a[0] == r.get_blob((0, 0, 0), "heights")
        (True, True)
        >>> r.close()
        """
        with self._lock:
            if self._snapshot == 0:
                self.meter.call(lambda: self.con.execute("BEGIN"))
            self._snapshot += 1
        try:
            yield
        finally:
            with self._lock:
                self._snapshot -= 1
                if self._snapshot == 0:
                    self._snapshot_version = None
                    self.meter.call(lambda: self.con.execute("COMMIT"))

    def version(self) -> int:
        """SQLite's ``data_version`` of this connection: it changes when another
        connection (an edit, :mod:`geoterrain.store.editor`) commits a change to the
        file, so a reader can tell that what it holds is stale."""
        with self._lock:
            return int(self.meter.call(
                lambda: self.con.execute("PRAGMA data_version").fetchone()[0]))

    @property
    def bytes_read(self) -> int:
        """Every byte this reader has read from the store file, opening included, as the
        operating system counts them (:mod:`geoterrain.core.osreads`); where it does not
        count a thread's reads, the blobs' bytes only."""
        return self.meter.bytes if EXACT else self._payload_bytes

    def close(self) -> None:
        self.con.close()


JOURNAL_MAGIC = bytes.fromhex("d9d505f920a163d7")  # a rollback journal's header (SQLite)


def _writer_active(path: Path) -> bool:
    """Whether another process holds SQLite's RESERVED lock on the store (an edit in its
    transaction): asked of the file's POSIX locks, taking none."""
    import fcntl
    import struct

    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:  # struct flock: type, whence, start, len, pid; RESERVED_BYTE is 2^30 + 1
        lk = struct.pack("hhqqi", fcntl.F_RDLCK, os.SEEK_SET, 0x40000001, 1, 0)
        got = fcntl.fcntl(fd, fcntl.F_GETLK, lk)
        return struct.unpack("hhqqi", got)[0] != fcntl.F_UNLCK
    except OSError:
        return False
    finally:
        os.close(fd)


def _wal_mode(path: Path) -> bool:
    """Whether the SQLite file ``path`` is in WAL mode (its header's read/write versions)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(20)
    except OSError:
        return False
    return len(head) == 20 and head[18] == 2 and head[19] == 2


def _roll_back_interrupted_edit(path: Path) -> None:
    """An edit killed in its transaction leaves ``STORE-journal`` (the old pages) beside
    the store: SQLite rolls it back when a connection that may write reads the file, and
    a read-only one refuses the file meanwhile. This opens such a connection once and
    reads the schema, which restores the old store; no SQL of the file's runs. A journal
    of an edit still running (it holds its lock) is left alone."""
    journal = Path(str(path) + "-journal")
    try:
        with open(journal, "rb") as fh:
            if fh.read(len(JOURNAL_MAGIC)) != JOURNAL_MAGIC:
                return  # none, or not SQLite's: the reader refuses it without writing
    except OSError:
        return
    try:
        con = sqlite3.connect(path, timeout=30.0)
        try:
            con.execute("PRAGMA trusted_schema=OFF")
            con.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        finally:
            con.close()
    except sqlite3.Error:
        raise StoreError(f"{path}: an interrupted edit left {journal.name} beside it; open "
                         "the store once where it can be written (the edit is rolled back "
                         "then), and keep the journal with it until then") from None


def _show(v: object) -> str:
    """A value from a store, printable: repr, no control characters, at most 40 chars."""
    r = "".join(c if c.isprintable() else "?" for c in repr(v))
    return r if len(r) <= 40 else r[:37] + "..."

"""The store's reader: :class:`StoreReader`, and the checks of opening a store.

A reader never writes beside a store: :class:`StoreReader` opens it read-only (no
journal, no ``-wal`` or ``-shm`` file is ever created beside it, so a store in a
read-only folder or on a read-only medium reads the same; a store in WAL mode, which
geoterrain never writes, is opened with SQLite's ``immutable=1``), and refuses one with a
non-empty write-ahead log, or a journal that no running edit holds and that is not one
to roll back, beside it (changes the file alone lacks, which reading without writing
cannot apply). Its one write: an edit killed in its transaction
(:mod:`geoterrain.store.editor`) leaves SQLite's hot journal, which the next reader rolls
back (:mod:`geoterrain.store.recovery`), restoring the old store byte for byte. Stores are
published by a rename, and edited in place in one transaction, whose locks keep a
reader's view whole.

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
import sqlite3
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from geoterrain.core.osreads import EXACT, ReadMeter
from geoterrain.core.paths import input_problem
from geoterrain.exceptions import StoreCorruptError, StoreError
from geoterrain.store.catalog import (
    META_ID,
    TILE_COLUMNS,
    TILES_ID,
    TileTable,
    catalog_crc,
    unpack_metadata,
    unpack_tiles,
)
from geoterrain.store.keys import (
    BLOB_KINDS,
    BLOCK_KIND,
    EDGE_KIND,
    KIND_CODES,
    blob_key,
    unpack_tile_keys,
)
from geoterrain.store.recovery import (
    JOURNAL_MAGIC,
    roll_back_interrupted_edit,
    wal_mode,
    writer_active,
)
from geoterrain.store.schema import (
    LATTICE_SCHEMA_VERSION,
    ROOTS_SCHEMA_VERSION,
    SCHEMA_VERSION,
    SCHEMA_VERSIONS,
    TABLE_SQL,
    blob_crc,
)

_KIND_NAMES = {i: k for k, i in KIND_CODES.items()}  # a blob key's kind number → its name

# the tables of schema versions 1 to 3 (a reader still finds their version)
_OLD_TABLES = ("metadata", "tiles", "blobs", "blob_keys")
_OLD_METADATA_SQL = ("CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT NOT NULL)",
                     "CREATE TABLE metadata (name TEXT NOT NULL, value TEXT NOT NULL)")
# a damaged schema's SQLite error message may not even decode as UTF-8
_DB_ERRORS = (sqlite3.DatabaseError, UnicodeDecodeError)
REBUILD = "rebuild it with `geoterrain preprocess DEM --overwrite`"
# blobs a query of StoreReader.get_blobs reads at most (SQLite's bound on a statement's
# parameters is 999 in builds before 3.32)
BATCH = 500


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
        roll_back_interrupted_edit(self.path)  # the one write: restoring the old store
        for side in ("-journal", "-wal"):
            try:
                with open(f"{self.path}{side}", "rb") as fh:
                    head = fh.read(len(JOURNAL_MAGIC))
            except OSError:
                continue
            # a journal left now is an edit's still running (it holds its lock, and
            # SQLite's locks keep this reader's view whole), or one that is not SQLite's
            if head and not (side == "-journal" and writer_active(self.path)):
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
            uri = path.resolve().as_uri() + "?mode=ro" + ("&immutable=1" if wal_mode(path)
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
        # (key, kind) → blob read ahead inside the snapshot (read_ahead), taken once
        self._ahead: dict[tuple[tuple[int, int, int], str], bytes] = {}

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
            if typ == "table" and name in TABLE_SQL and sql == TABLE_SQL[name]:
                tables.add(name)
                continue
            self._older_schema(seen)
            if typ == "table" and name in TABLE_SQL:
                raise self._foreign(f"table {name} has other columns")
            raise self._foreign(f"it holds a {typ} {_show(name)}: views, triggers and "
                                "other objects are refused")
        if tables != set(TABLE_SQL):
            raise self._foreign(f"tables {', '.join(sorted(set(TABLE_SQL) - tables))} missing")

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
        if self._ahead:  # read ahead in this snapshot (its version holds for it)
            data = self._ahead.pop((key, kind), None)
            if data is not None:
                return data, self._version_after_read(version, began=False)
        rowid = self._rowid_of(blob_key(key, kind))
        if rowid is None:
            return None, self.version() if version else -1

        def read():
            row = self.con.execute("SELECT data, crc32 FROM blobs WHERE rowid = ?",
                                   (rowid,)).fetchone()
            return row, self._version_after_read(version, began=True)

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

    def _version_after_read(self, version: bool, began: bool) -> int:
        """The :meth:`version` read right after a blob query, inside the same metered call
        (−1 unless ``version``). Inside a :meth:`snapshot` it is read once, by the query
        that began the snapshot's transaction (``began``): no commit can come in between
        after that."""
        if not version:
            return -1
        if self._snapshot_version is not None:  # no commit can come in between
            return self._snapshot_version
        with self._lock:
            v = int(self.con.execute("PRAGMA data_version").fetchone()[0])
            if self._snapshot and began:  # the read above began the snapshot's transaction
                self._snapshot_version = v
            return v

    def get_blobs(self, items: Sequence[tuple[tuple[int, int, int], str]],
                  version: bool = False) -> tuple[list[bytes | None], int]:
        """Many blobs at once: :meth:`get_blob` of each ``(key, kind)`` of ``items`` (None
        where not stored), read by one query a :data:`BATCH` of them, every blob's
        checksum verified, the I/O counters looked at once a query (``bytes_read`` stays
        what the operating system counts); and the :meth:`version` read in each query's
        metered call (−1 unless ``version``): the first's, or a later one's where another
        connection committed between two queries. A blob that fails its checksum, or
        a query that fails, is read again alone, so the error is the one-line error of
        :meth:`get_blob` (the first such blob of ``items``).

        Examples
        --------
        >>> r = StoreReader(t.path)
        >>> keys = [((0, 0, 0), "heights"), ((9, 9, 9), "heights"), ((0, 0, 0), "delta")]
        >>> blobs, v = r.get_blobs(keys, version=True)
        >>> blobs == [r.get_blob(*k) for k in keys], v == r.version(), blobs[1]
        (True, True, None)
        >>> r.close()
        """
        keys = [blob_key(k, kind) for k, kind in items]
        t = self.table()
        bk = np.array(keys, np.int64)
        at = np.minimum(np.searchsorted(t.blobs, bk), max(len(t.blobs) - 1, 0))
        found = (t.blobs[at] == bk) if len(t.blobs) else np.zeros(len(keys), bool)
        rowids = np.where(found, t.ids[at] if len(t.ids) else 0, -1).tolist()
        want = sorted({r for r in rowids if r >= 0})
        vers: list[int] = []
        rows: dict[int, tuple] = {}
        for n in range(0, max(len(want), 1), BATCH):
            part = want[n:n + BATCH]

            def read(part=part):
                got = self.con.execute(
                    f"SELECT rowid, data, crc32 FROM blobs WHERE rowid IN "
                    f"({','.join('?' * len(part))})", part).fetchall() if part else []
                return got, self._version_after_read(version, began=bool(part))

            try:
                got, v = self.meter.call(read)
            except (*_DB_ERRORS, OverflowError):
                got, v = [], (self.version() if version else -1)
            vers.append(v)
            rows.update((row[0], row[1:]) for row in got if type(row[0]) is int)
        # the first query's version, or a later one's where a commit came in between
        ver = next((v for v in vers if v != vers[0]), vers[0])
        out: list[bytes | None] = []
        for (key, kind), rid in zip(items, rowids, strict=True):
            if rid < 0:
                out.append(None)
                continue
            data, crc = rows.get(rid, (None, None))
            if not isinstance(data, bytes) or blob_crc(key, kind, data) != crc:
                # read alone: its own one-line error (damaged, or its row missing)
                data = self.get_blob(key, kind)
            out.append(data)
        self.blob_reads += len(want)
        self._payload_bytes += sum(len(d) for d, _ in rows.values() if isinstance(d, bytes))
        return out, ver

    def read_ahead(self, items: Sequence[tuple[tuple[int, int, int], str]]) -> int:
        """Inside a :meth:`snapshot`: the blobs of ``items`` not yet read ahead, read now
        by :meth:`get_blobs` (one query a :data:`BATCH`, each checksum verified, the I/O
        counters looked at once) and kept until :meth:`get_blob_version` asks for them
        (each once) or the snapshot ends; its version holds for them (no commit comes in
        between). Returns how many were kept; outside a snapshot nothing is read (0).

        Examples
        --------
        >>> r = StoreReader(t.path)
        >>> with r.snapshot():
        ...     r.read_ahead([((0, 0, 0), "delta"), ((0, 1, 0), "delta")])
        ...     reads = r.blob_reads
        ...     blob, v = r.get_blob_version((0, 0, 0), "delta")
        ...     r.blob_reads == reads, v == r.version()
        2
        (True, True)
        >>> blob == r.get_blob((0, 0, 0), "delta"), r.read_ahead([((0, 0, 0), "delta")])
        (True, 0)
        >>> r.close()
        """
        if not self._snapshot:
            return 0
        want = list(dict.fromkeys(it for it in items if it not in self._ahead))
        if not want:
            return 0
        blobs, _ = self.get_blobs(want, version=True)  # begins the snapshot's reads
        kept = {it: b for it, b in zip(want, blobs, strict=True) if b is not None}
        self._ahead.update(kept)
        return len(kept)

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
                    self._ahead.clear()
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



def _show(v: object) -> str:
    """A value from a store, printable: repr, no control characters, at most 40 chars."""
    r = "".join(c if c.isprintable() else "?" for c in repr(v))
    return r if len(r) <= 40 else r[:37] + "..."

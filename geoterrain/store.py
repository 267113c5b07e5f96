"""The store: one SQLite file, written atomically, every blob checksummed.

Schema (version :data:`SCHEMA_VERSION`), in the spirit of MBTiles/GeoPackage::

    metadata(name TEXT, value TEXT)                    -- JSON values, one row a name
    tiles(key INTEGER PRIMARY KEY, nvalid, zmin, zmax, error, boundary_error,
          xmin, xmax, ymin, ymax, delta_max, radius_max, crc32)  -- per-tile numbers
    blobs(id INTEGER PRIMARY KEY, data BLOB, crc32)    -- per-tile arrays, by id
    blob_keys(key INTEGER PRIMARY KEY, blob)           -- key → blobs rowid

A tile's key packs (level, x, y) as :func:`tile_key` (the Morton number of x, y, then
5 bits of level), a blob's key packs the tile's and its kind as :func:`blob_key`:
small integers, so the keys cost 2–4 bytes where the columns and their primary-key
indexes of schema 2 cost about 20 (docs/benchmarks.md §7h). The blob rows themselves
are bare, so the writer can insert them in the order that fills SQLite's leaf pages
(:mod:`geoterrain.pagepack`); ``blob_keys`` finds them.

``kind`` is one of ``heights`` (residual-coded heights and valid mask),
``delta`` (per-vertex errors δ), ``radius`` (nested sphere radii) and
``normals`` (octahedral normal map); optionally ``delta_edge`` (a second δ, on the
tiles the metadata lists) and ``block_delta`` (every GeoMipMapping block's δ_n, one
table on the root tile). See docs/store.md.

A store is written to a hidden temporary file in the destination folder and
published only after the ``complete`` flag is committed, so an interrupted write
never leaves a file that opens as a valid store. Without ``overwrite`` the publish
is a create-if-absent (a hard link), so of two racing writers exactly one wins.

A store may come from a stranger: :class:`StoreReader` opens it read-only with
SQLite's ``trusted_schema`` off and refuses any schema object but the three
plain tables (no views, triggers or virtual tables), so reading runs no SQL of
the file's. Checksums bind each blob and row to its (level, x, y, kind), and
the metadata records each level's tile count and key digest.
"""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3
import struct
import zlib
from pathlib import Path

from geoterrain.atomicfiles import publish, remove_stale_partials
from geoterrain.exceptions import (
    StoreCorruptError,
    StoreError,
    UsageError,
    WriteError,
    exists_error,
)
from geoterrain.pagepack import LEAF_HEADER, leaf_cell_size, pack_order
from geoterrain.storekeys import (  # noqa: F401 - the kinds and keys are the store's API
    BLOB_KINDS,
    BLOCK_KIND,
    EDGE_KIND,
    KIND_CODES,
    blob_key,
    tile_key,
    unpack_blob_key,
    unpack_tile_key,
)

SCHEMA_VERSION = 3  # 2: checksums bound to their tile and kind; per-level key digests;
#                    3: packed integer keys, bare blob rows found through blob_keys
PAGE_SIZE = 1024  # bytes per SQLite page of a written store
PACK_BYTES = 4 << 20  # blob bytes a writer holds before inserting them, packed (pagepack)
APPLICATION_ID = 0x47545252  # "GTRR" in the SQLite header: `file` can identify a store
TILE_COLUMNS = ("nvalid", "zmin", "zmax", "error", "boundary_error",
                "xmin", "xmax", "ymin", "ymax", "delta_max", "radius_max")

# The only schema objects a store may hold: these four tables, their SQL word for word
# (a reader compares it), and no index, view or trigger.
_TABLE_SQL = {
    # no primary key: its index cost a page; the writer writes each name once, and a
    # reader refuses a repeated one
    "metadata": "CREATE TABLE metadata (name TEXT NOT NULL, value TEXT NOT NULL)",
    "tiles": "CREATE TABLE tiles (key INTEGER PRIMARY KEY, nvalid INTEGER NOT NULL, "
             + ", ".join(f"{c} REAL" for c in TILE_COLUMNS[1:]) + ", crc32 INTEGER NOT NULL)",
    # id is the rowid (an INTEGER PRIMARY KEY, so VACUUM keeps it: blob_keys holds it)
    "blobs": "CREATE TABLE blobs (id INTEGER PRIMARY KEY, data BLOB NOT NULL, "
             "crc32 INTEGER NOT NULL)",
    "blob_keys": "CREATE TABLE blob_keys (key INTEGER PRIMARY KEY, blob INTEGER NOT NULL)",
}
_SCHEMA = "".join(f"{sql};\n" for sql in _TABLE_SQL.values())
# the metadata table of schema versions 1 and 2 (a reader still finds their version)
_OLD_METADATA_SQL = "CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT NOT NULL)"
_META_MAX_BYTES = 1 << 20  # metadata is a few kB; more is not a store of ours
# a damaged schema's SQLite error message may not even decode as UTF-8
_DB_ERRORS = (sqlite3.DatabaseError, UnicodeDecodeError)
REBUILD = "rebuild it with `geoterrain preprocess DEM --overwrite`"


def blob_crc(key: tuple[int, int, int], kind: str, data: bytes) -> int:
    """CRC-32 of a blob bound to its place: (level, x, y, kind) then the bytes.

    Examples
    --------
    >>> blob_crc((0, 0, 0), "delta", b"x") != blob_crc((0, 1, 0), "delta", b"x")
    True
    """
    return zlib.crc32(data, zlib.crc32(struct.pack("<3q", *key) + kind.encode()))


def keys_digest(keys) -> str:
    """SHA-256 (hex) of sorted tile keys: a missing or extra row changes it.

    Examples
    --------
    >>> keys_digest([(0, 1, 0), (0, 0, 0)]) == keys_digest([(0, 0, 0), (0, 1, 0)])
    True
    """
    h = hashlib.sha256()
    for k in sorted(keys):
        h.update(struct.pack("<3q", *k))
    return h.hexdigest()


def level_digests(keys) -> dict[str, list]:
    """Per level: [tile count, :func:`keys_digest`] (what the metadata records)."""
    by: dict[int, list] = {}
    for k in keys:
        by.setdefault(int(k[0]), []).append(tuple(int(v) for v in k))
    return {str(L): [len(ks), keys_digest(ks)] for L, ks in sorted(by.items())}


def _row_crc(key: tuple[int, int, int], values: tuple) -> int:
    # Pack numbers canonically so a flipped bit in any column is detected.
    nums = [float("nan") if v is None else float(v) for v in values]
    return zlib.crc32(struct.pack(f"<3q{len(nums)}d", *key, *nums))


def _meta_crc(items: dict[str, str]) -> int:
    return zlib.crc32(json.dumps(items, sort_keys=True).encode())


def default_store_path(src: str | Path) -> Path:
    """The input's path with the suffix ``.geoterrain``.

    Examples
    --------
    >>> default_store_path("dem/fuji.tif").name
    'fuji.geoterrain'
    """
    return Path(src).with_suffix(".geoterrain")


def is_store(path: str | Path) -> bool:
    """True when ``path`` is a geoterrain store (by suffix, or by its first bytes).

    Examples
    --------
    >>> is_store("dem.geoterrain"), is_store("no-such.tif")
    (True, False)
    """
    if str(path).endswith(".geoterrain"):
        return True
    try:
        with open(path, "rb") as fh:
            return fh.read(16).startswith(b"SQLite format 3")
    except OSError:
        return False


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

    def __init__(self, dst: str | Path, overwrite: bool = False):
        self.dst = Path(dst)
        if self.dst.exists() and not overwrite:
            raise exists_error(self.dst)
        if self.dst.is_dir():
            raise UsageError(f"{self.dst} is a directory; give a file path",
                             cli=f"{self.dst} is a directory; give a file path with -o")
        parent = self.dst.parent if str(self.dst.parent) else Path(".")
        if not parent.is_dir():
            raise UsageError(f"{parent}: no such directory for the store; create it first")
        remove_stale_partials(parent)
        self.tmp = parent / f".{self.dst.name}.partial-{os.getpid()}"
        self.overwrite = overwrite
        self._keys: list[tuple[int, int, int]] = []
        self._meta: dict[str, str] = {}
        self._rows: list[tuple] = []  # blob rows not yet inserted (see _flush)
        self._row_bytes = 0
        self._rowid = 0  # rows inserted so far: the next one's rowid is this + 1
        self._committed = False
        try:
            if self.tmp.exists():
                self.tmp.unlink()
            self.con = sqlite3.connect(self.tmp, isolation_level=None)
        except (OSError, sqlite3.Error) as exc:
            raise WriteError(
                f"cannot write in {parent}: {exc}; choose a writable -o path") from None
        self._guard(self._init)

    def _init(self) -> None:
        # The temporary file is not the store; durability comes from fsync + rename.
        # Small pages: a tile blob of a few kB overflows into whole pages, and 4 kB pages
        # left ~30 % of a store as slack (docs/benchmarks.md §7); readers take any size.
        self.con.execute(f"PRAGMA page_size={PAGE_SIZE}")
        self.con.execute("PRAGMA journal_mode=OFF")
        self.con.execute("PRAGMA synchronous=OFF")
        self.con.execute(f"PRAGMA application_id={APPLICATION_ID}")
        self.con.executescript(_SCHEMA)
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
        """Add metadata entries (JSON-encoded)."""
        for k, v in items.items():
            self._meta[k] = json.dumps(v)

    def put_blob(self, key: tuple[int, int, int], kind: str, data: bytes) -> None:
        self.put_blobs(kind, {key: data})

    def put_blobs(self, kind: str, blobs: dict[tuple[int, int, int], bytes]) -> None:
        """Add blobs of one kind. They are inserted in batches of about
        :data:`PACK_BYTES`, each in the order that fills SQLite's leaf pages
        (:mod:`geoterrain.pagepack`), so a store's bytes depend on the sequence of rows
        given, not on how it is split into calls."""
        for k, d in blobs.items():
            self._rows.append((blob_key(k, kind), d, blob_crc(k, kind, d)))
            self._row_bytes += len(d)
            if self._row_bytes >= PACK_BYTES:
                self._guard(self._flush)

    def _flush(self) -> None:
        """Insert the buffered blob rows, packed into leaf pages (pagepack.pack_order),
        and their keys."""
        rows, self._rows, self._row_bytes = self._rows, [], 0
        if not rows:
            return
        last = self._rowid + len(rows)  # cells are sized with the batch's largest rowid
        sizes = [leaf_cell_size((None, *r[1:]), last, PAGE_SIZE) for r in rows]
        order = pack_order(sizes, PAGE_SIZE - LEAF_HEADER)
        self.con.executemany("INSERT INTO blobs VALUES (NULL,?,?)",
                             (rows[i][1:] for i in order))
        # their keys in key order (in the packing's order they would split the pages of
        # blob_keys half empty; a store of one batch gets full pages, a larger one full
        # pages within each batch's run of keys)
        self.con.executemany("INSERT INTO blob_keys VALUES (?,?)", sorted(
            (rows[i][0], rowid) for rowid, i in enumerate(order, self._rowid + 1)))
        self._rowid = last

    def put_tiles(self, rows: dict[tuple[int, int, int], tuple]) -> None:
        """Per-tile numbers, in the order of :data:`TILE_COLUMNS`."""
        self._keys.extend(rows)
        # in key order (rows appended in rowid order fill their pages), one row at a
        # time: a list of every row would double the memory of a large pyramid's table
        data = ((tile_key(k), *rows[k], _row_crc(k, rows[k])) for k in sorted(rows, key=tile_key))
        self._guard(self.con.executemany,
                    f"INSERT INTO tiles VALUES ({', '.join('?' * (len(TILE_COLUMNS) + 2))})", data)

    def commit(self) -> Path:
        """Finish: write metadata and the complete flag, fsync, rename into place."""
        meta = dict(self._meta)
        meta["schema_version"] = json.dumps(SCHEMA_VERSION)
        meta["tile_keys"] = json.dumps(level_digests(self._keys))
        meta["complete"] = json.dumps(True)

        def _finish():
            self._flush()
            self.con.executemany("INSERT INTO metadata VALUES (?,?)", sorted(meta.items()))
            self.con.execute("INSERT INTO metadata VALUES (?,?)",
                             ("metadata_crc32", json.dumps(_meta_crc(meta))))
            self.con.execute("COMMIT")
            self.con.close()
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
        return self.dst

    def abort(self) -> None:
        """Drop the temporary file; the destination is untouched."""
        try:
            self.con.close()
        except Exception:  # noqa: BLE001 - closing a broken connection
            pass
        try:
            self.tmp.unlink()
        except OSError:
            pass

    def __enter__(self) -> StoreWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if not self._committed:
            self.abort()


class StoreReader:
    """Read a store, verifying schema, completeness and checksums.

    The file is untrusted input: it is opened read-only with ``trusted_schema``
    off, and refused unless its schema holds exactly the four plain tables, declared
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
        if not self.path.is_file():
            raise StoreError(f"{self.path}: no such store; run `geoterrain preprocess DEM` first")
        try:
            self.con = sqlite3.connect(self.path.resolve().as_uri() + "?mode=ro", uri=True,
                                       check_same_thread=False)
        except sqlite3.Error:
            raise StoreError(f"{self.path}: cannot open the store read-only") from None
        try:
            # damaged text never raises: it decodes with U+FFFD and then fails its checksum
            self.con.text_factory = lambda b: b.decode("utf-8", "replace")
            self.con.execute("PRAGMA trusted_schema=OFF")
            self.con.execute("PRAGMA query_only=ON")
            self._check_schema()
            n, size = self.con.execute(
                "SELECT COUNT(*), SUM(LENGTH(name) + LENGTH(value)) FROM metadata").fetchone()
            if n > 256 or (size or 0) > _META_MAX_BYTES:
                raise self._foreign("its metadata table is far too large")
            rows = self.con.execute("SELECT name, value FROM metadata").fetchall()
        except _DB_ERRORS:
            self.con.close()
            raise StoreError(f"{self.path}: not a geoterrain store (or damaged); "
                             "re-run `geoterrain preprocess`") from None
        except StoreError:
            self.con.close()
            raise
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in rows):
            self.con.close()
            raise self._foreign("its metadata holds values that are not text")
        raw = dict(rows)
        if len(raw) != len(rows):
            self.con.close()
            raise self._foreign("its metadata names an entry twice")
        crc = raw.pop("metadata_crc32", None)
        if raw.get("complete") != "true":
            raise StoreError(
                f"{self.path}: incomplete store (interrupted write); re-run preprocess")
        try:
            ok = crc is not None and int(json.loads(crc)) == _meta_crc(raw)
            self.metadata = {k: json.loads(v) for k, v in raw.items()} if ok else {}
        except (ValueError, TypeError, RecursionError):
            ok = False
        if not ok:
            raise StoreCorruptError(f"{self.path}: metadata checksum mismatch: the file is "
                                    "damaged; re-run `geoterrain preprocess`")
        version = self.metadata.get("schema_version")
        if version != SCHEMA_VERSION:
            raise StoreError(f"{self.path}: store schema version {_show(version)}, this "
                             f"geoterrain reads version {SCHEMA_VERSION}; {REBUILD}")
        self.blob_reads = 0  # how many blobs were read (tests count them)

    def _foreign(self, why: str) -> StoreError:
        return StoreError(f"{self.path}: not a geoterrain store ({why}); refusing to read it")

    def _check_schema(self) -> None:
        """Exactly the four plain tables, as the writer declares them, nothing else."""
        seen = self.con.execute("SELECT type, name, tbl_name, sql FROM sqlite_master").fetchall()
        tables = set()
        for typ, name, _tbl, sql in seen:
            if typ == "table" and name in _TABLE_SQL and sql == _TABLE_SQL[name]:
                tables.add(name)
            elif typ == "table" and name in _TABLE_SQL:
                self._older_schema(seen)
                raise self._foreign(f"table {name} has other columns")
            else:
                raise self._foreign(f"it holds a {typ} {_show(name)}: views, triggers and "
                                    "other objects are refused")
        if tables != set(_TABLE_SQL):
            raise self._foreign(f"tables {', '.join(sorted(set(_TABLE_SQL) - tables))} missing")

    def _older_schema(self, seen: list) -> None:
        """A store of an older schema (version 1 or 2: three plain tables and their
        primary-key indexes, the metadata declared as then) says how to rebuild it,
        rather than "not a geoterrain store". Its schema_version is read only when the
        file holds nothing else, so no SQL of the file's can run."""
        plain = all(typ == "table" and name in ("metadata", "tiles", "blobs")
                    and str(sql).startswith(f"CREATE TABLE {name} (")
                    or typ == "index" and sql is None and name == f"sqlite_autoindex_{tbl}_1"
                    for typ, name, tbl, sql in seen)
        if not plain or ("table", "metadata", "metadata", _OLD_METADATA_SQL) not in seen:
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

    def _damaged(self, what: str) -> StoreCorruptError:
        return StoreCorruptError(f"{self.path}: checksum mismatch in {what}: the file is damaged; "
                                 "re-run `geoterrain preprocess`")

    def get_blob(self, key: tuple[int, int, int], kind: str) -> bytes | None:
        """A tile's blob, checksum-verified (bound to key and kind), or None when not stored."""
        try:
            row = self.con.execute(
                "SELECT b.data, b.crc32 FROM blob_keys k JOIN blobs b ON b.rowid = k.blob "
                "WHERE k.key = ?", (blob_key(key, kind),)).fetchone()
        except _DB_ERRORS:
            raise self._damaged(f"tile {key} {kind}") from None
        if row is None:
            return None
        self.blob_reads += 1
        data, crc = row
        if not isinstance(data, bytes) or blob_crc(key, kind, data) != crc:
            raise self._damaged(f"tile {key} {kind}")
        return data

    def tiles(self) -> dict[tuple[int, int, int], dict]:
        """Every stored tile's numbers, checksum-verified, checked against the key digests.

        Every tile must hold one blob of each kind, and no blob may lack its tile.
        """
        try:
            rows = self.con.execute(
                f"SELECT key, {', '.join(TILE_COLUMNS)}, crc32 FROM tiles").fetchall()
            packed = self.con.execute("SELECT key, blob FROM blob_keys").fetchall()
            # the rowid range only (a few pages): counting or joining the rows would
            # read every leaf page of the blobs, which hold the blob bytes
            lo, hi = self.con.execute("SELECT MIN(rowid), MAX(rowid) FROM blobs").fetchone()
        except _DB_ERRORS:
            raise self._damaged("the tile table") from None
        out = {}
        for r in rows:
            vals, crc = tuple(r[1:-1]), r[-1]
            if type(r[0]) is not int or r[0] < 0 or not all(
                    v is None or type(v) in (int, float) for v in vals) or type(vals[0]) is not int:
                raise self._damaged(f"tile {_show(r[0])} bounds")
            key = unpack_tile_key(r[0])
            if _row_crc(key, vals) != crc:
                raise self._damaged(f"tile {key} bounds")
            out[key] = dict(zip(TILE_COLUMNS, vals, strict=True))
        if level_digests(out) != self.metadata.get("tile_keys"):
            raise StoreCorruptError(f"{self.path}: the tile table does not match the recorded "
                                    "tile keys (rows missing or added): the file is damaged; "
                                    "re-run `geoterrain preprocess`")
        want = {r[0] << 3 | KIND_CODES[kind] for r in rows for kind in BLOB_KINDS}
        try:
            want |= {blob_key(k, EDGE_KIND) for k in self.edge_keys(out)}
        except ValueError:  # a key out of any grid's range
            raise self._damaged("the delta_edge list") from None
        if "block_delta_levels" in self.metadata and out:
            want.add(blob_key((max(k[0] for k in out), 0, 0), BLOCK_KIND))  # the root tile
        # the keys name distinct rows that fill the table's rowid range exactly, so
        # every row is named once (a missing row in the range reads as "missing"; a
        # row's checksum binds it to its key, so a pointer moved to another row fails)
        ids = {b for _, b in packed}
        if (len(packed) != len(want) or {k for k, _ in packed} != want
                or len(ids) != len(packed) or not all(type(b) is int for b in ids)
                or (packed and (lo, hi) != (min(ids), max(ids)))
                or (packed and hi - lo + 1 != len(ids)) or (not packed and lo is not None)):
            raise StoreCorruptError(f"{self.path}: the blobs do not match the tile table "
                                    "(blobs missing or added): the file is damaged; "
                                    "re-run `geoterrain preprocess`")
        return out

    def edge_keys(self, tiles: dict) -> dict[tuple[int, int, int], float]:
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
            rows = self.con.execute("SELECT k.key, LENGTH(b.data) FROM blob_keys k "
                                    "LEFT JOIN blobs b ON b.rowid = k.blob").fetchall()
        except _DB_ERRORS:
            raise self._damaged("the blob table") from None
        if any(n is None for _, n in rows):  # a key whose row is gone
            raise self._damaged("the blob table")
        out: dict[tuple[str, int], int] = {}
        try:
            for k, n in rows:
                (level, _, _), kind = unpack_blob_key(k)
                out[kind, level] = out.get((kind, level), 0) + n
        except (KeyError, TypeError, ValueError):
            raise self._damaged("the blob table") from None
        return out

    def close(self) -> None:
        self.con.close()


def _show(v: object) -> str:
    """A value from a store, printable: repr, no control characters, at most 40 chars."""
    r = "".join(c if c.isprintable() else "?" for c in repr(v))
    return r if len(r) <= 40 else r[:37] + "..."

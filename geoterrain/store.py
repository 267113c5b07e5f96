"""The store: one SQLite file, written atomically, every blob checksummed.

Schema (version :data:`SCHEMA_VERSION`), in the spirit of MBTiles/GeoPackage::

    metadata(name TEXT PRIMARY KEY, value TEXT)       -- JSON values
    tiles(level, x, y, nvalid, zmin, zmax, error, boundary_error,
          xmin, xmax, ymin, ymax, delta_max, radius_max, crc32)  -- per-tile numbers
    blobs(level, x, y, kind, data BLOB, crc32)         -- per-tile arrays

``kind`` is one of ``heights`` (residual-coded heights and valid mask),
``delta`` (per-vertex errors δ), ``radius`` (nested sphere radii) and
``normals`` (octahedral normal map). See docs/store.md.

A store is written to a hidden temporary file in the destination folder and
renamed into place only after the ``complete`` flag is committed, so an
interrupted write never leaves a file that opens as a valid store.
"""

from __future__ import annotations

import json
import os
import sqlite3
import struct
import zlib
from pathlib import Path

from geoterrain.exceptions import (
    StoreCorruptError,
    StoreError,
    UsageError,
    WriteError,
    exists_error,
)

SCHEMA_VERSION = 1
APPLICATION_ID = 0x47545252  # "GTRR" in the SQLite header: `file` can identify a store
TILE_COLUMNS = ("nvalid", "zmin", "zmax", "error", "boundary_error",
                "xmin", "xmax", "ymin", "ymax", "delta_max", "radius_max")

_SCHEMA = """
CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE tiles (
    level INTEGER NOT NULL, x INTEGER NOT NULL, y INTEGER NOT NULL,
    nvalid INTEGER NOT NULL, zmin REAL, zmax REAL, error REAL, boundary_error REAL,
    xmin REAL, xmax REAL, ymin REAL, ymax REAL, delta_max REAL, radius_max REAL,
    crc32 INTEGER NOT NULL,
    PRIMARY KEY (level, x, y));
CREATE TABLE blobs (
    level INTEGER NOT NULL, x INTEGER NOT NULL, y INTEGER NOT NULL, kind TEXT NOT NULL,
    data BLOB NOT NULL, crc32 INTEGER NOT NULL,
    PRIMARY KEY (level, x, y, kind));
"""


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
        self.tmp = parent / f".{self.dst.name}.partial-{os.getpid()}"
        self._meta: dict[str, str] = {}
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
        self.con.execute("PRAGMA journal_mode=OFF")
        self.con.execute("PRAGMA synchronous=OFF")
        self.con.execute(f"PRAGMA application_id={APPLICATION_ID}")
        self.con.executescript(_SCHEMA)
        self.con.execute("BEGIN")

    def _guard(self, fn, *args):
        try:
            return fn(*args)
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
        self._guard(self.con.execute, "INSERT INTO blobs VALUES (?,?,?,?,?,?)",
                    (*key, kind, data, zlib.crc32(data)))

    def put_blobs(self, kind: str, blobs: dict[tuple[int, int, int], bytes]) -> None:
        rows = ((*k, kind, d, zlib.crc32(d)) for k, d in blobs.items())
        self._guard(self.con.executemany, "INSERT INTO blobs VALUES (?,?,?,?,?,?)", rows)

    def put_tiles(self, rows: dict[tuple[int, int, int], tuple]) -> None:
        """Per-tile numbers, in the order of :data:`TILE_COLUMNS`."""
        data = ((*k, *v, _row_crc(k, v)) for k, v in rows.items())
        self._guard(self.con.executemany,
                    f"INSERT INTO tiles VALUES ({', '.join('?' * (len(TILE_COLUMNS) + 4))})", data)

    def commit(self) -> Path:
        """Finish: write metadata and the complete flag, fsync, rename into place."""
        meta = dict(self._meta)
        meta["schema_version"] = json.dumps(SCHEMA_VERSION)
        meta["complete"] = json.dumps(True)

        def _finish():
            self.con.executemany("INSERT INTO metadata VALUES (?,?)", meta.items())
            self.con.execute("INSERT INTO metadata VALUES (?,?)",
                             ("metadata_crc32", json.dumps(_meta_crc(meta))))
            self.con.execute("COMMIT")
            self.con.close()
            fd = os.open(self.tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(self.tmp, self.dst)
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
            rows = self.con.execute("SELECT name, value FROM metadata").fetchall()
        except sqlite3.DatabaseError:
            raise StoreError(f"{self.path}: not a geoterrain store (or damaged); "
                             "re-run `geoterrain preprocess`") from None
        raw = dict(rows)
        crc = raw.pop("metadata_crc32", None)
        if raw.get("complete") != "true":
            raise StoreError(
                f"{self.path}: incomplete store (interrupted write); re-run preprocess")
        if crc is None or int(json.loads(crc)) != _meta_crc(raw):
            raise StoreCorruptError(f"{self.path}: metadata checksum mismatch: the file is "
                                    "damaged; re-run `geoterrain preprocess`")
        self.metadata = {k: json.loads(v) for k, v in raw.items()}
        version = self.metadata.get("schema_version")
        if version != SCHEMA_VERSION:
            raise StoreError(f"{self.path}: schema version {version}, this geoterrain reads "
                             f"{SCHEMA_VERSION}; re-run `geoterrain preprocess`")
        self.blob_reads = 0  # how many blobs were read (tests count them)

    def _damaged(self, what: str) -> StoreCorruptError:
        return StoreCorruptError(f"{self.path}: checksum mismatch in {what}: the file is damaged; "
                                 "re-run `geoterrain preprocess`")

    def get_blob(self, key: tuple[int, int, int], kind: str) -> bytes | None:
        """A tile's blob, checksum-verified, or None when the tile is not stored."""
        try:
            row = self.con.execute(
                "SELECT data, crc32 FROM blobs WHERE level=? AND x=? AND y=? AND kind=?",
                (*key, kind)).fetchone()
        except sqlite3.DatabaseError:
            raise self._damaged(f"tile {key} {kind}") from None
        if row is None:
            return None
        self.blob_reads += 1
        data, crc = row
        if zlib.crc32(data) != crc:
            raise self._damaged(f"tile {key} {kind}")
        return data

    def tiles(self) -> dict[tuple[int, int, int], dict]:
        """Every stored tile's numbers, checksum-verified."""
        try:
            rows = self.con.execute(
                f"SELECT level, x, y, {', '.join(TILE_COLUMNS)}, crc32 FROM tiles").fetchall()
        except sqlite3.DatabaseError:
            raise self._damaged("the tile table") from None
        out = {}
        for r in rows:
            key, vals, crc = tuple(r[:3]), tuple(r[3:-1]), r[-1]
            if _row_crc(key, vals) != crc:
                raise self._damaged(f"tile {key} bounds")
            out[key] = dict(zip(TILE_COLUMNS, vals, strict=True))
        return out

    def blob_bytes_by_kind_level(self) -> dict[tuple[str, int], int]:
        rows = self.con.execute(
            "SELECT kind, level, SUM(LENGTH(data)) FROM blobs GROUP BY kind, level").fetchall()
        return {(k, lv): int(s) for k, lv, s in rows}

    def close(self) -> None:
        self.con.close()

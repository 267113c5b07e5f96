"""The store file's schema: one SQLite file of two plain tables, every row checksummed.

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

Here: the schema's versions and history, the tables' SQL (the writer declares them, the
reader compares them word for word), the page size rule, the blob checksum and how a
store file is recognised; the writer (:mod:`geoterrain.store.writer`) and the reader
(:mod:`geoterrain.store.reader`) both follow them. Checksums bind each blob to its
(level, x, y, kind) and each catalog row to its id.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from geoterrain.core.paths import STORE_SUFFIX

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
APPLICATION_ID = 0x47545252  # "GTRR" in the SQLite header: `file` can identify a store

# The only schema objects a store may hold: these two tables, their SQL word for word
# (a reader compares it), and no index, view or trigger. Each id is the rowid (an
# INTEGER PRIMARY KEY, so VACUUM keeps it: the catalog holds the blob ids).
TABLE_SQL = {
    "catalog": "CREATE TABLE catalog (id INTEGER PRIMARY KEY, data BLOB NOT NULL, "
               "crc32 INTEGER NOT NULL)",
    "blobs": "CREATE TABLE blobs (id INTEGER PRIMARY KEY, data BLOB NOT NULL, "
             "crc32 INTEGER NOT NULL)",
}


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


"""The store is complete and valid, or absent; damage gives a clear error."""

import os
import shutil
import signal
import sqlite3
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import StoreCorruptError, StoreError, UsageError, WriteError
from geoterrain.store.catalog import (
    META_ID,
    TILE_COLUMNS,
    TileTable,
    catalog_crc,
    pack_tiles,
    stored_numbers,
    unpack_tiles,
)
from geoterrain.store.keys import KIND_CODES, blob_key, tile_key, unpack_blob_key, unpack_tile_key
from geoterrain.store.reader import StoreReader
from geoterrain.store.writer import StoreWriter
from tests.store.storesql import (
    delete_blob,
    read_blob,
    read_table,
    update_blob,
    write_table,
)


@pytest.mark.fast
def test_incomplete_temp_file_is_never_a_valid_store(tmp_path):
    dst = tmp_path / "a.geoterrain"
    w = StoreWriter(dst)
    w.put_blob((0, 0, 0), "heights", b"abc")
    w.con.execute("COMMIT")  # as if killed after data but before commit()
    assert not dst.exists()
    with pytest.raises(StoreError, match="incomplete"):
        StoreReader(w.tmp)


@pytest.mark.fast
def test_the_writer_thread_writes_the_writer_s_bytes(tmp_path):
    """The same calls on a StoreThread (run on its own thread) and on a StoreWriter give
    the same file, byte for byte."""
    from geoterrain.store.writer import StoreThread

    rng = np.random.default_rng(5)
    blobs = {(0, x, y): rng.integers(0, 256, int(rng.integers(1, 3000)), np.uint8).tobytes()
             for x in range(9) for y in range(7)}
    rows = {(0, x, y): (3, 0.0, 1.0, 0.5, 0.25, 0.0, 1.0, 0.0, 1.0, 0.5, 0.5)
            for x in range(9) for y in range(7)}
    files = []
    for cls in (StoreWriter, StoreThread):
        dst = tmp_path / f"{cls.__name__}.geoterrain"
        with cls(dst) as w:
            w.put_blobs("heights", blobs)
            w.put_blobs("delta", {k: b[:5] for k, b in blobs.items()})
            w.put_tiles(rows)
            w.put_metadata({"grid": {"rows": 9, "cols": 9, "n": 3, "t": 2}})
            assert w.commit() == dst
        files.append(dst.read_bytes())
    assert files[0] == files[1]


@pytest.mark.fast
def test_a_failure_while_the_writer_thread_runs_leaves_nothing(tmp_path, fbm_tif, monkeypatch):
    """An error in the coding after the height blobs went to the store's thread stops it:
    no store, no partial file, no thread left."""
    import threading

    from geoterrain.preprocessing import levelblobs

    def boom(*a, **k):
        raise RuntimeError("coding failed")

    monkeypatch.setattr(levelblobs, "level_blobs", boom)
    dst = tmp_path / "s.geoterrain"
    with pytest.raises(RuntimeError, match="coding failed"):
        geoterrain.preprocess(fbm_tif, dst)
    assert not dst.exists()
    assert list(tmp_path.glob(".*partial*")) == []
    assert not [t for t in threading.enumerate() if t.name == "geoterrain-store"]


@pytest.mark.fast
def test_failure_mid_write_leaves_nothing(tmp_path, fbm_tif, monkeypatch):
    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(StoreWriter, "put_tiles", boom)
    dst = tmp_path / "s.geoterrain"
    with pytest.raises(OSError):
        geoterrain.preprocess(fbm_tif, dst)
    assert not dst.exists()
    assert list(tmp_path.glob(".*partial*")) == []


def test_kill_mid_write_leaves_no_valid_store(tmp_path):
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "big.tif", generate("fbm", 1025, seed=2))
    dst = tmp_path / "k.geoterrain"
    code = ("import geoterrain, geoterrain.store.writer as s, time\n"
            "orig = s.StoreWriter.put_blobs\n"
            "def slow(self, *a):\n    orig(self, *a); time.sleep(30)\n"
            "s.StoreWriter.put_blobs = slow\n"
            f"geoterrain.preprocess({str(src)!r}, {str(dst)!r})\n")
    p = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.time() + 120
    while time.time() < deadline and not list(tmp_path.glob(".*partial*")):
        time.sleep(0.2)
    time.sleep(1.0)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert not dst.exists()
    for f in tmp_path.glob(".*partial*"):  # a leftover temp file must not open as a store
        with pytest.raises(StoreError):
            StoreReader(f)


@pytest.mark.fast
def test_flipped_byte_in_blob_gives_clear_error(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    con = sqlite3.connect(dst)
    data, = read_blob(con, (0, 0, 0, "heights"))
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0x10
    update_blob(con, (0, 0, 0, "heights"), data=bytes(bad))
    con.commit()
    con.close()
    t = geoterrain.open(dst)
    with pytest.raises(StoreCorruptError, match="damaged"):
        t.tile(0, 0, 0)


@pytest.mark.fast
def test_flipped_byte_anywhere_never_gives_wrong_heights(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    good = geoterrain.open(dst).scene_xyz()[2]
    raw = bytearray(dst.read_bytes())
    rng = np.random.default_rng(0)
    for pos in rng.integers(100, len(raw), 25):
        bad = bytearray(raw)
        bad[pos] ^= 0xFF
        p = tmp_path / f"bad{pos}.geoterrain"
        p.write_bytes(bytes(bad))
        try:
            z = geoterrain.open(p).scene_xyz()[2]
        except StoreError:
            continue
        np.testing.assert_array_equal(z, good)  # either an error or the right heights


@pytest.mark.fast
def test_existing_destination_needs_overwrite(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with pytest.raises(UsageError, match="overwrite=True") as exc:
        geoterrain.preprocess(fbm_tif, dst)
    assert "--overwrite" in exc.value.cli  # the command line's words, for the CLI
    geoterrain.preprocess(fbm_tif, dst, overwrite=True)


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_read_only_directory(tmp_path, fbm_tif):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(WriteError):
        geoterrain.preprocess(fbm_tif, ro / "s.geoterrain")


@pytest.mark.fast
def test_not_a_store(tmp_path):
    p = tmp_path / "x.geoterrain"
    p.write_text("hello")
    with pytest.raises(StoreError, match="not a geoterrain store"):
        StoreReader(p)


@pytest.mark.fast
def test_missing_tile_is_a_clear_store_error(tmp_path, fbm_tif):
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with geoterrain.open(store) as t:
        with pytest.raises(StoreError, match="not stored"):
            t.tile(0, 999, 999)
        key = t.tile_keys(0)[0]
    con = sqlite3.connect(store)  # a blob row lost from a store that lists the tile
    delete_blob(con, (*key, "heights"))
    con.commit()
    con.close()
    # caught on open when the row was first or last of the blob table's rowid range,
    # else when the tile is read (storecheck checks the range, not every row)
    with pytest.raises(StoreCorruptError, match="missing"), geoterrain.open(store) as t:
        t.tile(*key)


@pytest.mark.fast
@settings(max_examples=300, deadline=None)
@given(level=st.integers(0, 31), x=st.integers(0, (1 << 26) - 1),
       y=st.integers(0, (1 << 26) - 1), kind=st.sampled_from(sorted(KIND_CODES)))
def test_packed_keys_round_trip_and_stay_small(level, x, y, kind):
    """A tile's and a blob's packed keys give back (level, x, y) and the kind; a level-L
    key of a pyramid whose top is N stays below 32 · 4^(N − L) (as a 2^(N−L)-tile side
    needs), so small stores have 1–3 byte keys."""
    k = tile_key((level, x, y))
    assert unpack_tile_key(k) == (level, x, y)
    assert unpack_blob_key(blob_key((level, x, y), kind)) == ((level, x, y), kind)
    side = max(x, y).bit_length()  # the smallest 2^b tiles a side holding x and y
    assert k < 32 << (2 * side)
    assert 0 <= blob_key((level, x, y), kind) < 1 << 62


@pytest.mark.fast
@pytest.mark.parametrize("bad", [(-1, 0, 0), (32, 0, 0), (0, 1 << 26, 0), (0, 0, -3)])
def test_keys_out_of_range_are_refused(bad):
    with pytest.raises(ValueError):
        tile_key(bad)


def _two_heights(t):
    return [i for i, k in enumerate(t.blobs.tolist())
            if unpack_blob_key(k)[1] == "heights" and unpack_blob_key(k)[0][0] == 0][:2]


@pytest.mark.fast
def test_blob_pointers_are_checked(tmp_path, fbm_tif):
    """Two keys naming one row are refused on open; two pointers swapped open (each
    names a row) but each swapped blob fails its checksum, bound to its key, on read."""
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with geoterrain.open(store) as t:
        want = t.tile(*t.tile_keys(0)[0]).heights.copy()
    shared, swapped = tmp_path / "shared.geoterrain", tmp_path / "swapped.geoterrain"
    shutil.copy(store, shared)
    shutil.copy(store, swapped)
    for path in (shared, swapped):
        with sqlite3.connect(path) as con:
            t = read_table(con)
            a, b = _two_heights(t)
            ids = t.ids.copy()
            ids[a], ids[b] = (ids[b], ids[b]) if path == shared else (ids[b], ids[a])
            write_table(con, TileTable(t.tiles, t.numbers, t.blobs, ids))
    with pytest.raises(StoreCorruptError, match="blobs do not match"):
        geoterrain.open(shared)
    for i in (a, b):
        with geoterrain.open(swapped) as s, pytest.raises(StoreCorruptError, match="checksum"):
            s.tile(*unpack_blob_key(int(t.blobs[i]))[0])
    with geoterrain.open(store) as t:  # the original still reads
        assert np.array_equal(t.tile(*t.tile_keys(0)[0]).heights, want, equal_nan=True)


@pytest.mark.fast
def test_a_vacuumed_store_reads_the_same(tmp_path, fbm_tif):
    """The tile table holds the blob rows' ids, so they are the table's INTEGER PRIMARY KEY
    (SQLite's VACUUM may renumber the rowids of a table without one): a vacuumed store
    reads every tile as before."""
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with geoterrain.open(store) as t:
        want = {k: t.tile(*k).heights.copy() for k in t.tile_keys()}
    con = sqlite3.connect(store)
    con.execute("VACUUM")
    con.close()
    with geoterrain.open(store) as t:
        for k, h in want.items():
            assert np.array_equal(t.tile(*k).heights, h, equal_nan=True)


_V2_SCHEMA = """
CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE tiles (level INTEGER NOT NULL, x INTEGER NOT NULL, y INTEGER NOT NULL,
    nvalid INTEGER NOT NULL, crc32 INTEGER NOT NULL, PRIMARY KEY (level, x, y));
CREATE TABLE blobs (level INTEGER NOT NULL, x INTEGER NOT NULL, y INTEGER NOT NULL,
    kind TEXT NOT NULL, data BLOB NOT NULL, crc32 INTEGER NOT NULL,
    PRIMARY KEY (level, x, y, kind));
"""


_V3_SCHEMA = """
CREATE TABLE metadata (name TEXT NOT NULL, value TEXT NOT NULL);
CREATE TABLE tiles (key INTEGER PRIMARY KEY, nvalid INTEGER NOT NULL, crc32 INTEGER NOT NULL);
CREATE TABLE blobs (id INTEGER PRIMARY KEY, data BLOB NOT NULL, crc32 INTEGER NOT NULL);
CREATE TABLE blob_keys (key INTEGER PRIMARY KEY, blob INTEGER NOT NULL);
"""


@pytest.mark.fast
@pytest.mark.parametrize("version,schema", [(2, _V2_SCHEMA), (3, _V3_SCHEMA)])
@pytest.mark.parametrize("extra", ["", "CREATE TRIGGER t AFTER INSERT ON tiles BEGIN "
                                       "SELECT 1; END;"])
def test_an_older_store_says_to_rebuild_it(tmp_path, version, schema, extra):
    """A store of a previous schema is told apart from a stranger's file: its version
    and the rebuild command, read only when the file holds nothing but the old tables."""
    p = tmp_path / "old.geoterrain"
    con = sqlite3.connect(p)
    con.executescript(schema + extra)
    con.execute("INSERT INTO metadata VALUES ('schema_version', ?)", (str(version),))
    con.commit()
    con.close()
    if extra:
        with pytest.raises(StoreError, match="not a geoterrain store"):
            StoreReader(p)
    else:
        with pytest.raises(StoreError,
                           match=f"schema version {version}.*preprocess DEM --overwrite"):
            StoreReader(p)


@pytest.mark.fast
def test_a_repeated_metadata_name_is_refused(tmp_path, fbm_tif):
    """The metadata is one JSON object: a name given twice (which JSON readers resolve
    by keeping either) is refused, at any depth, even with a valid checksum."""
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    for twice in ('{"schema_version": 4, "complete": true, "complete": true}',
                  '{"schema_version": 4, "complete": true, "grid": {"n": 1, "n": 2}}'):
        bad = tmp_path / "bad.geoterrain"
        shutil.copy(store, bad)
        data = zstandard.ZstdCompressor().compress(twice.encode())
        with sqlite3.connect(bad) as con:
            con.execute("UPDATE catalog SET data = ?, crc32 = ? WHERE id = ?",
                        (data, catalog_crc(META_ID, data), META_ID))
        with pytest.raises(StoreError, match="metadata cannot be read .it names an entry twice"):
            geoterrain.open(bad)


@pytest.mark.fast
def test_a_stray_catalog_row_is_refused(tmp_path, fbm_tif):
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with sqlite3.connect(store) as con:
        con.execute("INSERT INTO catalog VALUES (7, x'00', 0)")
    with pytest.raises(StoreError, match="rows of no meaning"):
        geoterrain.open(store)


_KEYS = st.lists(st.integers(0, (1 << 62) - 1), max_size=160, unique=True).map(sorted)


@pytest.mark.fast
@settings(max_examples=200, deadline=None)
@given(keys=_KEYS, seed=st.integers(0, 2**32 - 1), flat=st.booleans())
def test_the_tile_table_round_trips(keys, seed, flat):
    """pack_tiles / unpack_tiles give back every key, number (NaN and ±inf too) and
    id (a quarter of the keys name tiles, as every tile has 4 blobs)."""
    rng = np.random.default_rng(seed)
    tiles = sorted(rng.choice(keys, len(keys) // 4, replace=False).tolist()) if keys else []
    nums = (np.zeros((len(tiles), len(TILE_COLUMNS))) if flat
            else rng.normal(size=(len(tiles), len(TILE_COLUMNS))) * 1e3)
    if len(tiles) and not flat:
        nums[rng.integers(len(tiles)), rng.integers(1, len(TILE_COLUMNS))] = np.nan
        nums[rng.integers(len(tiles)), rng.integers(1, len(TILE_COLUMNS))] = -np.inf
    ids = rng.permutation(len(keys)).astype(np.int64) + 1
    t = TileTable(np.array(tiles, np.int64), nums, np.array(keys, np.int64), ids)
    u = unpack_tiles(pack_tiles(t))
    assert np.array_equal(u.tiles, t.tiles) and np.array_equal(u.blobs, t.blobs)
    assert np.array_equal(u.ids, t.ids)
    # every number back as it was, the boxes' rounded outward (stored_numbers); a column
    # with a NaN or an infinity exactly
    assert np.array_equal(u.numbers, stored_numbers(t.tiles, t.numbers), equal_nan=True)
    assert np.array_equal(unpack_tiles(pack_tiles(u)).numbers, u.numbers, equal_nan=True)


def _pyramid(rng, side: int, top: int, holes: float, scale: float, origin: float):
    """A tile table as a store's: level-0 tiles on a side × side grid (some missing),
    each coarser tile the union of its stored children (box, z range); the other
    numbers random."""
    from geoterrain.store.keys import tile_key

    cols = {c: j for j, c in enumerate(TILE_COLUMNS)}
    rows = {}
    for y in range(side):
        for x in range(side):
            if rng.random() < holes:
                continue
            # a curved grid: x and y move with both indices
            x0 = origin + scale * (64 * x + 0.3 * y * y + rng.normal() * 0.01)
            y0 = origin - scale * (64 * y + 0.2 * x * x + rng.normal() * 0.01)
            z = np.sort(rng.normal(size=2) * 100)
            rows[(0, x, y)] = dict(xmin=x0, xmax=x0 + 64 * scale, ymin=y0 - 64 * scale,
                                   ymax=y0, zmin=z[0], zmax=z[1])
    for L in range(1, top + 1):
        for (lv, x, y), r in list(rows.items()):
            if lv != L - 1:
                continue
            p = rows.setdefault((L, x >> 1, y >> 1), dict(r))
            for k in ("xmin", "ymin", "zmin"):
                p[k] = min(p[k], r[k])
            for k in ("xmax", "ymax", "zmax"):
                p[k] = max(p[k], r[k])
    keys = sorted(rows, key=tile_key)
    nums = rng.normal(size=(len(keys), len(TILE_COLUMNS))) * 50
    for i, k in enumerate(keys):
        for c, v in rows[k].items():
            nums[i, cols[c]] = v
    return np.array([tile_key(k) for k in keys], np.int64), nums


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), side=st.integers(1, 9), holes=st.floats(0, 0.5),
       scale=st.sampled_from([1e-3, 0.5, 1.0, 30.0, 2000.0]),
       origin=st.sampled_from([0.0, -1e4, 5.5e6, 3e7]))
def test_the_tile_table_predicts_parents_and_rounds_boxes_outward(seed, side, holes, scale,
                                                                   origin):
    """A store-like pyramid (every coarser tile its children's union) round-trips: the
    boxes rounded outward to BOX_STEP (each holds the original, less than a step larger,
    and rounding again changes nothing), every other number exactly; every tile with
    stored children has residual 0 in the z and box columns (what makes the table
    small: a prediction broken leaves them non-zero), and the box columns' level-0
    residuals stay small on a smoothly curved grid."""
    from geoterrain.store.catalog import BOX_STEP, _Tree, column_bytes

    rng = np.random.default_rng(seed)
    top = max(0, int(np.ceil(np.log2(side))))
    keys, nums = _pyramid(rng, side, top, holes, scale, origin)
    if not len(keys):
        return
    m = 4 * len(keys)
    t = TileTable(keys, nums, np.arange(m, dtype=np.int64), rng.permutation(m) + 1)
    u = unpack_tiles(pack_tiles(t))
    want = stored_numbers(keys, nums)
    assert np.array_equal(u.numbers, want) and np.array_equal(u.ids, t.ids)
    for j, c in enumerate(TILE_COLUMNS):
        lo, hi = nums[:, j], want[:, j]
        if c in ("xmin", "ymin"):
            assert (hi <= lo).all() and (lo - hi < BOX_STEP).all()
        elif c in ("xmax", "ymax"):
            assert (hi >= lo).all() and (hi - lo < BOX_STEP).all()
        else:
            assert np.array_equal(lo, hi)
    assert np.array_equal(stored_numbers(keys, want), want)
    tree = _Tree(keys)
    parents = np.zeros(len(keys), bool)
    parents[tree.kid_parent] = True
    for c in ("zmin", "zmax", "xmin", "xmax", "ymin", "ymax"):
        raw = column_bytes(tree, c, want[:, TILE_COLUMNS.index(c)])
        res = np.frombuffer(raw, np.uint8).reshape(8, -1).T.copy().view("<i8").ravel()
        assert (res[:len(keys)][parents] == 0).all(), c
        if c[0] in "xy" and holes == 0:  # level 0: LOCO-I's plane leaves the noise,
            # and the first row's and column's steps (a tile predicted from nothing would
            # be off by its coordinate / BOX_STEP)
            r = (res.view(np.uint64) >> np.uint64(1)).view(np.int64) ^ -(res & 1)
            assert (np.abs(r[1:]) <= (64 + side * side) * scale / BOX_STEP + 8).all(), c


@pytest.mark.fast
def test_the_writer_packs_its_staged_table_as_pack_tiles_does(tmp_path, fbm_tif):
    """The writer streams its tile table from its staging tables a column at a
    time; the row it writes is the one pack_tiles makes of the table read back, and no
    staging table is left in the store."""
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain", tile_size=16)
    r = StoreReader(store)
    t = r.table()
    assert len(t.tiles) > 1 and len(t.blobs) >= 4 * len(t.tiles)
    (row,) = r.con.execute("SELECT data FROM catalog WHERE id = 1").fetchone()
    assert row == pack_tiles(t)
    assert [n for (n,) in r.con.execute("SELECT name FROM sqlite_master")] == ["catalog",
                                                                               "blobs"]


@pytest.mark.fast
def test_the_staging_file_sits_beside_the_store_and_goes(tmp_path):
    """The tile table is staged in a file in the store's own folder (so a full disk is
    the store's disk), and neither it nor the partial store outlives commit or abort."""
    for finish in ("commit", "abort"):
        d = tmp_path / finish
        d.mkdir()
        w = StoreWriter(d / "a.geoterrain")
        w.put_blobs("heights", {(0, 0, 0): b"x"})
        w.put_tiles({(0, 0, 0): (1, *[0.0] * (len(TILE_COLUMNS) - 1))})
        names = sorted(p.name for p in d.iterdir())
        assert names == sorted([w.tmp.name, w.staging.name]), names
        assert w.staging.name == f".a.geoterrain.partial-{os.getpid()}.staging"
        getattr(w, finish)()
        left = sorted(p.name for p in d.iterdir())
        assert left == (["a.geoterrain"] if finish == "commit" else []), left


@pytest.mark.fast
def test_a_dropped_writer_leaves_nothing_and_a_dead_ones_files_are_removed(tmp_path):
    """A writer garbage-collected without commit or abort removes its partial store and
    staging file; those of a dead process are removed by the next writer there."""
    import gc

    w = StoreWriter(tmp_path / "a.geoterrain")
    w.put_blobs("heights", {(0, 0, 0): b"x"})
    del w
    gc.collect()
    assert list(tmp_path.iterdir()) == []
    dead = 999_999_999  # no such process
    for name in (f".a.geoterrain.partial-{dead}", f".a.geoterrain.partial-{dead}.staging"):
        (tmp_path / name).write_bytes(b"junk")
    StoreWriter(tmp_path / "b.geoterrain").abort()
    assert list(tmp_path.iterdir()) == []


def test_a_large_staged_table_reads_back_exactly(tmp_path):
    """More tiles and blobs than one fetch of the staging tables (65 536) and a table
    past 1 MiB (zstd level 3): every key, number (None as NaN; the boxes rounded outward,
    stored_numbers) and id reads back."""
    rng = np.random.default_rng(5)
    n = 70_000
    keys = [(0, int(x), int(y)) for x, y in rng.permutation(300 * 300)[:n, None]
            // np.array([1, 300]) % 300]
    nums = rng.normal(size=(n, len(TILE_COLUMNS))) * 1e4
    nums[:, 0] = rng.integers(0, 4226, n)
    nums[::7, 3] = np.nan
    rows = {k: (int(r[0]), *(None if v != v else float(v) for v in r[1:]))
            for k, r in zip(keys, nums.tolist(), strict=True)}
    with StoreWriter(tmp_path / "big.geoterrain") as w:
        for i in range(0, n, 9_999):  # in calls, as the preprocess puts a tile row
            part = keys[i:i + 9_999]
            w.put_tiles({k: rows[k] for k in part})
            for kind in ("heights", "delta", "radius", "normals"):
                w.put_blobs(kind, {k: bytes([i % 251]) for k in part})
        w.commit()
    r = StoreReader(tmp_path / "big.geoterrain")
    t = r.table()
    order = np.argsort([tile_key(k) for k in keys])
    assert np.array_equal(t.tiles, np.sort([tile_key(k) for k in keys]))
    assert np.array_equal(t.numbers, stored_numbers(t.tiles, nums[order]), equal_nan=True)
    assert np.array_equal(t.blobs, np.sort([blob_key(k, kind) for k in keys for kind in
                                            ("heights", "delta", "radius", "normals")]))
    assert sorted(t.ids.tolist()) == list(range(1, 4 * n + 1))
    for k in keys[:50]:
        assert r.get_blob(k, "heights") == bytes([keys.index(k) // 9_999 * 9_999 % 251])
    (row,) = r.con.execute("SELECT data FROM catalog WHERE id = 1").fetchone()
    assert row[0] == 1 and row == pack_tiles(t)
    assert r.metadata["tile_counts"] == {"0": n}


def _flat_table(n: int) -> TileTable:
    # n tiles of equal numbers, regular keys and ids: compresses far past RATIO_CAP
    return TileTable(np.arange(n, dtype=np.int64) * 32, np.zeros((n, len(TILE_COLUMNS))),
                     np.arange(4 * n, dtype=np.int64), np.arange(1, 4 * n + 1, dtype=np.int64))


def test_a_flat_table_past_the_ratio_cap_is_stored_raw(tmp_path, monkeypatch):
    """pack_tiles stores such a table raw, and it reads back; so does the writer, which
    streams its staging tables a second time for a raw row (forced here: a cap of 2)."""
    from geoterrain.store import catalog as storecatalog

    n = 20_000
    t = _flat_table(n)
    data = pack_tiles(t)
    assert data[0] == 0 and len(data) > 8 * n * (1 + len(TILE_COLUMNS))
    assert np.array_equal(unpack_tiles(data).blobs, t.blobs)
    monkeypatch.setattr(storecatalog, "RATIO_CAP", 2)
    with StoreWriter(tmp_path / "flat.geoterrain") as w:
        keys = [(0, x, y) for x in range(100) for y in range(200)]
        w.put_tiles({k: (0, *[1.0] * (len(TILE_COLUMNS) - 1)) for k in keys})
        for kind in ("heights", "delta", "radius", "normals"):
            w.put_blobs(kind, {k: b"" for k in keys})
        w.commit()
    r = StoreReader(tmp_path / "flat.geoterrain")
    (row,) = r.con.execute("SELECT data FROM catalog WHERE id = 1").fetchone()
    assert row[0] == 0 and row == pack_tiles(r.table())
    assert len(r.tiles()) == n


@pytest.mark.fast
def test_a_table_larger_than_its_file_could_hold_is_refused_before_decoding(tmp_path):
    """Every tile owns 4 blob rows and every blob row a few bytes of the file, so a
    head claiming more is refused before anything is decoded: a 0.4 MB file cannot
    make a reader build 800 000 tiles' objects (schema 4 as first written did, for
    about 1.1 GB)."""
    data = pack_tiles(_flat_table(50_000))
    with pytest.raises(ValueError, match="cannot be a store of this size"):
        unpack_tiles(data, file_bytes=400_000)
    assert len(unpack_tiles(data, file_bytes=1_200_000).tiles) == 50_000
    bad = struct.pack("<BII", 1, 10, 39) + data[9:]  # fewer than 4 blobs a tile (the
    #                                                    rest of the head kept)
    with pytest.raises(ValueError, match="cannot be a store"):
        unpack_tiles(bad)




@pytest.mark.fast
@pytest.mark.parametrize("tiles", [[5, 5], [7, 3], [-32, 0], [0, (1 << 63) - 1],
                                   [1 << 62, (1 << 62) + 1]])
def test_a_table_whose_keys_do_not_ascend_is_refused(tiles):
    """Repeated, descending, negative, wrapping (a difference that carries the sum past
    2^63) and out-of-range keys are refused."""
    t = TileTable(np.array(tiles, np.int64), np.zeros((2, len(TILE_COLUMNS))),
                  np.arange(8, dtype=np.int64), np.arange(1, 9, dtype=np.int64))
    with pytest.raises(ValueError, match="ascending"):
        unpack_tiles(pack_tiles(t))


@pytest.mark.fast
def test_a_table_claiming_more_than_its_bytes_allow_is_refused():
    """A head claiming 2^31 tiles over a few bytes of zstd is refused before any
    allocation (RATIO_CAP), as is a raw row shorter than its counts."""
    bomb = (struct.pack("<BIIBBI", 1, 1 << 29, 1 << 31, 4, 0, 0)
            + zstandard.ZstdCompressor().compress(b"x"))
    with pytest.raises(ValueError, match="too many"):
        unpack_tiles(bomb)
    with pytest.raises(ValueError, match="size"):
        unpack_tiles(struct.pack("<BIIBBI", 0, 10, 40, 2, 0, 0) + bytes(80))


@pytest.mark.fast
@pytest.mark.parametrize("head, words", [
    ((3, 0, 0), "unknown layout"),  # ids of 3 bytes
    ((2, 2, 0), "unknown layout"),  # a box coding of no meaning
    ((2, 0, 5), "unknown layout"),  # holes without the grid coding
    ((2, 1, 5), "level-0 grid does not match"),  # holes that are not the grid's
    ((2, 1, 1 << 30), "larger than its tiles allow"),
])
def test_a_table_of_an_unknown_layout_is_refused(head, words):
    """The head's id width, box coding and level-0 holes are checked, the holes against
    the tiles' own grid: a table claiming others is refused (a stranger's file cannot
    make the reader allocate a grid its tiles do not fill)."""
    keys = np.array([tile_key((0, x, y)) for y in range(3) for x in range(3)], np.int64)
    keys.sort()
    t = TileTable(keys, np.ones((9, len(TILE_COLUMNS))), np.arange(36, dtype=np.int64),
                  np.arange(1, 37, dtype=np.int64))
    data = pack_tiles(t)
    assert struct.unpack_from("<BBI", data, 9) == (2, 1, 0)  # a full 3 × 3 grid
    fmt, n, m = struct.unpack_from("<BII", data)
    raw = struct.pack("<BIIBBI", 0, n, m, *head)
    body = (np.diff(keys, prepend=0).astype("<i8").tobytes()
            + bytes(8 * n * len(TILE_COLUMNS) + 4 * 8 * head[2] * (head[1] == 1)
                    + (8 + head[0]) * m)) if head[2] < 1 << 20 else b""
    with pytest.raises(ValueError, match=words):
        unpack_tiles(raw + body)




def test_tile_keys_unpack_as_arrays_as_one_by_one():
    """``unpack_tile_keys`` (whole arrays) gives what ``unpack_tile_key`` gives per key."""
    from geoterrain.store.keys import tile_key, unpack_tile_key, unpack_tile_keys

    @settings(max_examples=50, deadline=None)
    @given(st.lists(st.tuples(st.integers(0, 31), st.integers(0, (1 << 26) - 1),
                              st.integers(0, (1 << 26) - 1)), max_size=20))
    def check(keys):
        k = [tile_key(key) for key in keys]
        L, x, y = unpack_tile_keys(np.array(k, np.int64))
        assert list(zip(L.tolist(), x.tolist(), y.tolist(), strict=True)) == \
            [unpack_tile_key(v) for v in k]

    check()
    with pytest.raises(ValueError):
        unpack_tile_keys(np.array([5, -1]))


@given(keys=st.lists(st.tuples(st.integers(0, 31), st.integers(0, 1 << 20),
                               st.integers(0, 1 << 20)), max_size=20, unique=True))
def test_the_writer_packs_keys_as_the_reader_and_fills_no_key_cache(tmp_path_factory, keys):
    """The writer's packed keys are tile_key's and blob_key's, and writing a store leaves
    tile_key's cache as it was (a 16385² store's 87 381 tiles kept 65 536 entries, about
    17.5 MB traced, through the whole write)."""
    from geoterrain.store.keys import blob_key, pack_blob_key, pack_tile_key, tile_key

    for k in keys:
        assert pack_tile_key(k) == tile_key(k)
        assert pack_blob_key(k, "normals") == blob_key(k, "normals")
    tile_key.cache_clear()
    dst = tmp_path_factory.mktemp("w") / "a.geoterrain"
    with StoreWriter(dst) as w:
        w.put_metadata({"note": "x"})
        w.put_blobs("delta", {k: b"d" for k in keys})
        w.put_tiles({k: (1, *[0.0] * (len(TILE_COLUMNS) - 1)) for k in keys})
        w.commit()
    assert tile_key.cache_info().currsize == 0

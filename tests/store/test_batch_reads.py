"""Blobs read in batches (``StoreReader.get_blobs``, ``Terrain.tiles``): the blobs, the
errors and the bytes counted are those of reading each alone."""

import shutil
import sqlite3

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core import osreads
from geoterrain.exceptions import StoreCorruptError
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.store import reader as reader_mod
from geoterrain.store.keys import BLOB_KINDS, blob_key
from geoterrain.store.reader import StoreReader
from tests.store.storesql import delete_blob, read_blob, update_blob

pytestmark = pytest.mark.fast


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch")
    return geoterrain.preprocess(write_geotiff(d / "f.tif", generate("fbm", 129, seed=5)),
                                 d / "f.geoterrain", tile_size=16)


@pytest.fixture(scope="module")
def keys(store):
    with geoterrain.open(store) as t:
        return t.tile_keys() + [(0, 99, 99)]


def _selects(con: sqlite3.Connection) -> list:
    seen: list = []
    con.set_trace_callback(lambda sql: seen.append(sql) if "FROM blobs" in sql else None)
    return seen


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(picks=st.lists(st.tuples(st.integers(0, 10 ** 6), st.sampled_from(BLOB_KINDS)),
                      max_size=40),
       batch=st.sampled_from([1, 3, 500]), version=st.booleans())
def test_a_batch_reads_what_single_reads_do(store, keys, monkeypatch, picks, batch, version):
    """Any keys (stored or not, repeated, of any kind), in chunks of any size: the blobs
    and the version of single reads, one query a chunk."""
    monkeypatch.setattr(reader_mod, "BATCH", batch)
    items = [(keys[i % len(keys)], kind) for i, kind in picks]
    r = StoreReader(store)
    try:
        want = [r.get_blob(*k) for k in items]
        seen = _selects(r.con)
        got, v = r.get_blobs(items, version)
        assert got == want
        assert v == (r.version() if version else -1)
        stored = {k for k, b in zip(items, want, strict=True) if b is not None}
        assert len(seen) == -(-len(stored) // batch)  # one query a chunk
    finally:
        r.close()


def _damaged(store, tmp_path, how):
    p = tmp_path / f"{how}.geoterrain"
    shutil.copy(store, p)
    with geoterrain.open(p) as t:
        key = t.tile_keys(0)[5]
    con = sqlite3.connect(p)
    if how == "flipped":
        data, = read_blob(con, (*key, "heights"))
        bad = bytearray(data)
        bad[len(bad) // 2] ^= 0x10
        update_blob(con, (*key, "heights"), data=bytes(bad))
    else:
        delete_blob(con, (*key, "heights"))
    con.commit()
    con.close()
    return p, key


@pytest.mark.parametrize("how", ["flipped", "missing"])
def test_a_damaged_blob_in_a_batch_gives_the_single_read_s_error(store, tmp_path, how):
    """A blob whose checksum fails (or whose row is gone), among good ones, is refused
    with the one-line error a read of it alone gives; the same through Terrain.tiles."""
    p, key = _damaged(store, tmp_path, how)
    try:
        r = StoreReader(p)
    except StoreCorruptError:
        pytest.skip("caught on open (the row was the first or last of the rowid range)")
    try:
        with pytest.raises(StoreCorruptError) as alone:
            r.get_blob(key, "heights")
        items = [((0, x, 0), "heights") for x in range(4)] + [(key, "heights")]
        with pytest.raises(StoreCorruptError) as batch:
            r.get_blobs(items)
        assert str(batch.value) == str(alone.value) and "\n" not in str(alone.value)
        assert ("missing" if how == "missing" else "checksum mismatch") in str(alone.value)
    finally:
        r.close()
    with geoterrain.open(p) as t:
        with pytest.raises(StoreCorruptError) as tiles:
            t.tiles(t.tile_keys(0)[:8])
        assert str(tiles.value) == str(alone.value)


@pytest.mark.skipif(not osreads.EXACT, reason="no per-thread I/O counters")
def test_a_batch_counts_what_the_process_read(store):
    """Around a batch (the reader's, and the terrain's with its decodes), the process's own
    count grows by ``bytes_read`` and the counters' looks, nothing else."""
    from tests.store.test_open_reads import _process_rchar

    with geoterrain.open(store) as warm:  # modules and kernels loaded
        warm.tiles(warm.tile_keys(0)[:3])
    t = geoterrain.open(store)
    try:
        items = [(k, kind) for k in t.tile_keys(0) for kind in ("heights", "delta")]
        for step in (lambda: t.reader.get_blobs(items, True), lambda: t.tiles(t.tile_keys(0))):
            b0, p0 = t.bytes_read, t.reader.meter.probes
            r0 = _process_rchar()
            step()
            r1 = _process_rchar()
            read, probes = t.bytes_read - b0, t.reader.meter.probes - p0
            assert read > 0 and r1[0] - r0[0] - r0[1] == read + probes
    finally:
        t.close()


def test_terrain_tiles_decode_what_tile_decodes_in_one_query(store):
    """Tiles and their ancestors not cached are read in one query, decoded as tile()
    decodes them, into the same cache; cached ones are not read again."""
    with geoterrain.open(store) as a, geoterrain.open(store) as b:
        keys = a.tile_keys(0)[3:20:2] + [a.tile_keys(1)[0]]
        one = [a.tile(*k) for k in keys]
        seen = _selects(b.reader.con)
        got = b.tiles(keys)
        assert len(seen) == 1 and b.decoded_tiles == a.decoded_tiles
        for x, y in zip(one, got, strict=True):
            assert x.key == y.key and np.array_equal(x.codes, y.codes)
            assert np.array_equal(x.heights, y.heights, equal_nan=True)
            assert np.array_equal(x.valid, y.valid)
            assert b.lookup(("h", *y.key)) is y
        b.tiles(keys)
        assert len(seen) == 1 and b.decoded_tiles == a.decoded_tiles


def test_a_commit_between_two_queries_is_seen_in_the_version(store, tmp_path, monkeypatch):
    """Another connection's commit between a batch's queries (outside a snapshot) gives
    the later version, so a terrain refuses the mixed batch as it refuses a single read
    an edit overtook."""
    from geoterrain.exceptions import StoreChangedError

    p = tmp_path / "c.geoterrain"
    shutil.copy(store, p)
    monkeypatch.setattr(reader_mod, "BATCH", 1)
    t = geoterrain.open(p)
    r = t.reader
    try:
        v0 = r.version()
        calls = []
        call = r.meter.call

        def commit_after_first(fn):
            out = call(fn)
            calls.append(1)
            if len(calls) == 1:  # another connection commits after the first query
                con = sqlite3.connect(p)
                con.execute("UPDATE blobs SET crc32 = crc32 + 1 WHERE rowid = ?", (other,))
                con.commit()
                con.close()
            return out

        keys = t.tile_keys(0)[:2]
        from geoterrain.store.keys import blob_key

        other = r._rowid_of(blob_key(keys[0], "normals"))  # a row no batch here reads
        r.meter.call = commit_after_first
        _, v = r.get_blobs([(k, "heights") for k in keys], True)
        assert len(calls) == 2 and v != v0
        calls.clear()
        with pytest.raises(StoreChangedError):
            t.tiles(keys)
    finally:
        t.close()


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(ahead=st.lists(st.tuples(st.integers(0, 10 ** 6), st.sampled_from(BLOB_KINDS)),
                      max_size=20),
       asked=st.lists(st.tuples(st.integers(0, 10 ** 6), st.sampled_from(BLOB_KINDS)),
                      max_size=20),
       version=st.booleans())
def test_blobs_read_ahead_are_those_single_reads_give(store, keys, ahead, asked, version):
    """Inside a snapshot, blobs read ahead (any keys, stored or not, repeated) are given
    as single reads give them, with the same version, without another query; each once
    (asked again, it is read again). Outside a snapshot nothing is read ahead."""
    pick = [(keys[i % len(keys)], kind) for i, kind in ahead]
    want_items = [(keys[i % len(keys)], kind) for i, kind in asked]
    r = StoreReader(store)
    try:
        want = [r.get_blob_version(*k, version) for k in want_items]
        seen = _selects(r.con)
        assert r.read_ahead(pick) == 0 and not seen  # no snapshot: nothing
        with r.snapshot():
            kept = r.read_ahead(pick)
            stored = {k for k in pick if r._rowid_of(blob_key(*k)) is not None}
            assert kept == len(stored) and len(seen) == (1 if stored else 0)
            got, taken = [], set()
            for k in want_items:
                n = len(seen)
                got.append(r.get_blob_version(*k, version))
                fresh = k in stored and k not in taken
                assert len(seen) == n + (0 if fresh or got[-1][0] is None else 1)
                taken.add(k)
        assert got == want
    finally:
        r.close()


def test_blobs_read_ahead_are_dropped_when_the_snapshot_ends(store, tmp_path):
    """A blob read ahead and not asked for is not kept past its snapshot: another
    connection's commit afterwards is read, not the blob read ahead."""
    p = tmp_path / "a.geoterrain"
    shutil.copy(store, p)
    r = StoreReader(p)
    try:
        key = (0, 1, 0)
        with r.snapshot():
            assert r.read_ahead([(key, "normals"), ((0, 2, 0), "normals")]) == 2
        con = sqlite3.connect(p)
        data, = read_blob(con, (*key, "normals"))
        update_blob(con, (*key, "normals"), data=data + b"\0")
        con.commit()
        con.close()
        with pytest.raises(StoreCorruptError):  # the new row (its checksum not updated)
            r.get_blob(key, "normals")
    finally:
        r.close()

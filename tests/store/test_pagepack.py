"""Blob rows are inserted in an order that fills SQLite's leaf pages (geoterrain.store.pagepack).

The cell sizes are checked against SQLite's own page statistics (the ``dbstat`` virtual
table, where the library has it), not against the module's arithmetic.
"""

import sqlite3

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain.store.writer as store
from geoterrain.store.pagepack import (
    LEAF_HEADER,
    blob_cell_sizes,
    leaf_cell_size,
    pack_order,
    varint_len,
)
from geoterrain.store.reader import StoreReader
from geoterrain.store.writer import StoreWriter
from tests.store.storesql import all_blobs


def _dbstat(path) -> dict:
    con = sqlite3.connect(path)
    try:
        rows = con.execute("SELECT name, pagetype, COUNT(*), SUM(pgsize), SUM(unused) "
                           "FROM dbstat GROUP BY name, pagetype").fetchall()
    except sqlite3.OperationalError:
        pytest.skip("this SQLite has no dbstat table")
    finally:
        con.close()
    return {(n, t): (c, size, unused) for n, t, c, size, unused in rows}


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(sizes=st.lists(st.integers(1, 1016), max_size=300), cap=st.sampled_from([1016, 4088]))
def test_packed_pages_hold_their_items_and_leave_no_room_for_a_later_page(sizes, cap):
    """Laid out in the order given, each item starting a page when it does not fit the
    current one: every page holds at most its capacity, and no page had room for the
    first item of a later page (what best-fit decreasing guarantees, and what
    appending in key order does not)."""
    sizes = [min(s, cap) for s in sizes]
    order = pack_order(sizes, cap)
    assert sorted(order) == list(range(len(sizes)))
    pages, used = [[]], 0
    for i in order:
        if used + sizes[i] > cap:
            pages.append([])
            used = 0
        pages[-1].append(sizes[i])
        used += sizes[i]
    pages = [p for p in pages if p]
    assert all(sum(p) <= cap for p in pages)
    for a in range(len(pages)):
        for b in range(a + 1, len(pages)):
            assert cap - sum(pages[a]) < pages[b][0], (a, b)


@pytest.mark.fast
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 400),
       small=st.floats(0.0, 1.0), pack_bytes=st.sampled_from([1 << 10, 1 << 16, 4 << 20]),
       page_size=st.sampled_from([store.SMALL_PAGE_SIZE, store.PAGE_SIZE]))
def test_a_store_s_blob_leaves_are_full_and_its_rows_unchanged(tmp_path_factory, seed, n,
                                                                small, pack_bytes, page_size):
    """Random blob rows (a few bytes to several pages) written through the store writer,
    in batches of 1 kB to 4 MB: they read back as written, SQLite's own count of the
    bytes on the leaves is ``leaf_cell_size``'s, and its leaves are the pages of
    appending those cells in rowid order (so :func:`pack_order`'s guarantee, tested
    above, holds in the file)."""
    tmp = tmp_path_factory.mktemp("pp")
    rng = np.random.default_rng(seed)
    lens = np.where(rng.random(n) < small, rng.integers(1, 200, n), rng.integers(1, 5000, n))
    blobs = {(int(i % 7), int(i // 7), 0): rng.bytes(int(m)) for i, m in enumerate(lens)}
    old = store.PACK_BYTES
    store.PACK_BYTES = pack_bytes
    try:
        w = StoreWriter(tmp / "s.gt", page_size=page_size)
        for k, d in blobs.items():
            w.put_blob(k, "heights", d)
        w.put_tiles({})
        dst = w.commit()
    finally:
        store.PACK_BYTES = old
    with sqlite3.connect(dst) as con:
        got = {k[:3]: d for k, d in all_blobs(con).items()}
    assert got == blobs
    _check_leaves(dst, one_batch=pack_bytes >= sum(map(len, blobs.values())))


def _check_leaves(dst, one_batch: bool) -> None:
    """SQLite's own count of the bytes on the blob leaves is ``leaf_cell_size``'s, its
    leaves are the pages of appending those cells in rowid order, and, for rows inserted
    in one batch, no leaf had room for the first cell of a later one (best-fit
    decreasing's guarantee, which appending in key order does not give)."""
    count, size, unused = _dbstat(dst)[("blobs", "leaf")]
    con = sqlite3.connect(dst)
    try:
        rows = con.execute("SELECT rowid, data, crc32 FROM blobs ORDER BY rowid").fetchall()
        (page,), = con.execute("PRAGMA page_size")  # the writer's: 512 or 1024 B
    finally:
        con.close()
    cells = [leaf_cell_size((None, *r[1:]), r[0], page) for r in rows]
    assert size - unused - count * LEAF_HEADER == sum(cells)
    cap = page - LEAF_HEADER
    pages: list[list[int]] = []
    for c in cells:  # SQLite appends: a cell that does not fit the last leaf starts one
        if not pages or sum(pages[-1]) + c > cap:
            pages.append([])
        pages[-1].append(c)
    assert count == len(pages)
    if one_batch:
        # the writer sizes a batch's cells at its largest rowid; a cell whose own rowid
        # has a shorter varint is that much smaller on the page, and SQLite may fit it
        # where the plan did not: each such byte is slack in the guarantee
        last = rows[-1][0] if rows else 0
        short = [varint_len(last) - varint_len(r[0]) for r in rows]
        slack, k = [], 0
        for pg in pages:
            slack.append(sum(short[k:k + len(pg)]))
            k += len(pg)
        first = np.cumsum([0] + [len(pg) for pg in pages])[:-1]
        for a in range(len(pages)):
            for b in range(a + 1, len(pages)):
                assert cap - sum(pages[a]) < pages[b][0] + slack[a] + short[first[b]], (a, b)


@pytest.mark.parametrize("tile_size", [16, 64])
def test_a_preprocessed_store_packs_its_leaves(tmp_path, fbm_tif, tile_size):
    """Both preprocess paths write packed leaves (one batch at these sizes)."""
    import geoterrain
    from geoterrain.preprocessing.streaming import preprocess_streaming

    a = geoterrain.preprocess(fbm_tif, tmp_path / "a.geoterrain", tile_size=tile_size)
    b = preprocess_streaming(fbm_tif, tmp_path / "b.geoterrain", tile_size=tile_size, band=16)
    for dst in (a, b):
        StoreReader(dst).tiles()  # a valid store
        _check_leaves(dst, one_batch=True)


@settings(max_examples=60, deadline=None)
@given(rows=st.lists(st.tuples(st.integers(0, 1 << 20), st.integers(0, (1 << 32) - 1)),
                     min_size=1, max_size=20),
       rowid=st.integers(1, 1 << 62), usable=st.sampled_from([512, 1024, 4096, 65536]))
def test_blob_cell_sizes_are_leaf_cell_sizes(rows, rowid, usable):
    """The writer's whole-array sizes of its blob rows equal the per-row rule."""
    n, c = zip(*rows, strict=True)
    want = [leaf_cell_size((None, bytes(k), crc), rowid, usable) for k, crc in rows]
    assert blob_cell_sizes(n, c, rowid, usable).tolist() == want

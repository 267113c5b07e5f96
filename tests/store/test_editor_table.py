"""The edit's transaction takes the terrain's parsed tile table only where the row it
reads inside its transaction is the one that reader parsed, packs it again with what that
row knows, and opens no reader of its own where the terrain's checked the store
(store/editor.py, store/catalog.py)."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import StoreError
from geoterrain.store import editor
from geoterrain.store.catalog import TILE_COLUMNS, TileTable, pack_tiles, unpack_tiles
from geoterrain.store.editor import StoreEditor
from geoterrain.store.reader import StoreReader
from tests.preprocessing.editcheck import integer_dem, write_dem
from tests.store.test_store import _pyramid


@pytest.mark.fast
def test_editor_takes_a_reader_s_table_only_while_the_row_is_the_one_it_parsed(tmp_path):
    store = geoterrain.preprocess(write_dem(tmp_path / "dem.tif", integer_dem(4, 33, 33)),
                                  tile_size=8)
    old = StoreReader(store)
    try:
        parsed = old.table()
        with StoreEditor(store, known=old) as ed:  # the same row: the parsed table
            assert ed.table is parsed
        with geoterrain.open(store) as t:  # another edit commits a new tile table
            t.edit((3, 4), np.full((20, 20), 2000.0))
        with StoreEditor(store, known=old) as ed:  # its row, unpacked
            assert ed.table is not parsed
            fresh = StoreReader(store)
            try:
                new = fresh.table()
            finally:
                fresh.close()
            assert not np.array_equal(np.asarray(new.numbers), np.asarray(parsed.numbers))
            assert np.array_equal(np.asarray(ed.table.numbers), np.asarray(new.numbers))
    finally:
        old.close()


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), side=st.integers(1, 9), holes=st.floats(0, 0.5),
       changed=st.integers(0, 6), boxes=st.booleans(), scale=st.sampled_from([1.0, 1e9]))
def test_a_table_packed_again_from_its_row_is_packed_as_from_nothing(seed, side, holes,
                                                                     changed, boxes, scale):
    """A table unpacked from a row, some tiles' numbers changed (their box columns too, or
    not), packs to the bytes of the same table packed from nothing: the tree and the box
    columns taken from the row (``TileTable.packed``) are the ones computed again, and a
    column that changed is computed again (boxes stored exactly past BOX_LIMIT too); a
    table of other tiles takes nothing from it."""
    rng = np.random.default_rng(seed)
    top = max(0, int(np.ceil(np.log2(side))))
    keys, nums = _pyramid(rng, side, top, holes, scale, 0.0)
    if not len(keys):
        return
    m = 4 * len(keys)
    u = unpack_tiles(pack_tiles(TileTable(keys, nums, np.arange(m, dtype=np.int64),
                                          rng.permutation(m) + 1)))
    assert u.packed is not None and u.packed.tree.keys is u.tiles
    new = u.numbers.copy()
    at = rng.integers(0, len(keys), changed)
    cols = [TILE_COLUMNS.index(c) for c in (("zmin", "xmin", "ymax") if boxes else
                                            ("zmin", "zmax", "error"))]
    new[np.ix_(at, cols)] += rng.normal(size=(len(at), len(cols)))
    for fast in (False, True):
        again = pack_tiles(TileTable(u.tiles, new, u.blobs, u.ids, u.packed), fast)
        assert again == pack_tiles(TileTable(u.tiles.copy(), new, u.blobs, u.ids), fast)
    if len(keys) > 1:  # other tiles: what the row knows does not apply
        fewer = (u.tiles[1:], new[1:], u.blobs, u.ids)
        assert pack_tiles(TileTable(*fewer, u.packed)) == pack_tiles(TileTable(*fewer))


@pytest.mark.fast
def test_an_edit_opens_no_reader_of_its_own_and_checks_the_schema_inside(tmp_path):
    """With the terrain's reader (``known``) and the metadata it read (``expect``), and
    nothing beside the store, the editor opens no reader of its own; a schema changed since
    that reader opened (a trigger added) is refused inside the transaction, nothing
    written; a journal beside the store sends it to a reader of its own, as before."""
    store = geoterrain.preprocess(write_dem(tmp_path / "dem.tif", integer_dem(4, 33, 33)),
                                  tile_size=8)
    opened = []

    def counting(*a, **k):  # the editor's own readers
        opened.append(a)
        return StoreReader(*a, **k)

    with geoterrain.open(store) as t, mock.patch.object(editor, "StoreReader", counting):
        t.edit((3, 4), np.full((20, 20), 2000.0))
        assert opened == []
    known = StoreReader(store)  # a terrain's reader, opened before the schema changed
    try:
        con = sqlite3.connect(store)
        con.execute("CREATE TRIGGER t AFTER UPDATE ON blobs BEGIN SELECT 1; END")
        con.commit()
        con.close()
        changed = store.read_bytes()
        with pytest.raises(StoreError, match="schema changed"):
            StoreEditor(store, expect=known.metadata, known=known)
        assert store.read_bytes() == changed
        assert opened == []
    finally:
        known.close()
    fresh = geoterrain.preprocess(write_dem(tmp_path / "b.tif", integer_dem(5, 33, 33)),
                                  tile_size=8)
    Path(f"{fresh}-journal").write_bytes(b"not SQLite's")
    with mock.patch.object(editor, "StoreReader", counting):
        opened.clear()
        with pytest.raises(StoreError, match="journal"):
            StoreEditor(fresh, expect={}, known=SimpleNamespace(path=fresh, table_stamp=None))
    assert opened  # a reader of its own refused the journal

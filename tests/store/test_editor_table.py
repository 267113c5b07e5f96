"""The edit's transaction takes the terrain's parsed tile table only where the row it
reads inside its transaction is the one that reader parsed (store/editor.py)."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain.store.editor import StoreEditor
from geoterrain.store.reader import StoreReader
from tests.preprocessing.editcheck import integer_dem, write_dem


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

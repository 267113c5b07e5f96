"""Tile and skirt errors of an edit by tiles from the old tile rows
(geoterrain.preprocessing.edit.localerrors, issue 52): where a block the edit does not
reach held a tile's old maximum, it is kept without reading the other blocks; where a
reached block held it and the edit lowers it, the next one is found. The oracle: a store
preprocessed from the edited DEM (tests/preprocessing/editcheck.py).
"""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain.preprocessing.edit import Patch, edit_terrain
from geoterrain.preprocessing.edit.localerrors import TileErrors
from tests.preprocessing.editcheck import apply_by_hand, assert_same_store, integer_dem, write_dem

TILE = 8  # 65² samples: levels 0-3, the block table covers every level


def _spiked() -> np.ndarray:
    """A rough integer DEM with three tall spikes: one inside a tile (the largest field of
    its tiles but the top's), one on the border line of row 32 (a skirt's largest,
    levels 0-2), and a taller one far from both (the store's largest δ, which an edit by
    tiles must keep)."""
    z = integer_dem(3, 65, 65)
    z[21, 27] += 400.0
    z[32, 43] += 300.0
    z[53, 11] += 900.0
    return z


def _edit(tmp, z, row, col, patch, mode, monkeypatch):
    """(the store edited by tiles, the store of the edited DEM, the edit's TileErrors)."""
    seen = []
    run = TileErrors.run

    def spy(self):
        run(self)
        seen.append(self)

    monkeypatch.setattr(TileErrors, "run", spy)
    (tmp / "a").mkdir(parents=True)
    (tmp / "b").mkdir()
    store = geoterrain.preprocess(write_dem(tmp / "a" / "dem.tif", z), tile_size=TILE)
    with geoterrain.open(store) as t:
        res = edit_terrain(t, Patch(row, col, patch), mode, how="tiles")
    assert res.how == "tiles"
    fresh = geoterrain.preprocess(write_dem(tmp / "b" / "dem.tif",
                                            apply_by_hand(z, row, col, patch, mode)),
                                  tile_size=TILE)
    return store, fresh, seen[-1]


@pytest.mark.fast
@pytest.mark.parametrize("at", [(21, 27), (32, 43)])
def test_an_edit_that_lowers_a_tile_s_largest_error(tmp_path, monkeypatch, at):
    """Flattening a spike that held its tiles' largest error (and a skirt's, on row 32):
    the old maximum was in a block the edit reaches, so the tiles' errors are found
    again from the blocks, and equal a preprocess's."""
    z = _spiked()
    i, j = at
    flat = np.array([[np.rint(0.25 * (z[i - 1, j] + z[i + 1, j] + z[i, j - 1] + z[i, j + 1]))]])
    a, b, errs = _edit(tmp_path, z, i, j, flat, "replace", monkeypatch)
    assert_same_store(a, b)
    assert errs.fallbacks > 0


@pytest.mark.fast
def test_an_edit_away_from_the_largest_error_keeps_it_from_the_rows(tmp_path, monkeypatch):
    """A small cut away from both spikes: the tiles whose largest error an unreached
    block holds keep it from their old rows (no other block read), and the store is a
    preprocess's."""
    z = _spiked()
    a, b, errs = _edit(tmp_path, z, 17, 30, np.full((3, 3), -2.0), "add", monkeypatch)
    assert_same_store(a, b)
    assert errs.shortcuts > 0


@pytest.mark.fast
@pytest.mark.parametrize("at", [(21, 27), (32, 43)])
def test_an_old_maximum_kept_where_it_dropped_is_seen(tmp_path, monkeypatch, at):
    """Mutation: the reached blocks' old fields taken as 0 (so the old maximum is always
    kept) leaves another store than a preprocess's when the edit lowers the spike that
    held it."""
    zero = (0.0, False, np.zeros((TILE + 1, TILE + 1)), np.zeros((TILE, TILE), bool))
    monkeypatch.setattr(TileErrors, "_old_field", lambda self, ty, tx, L: zero)
    z = _spiked()
    i, j = at
    flat = np.array([[np.rint(0.25 * (z[i - 1, j] + z[i + 1, j] + z[i, j - 1] + z[i, j + 1]))]])
    a, b, _ = _edit(tmp_path, z, i, j, flat, "replace", monkeypatch)
    with pytest.raises(AssertionError):
        assert_same_store(a, b)



def _fbm_store(tmp, z):
    (tmp / "a").mkdir(parents=True)
    return geoterrain.preprocess(write_dem(tmp / "a" / "dem.tif", z), tile_size=32)


# 513² fBm in whole metres, tiles of 32 samples (levels 0-4: blocks of up to 256 tiles);
# cuts and fills whose window holds a coarse vertex's largest old value, or raises it
FBM_EDITS = [(38, 80, 65, -40.0), (206, 319, 33, 40.0), (300, 120, 9, -40.0)]


def _fbm_z() -> np.ndarray:
    from geoterrain.ingest.synth import generate

    return np.rint(generate("fbm", 513, seed=2))


@pytest.mark.fast
@pytest.mark.parametrize("edit", FBM_EDITS)
def test_a_coarse_vertex_s_raw_code_from_the_window(tmp_path, monkeypatch, edit):
    """Direct coarse vertices whose raw δ code the edit's window alone gives (their
    stored code and the window's old and new values: localbounds.Bounds._raw_by_window)
    sweep no tile, and the edited store is a preprocess's."""
    from geoterrain.preprocessing.edit.localbounds import Bounds

    seen = []
    run = Bounds.run

    def spy(self):
        out = run(self)
        seen.append(self)
        return out

    monkeypatch.setattr(Bounds, "run", spy)
    row, col, w, dz = edit
    z = _fbm_z()
    store = _fbm_store(tmp_path, z)
    p = np.full((w, w), dz)
    with geoterrain.open(store) as t:
        assert edit_terrain(t, Patch(row, col, p), "add", how="tiles").how == "tiles"
    (tmp_path / "b").mkdir()
    fresh = geoterrain.preprocess(write_dem(tmp_path / "b" / "dem.tif",
                                            apply_by_hand(z, row, col, p, "add")), tile_size=32)
    assert_same_store(store, fresh)
    assert seen[-1].by_window > 0


@pytest.mark.fast
@pytest.mark.parametrize("edit", FBM_EDITS[:2])
def test_a_raw_code_kept_where_the_window_held_it_is_seen(tmp_path, monkeypatch, edit):
    """Mutation: the window's old values taken as 0 (so a coarse vertex's stored code
    always counts as held outside the window) leaves another store than a preprocess's
    where the window held a coarse vertex's largest value."""
    from geoterrain.preprocessing.edit.localbounds import Bounds

    rect = Bounds._rect_max
    monkeypatch.setattr(Bounds, "_rect_max",
                        lambda self, cell, zc, rc, r, new: rect(self, cell, zc, rc, r, new)
                        if new else 0.0)
    row, col, w, dz = edit
    z = _fbm_z()
    store = _fbm_store(tmp_path, z)
    p = np.full((w, w), dz)
    with geoterrain.open(store) as t:
        assert edit_terrain(t, Patch(row, col, p), "add", how="tiles").how == "tiles"
    (tmp_path / "b").mkdir()
    fresh = geoterrain.preprocess(write_dem(tmp_path / "b" / "dem.tif",
                                            apply_by_hand(z, row, col, p, "add")), tile_size=32)
    with pytest.raises(AssertionError):
        assert_same_store(store, fresh)

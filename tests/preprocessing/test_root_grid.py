"""The whole-grid preprocess on a rectangular root grid (issue 45, opt-in:
``preprocess(..., root_grid=True)``, ``--root-grid``): the store's tiles against the
raster, and the one-line refusals of what does not build one yet."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from conftest import write_tif
from geoterrain.core.grid import Grid
from geoterrain.exceptions import StoreError, UsageError
from geoterrain.ingest.synth import generate
from geoterrain.store.database import ROOTS_SCHEMA_VERSION, StoreReader

pytestmark = pytest.mark.fast


def fbm(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    z = generate("fbm", max(rows, cols), seed=seed)[:rows, :cols]
    return np.rint(500.0 * (z - z.min()) / max(float(np.ptp(z)), 1e-12))


def test_the_store_is_a_root_grid_with_every_data_tile(tmp_path):
    z = fbm(50, 121, seed=4).astype(np.int16)
    z[20:24, 30:41] = -9999
    src = write_tif(tmp_path / "w.tif", z, dtype="int16", nodata=-9999)
    store = geoterrain.preprocess(src, tmp_path / "w.geoterrain", tile_size=8, root_grid=True)
    r = StoreReader(store)
    m = r.metadata
    g = Grid(**m["grid"])
    assert m["schema_version"] == ROOTS_SCHEMA_VERSION
    assert (g.layout, g.roots, g.shape) == ("roots", (2, 1), (57, 121))
    valid = z != -9999
    want = set()
    for L in g.levels:  # brute force: tiles of the grid whose footprint holds data
        s = g.tile_span(L)
        tx, ty = g.tiles(L)
        for y in range(ty):
            for x in range(tx):
                if valid[y * s:(y + 1) * s + 1, x * s:(x + 1) * s + 1].any():
                    want.add((L, x, y))
    assert set(r.tiles()) == want
    assert all(r.get_blob(k, "heights") for k in want)
    r.close()
    with pytest.raises(StoreError, match="does not draw yet"):  # the reader comes next
        geoterrain.open(store)


def test_a_square_raster_keeps_the_square_store(tmp_path):
    src = write_tif(tmp_path / "s.tif", fbm(65, 65, seed=1), dtype="int16")
    a, b = (geoterrain.preprocess(src, tmp_path / f"{k}.geoterrain", tile_size=16,
                                  root_grid=k == "a") for k in "ab")
    assert a.read_bytes() == b.read_bytes()


def test_geographic_and_streamed_root_grids_are_refused_in_one_line(tmp_path):
    z = fbm(33, 65)
    src = write_tif(tmp_path / "g.tif", z, crs="EPSG:4326", origin=(10.0, 45.0),
                    spacing=0.001, dtype="int16")
    with pytest.raises(UsageError, match="projected and pixel frames only") as e:
        geoterrain.preprocess(src, tmp_path / "g.geoterrain", tile_size=16, root_grid=True)
    assert "\n" not in str(e.value)
    src = write_tif(tmp_path / "s.tif", fbm(1025, 2049), dtype="int16")
    with pytest.raises(UsageError, match="whole-grid preprocess only") as e:
        geoterrain.preprocess(src, tmp_path / "s.geoterrain", root_grid=True,
                              memory_limit=64 << 20)
    assert "\n" not in str(e.value)
    assert not (tmp_path / "s.geoterrain").exists()

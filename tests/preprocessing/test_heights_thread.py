"""The height codec on a thread of its own (levelblobs.HeightsJob), the normals and the tile
bounds on others, a level's bounds' blobs in two halves on two threads and the bounds' rows
handed to the store's writer level by level (tile_blobs' on_rows) write the same bytes as
all of it in line, each level in one piece and every row at the end."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.codec.pyramid import encode_pyramid
from geoterrain.codec.quantize import Quantizer
from geoterrain.core.grid import Grid, footprint_counts
from geoterrain.ingest.synth import generate
from geoterrain.preprocessing import levelblobs, pipeline
from geoterrain.preprocessing.levelblobs import pyramid_keys
from geoterrain.preprocessing.pipeline import preprocess
from tests.conftest import write_tif


@pytest.mark.fast
@given(rows=st.integers(3, 90), cols=st.integers(3, 90), tile=st.sampled_from([4, 8, 16]),
       roots=st.booleans(), holes=st.floats(0.0, 1.0), seed=st.integers(0, 2**16))
def test_pyramid_keys_are_the_codecs_tiles_in_its_order(rows, cols, tile, roots, holes, seed):
    """The tiles the bounds' loop takes before the heights are coded: those the codec
    stores, in the order it stores them (the tile table's rows follow it)."""
    rng = np.random.default_rng(seed)
    g = Grid.for_shape(rows, cols, tile, roots=roots)
    valid = g.pad(rng.random((rows, cols)) >= holes, False, whole=True)
    z = np.where(valid, rng.integers(-50, 50, valid.shape), 0).astype(np.float64)
    counts = footprint_counts(valid, g.t, g.top_level)
    blobs = g.held(encode_pyramid(z, valid, g.t, Quantizer("int"), roots=g.codec_roots,
                                  counts=counts))
    assert pyramid_keys(g, counts) == list(blobs)


def _sources(tmp_path):
    z = generate("fbm", 70, seed=4).astype(np.float32)[:, :61]
    holed = z.copy()
    holed[20:31, 5:40] = -9999.0
    return {
        "square": (write_tif(tmp_path / "s.tif", z), {}),
        "voids, padded": (write_tif(tmp_path / "v.tif", holed, nodata=-9999.0), {}),
        "geographic": (write_tif(tmp_path / "g.tif", z, crs="EPSG:4326",
                                 origin=(10.0, 61.0), spacing=0.01), {}),
        "root grid": (write_tif(tmp_path / "r.tif", z[:20]), {"root_grid": True}),
        "lossy": (write_tif(tmp_path / "e.tif", z), {"codec_error": 0.5}),
        "every normal and bound": (write_tif(tmp_path / "n.tif", holed, nodata=-9999.0),
                                   {"derive_normals": False, "derive_bounds": False}),
    }


@pytest.mark.fast
def test_the_heights_thread_writes_the_same_bytes(tmp_path, monkeypatch):
    """Every grid with its heights coded on their thread and its levels of two tiles or more
    in halves (the thresholds at 0 and 2) against the same coded in line and whole, and
    against the rows written at the end (write_rows as before the writer took them level
    by level)."""
    tb, wr = pipeline.tile_blobs, pipeline.write_rows
    for name, (src, kw) in _sources(tmp_path).items():
        monkeypatch.setattr(levelblobs, "HEIGHTS_THREAD_SAMPLES", 0)
        monkeypatch.setattr(levelblobs, "SPLIT_LEVEL_TILES", 2)
        a = preprocess(src, tmp_path / "a.gt", tile_size=8, overwrite=True, **kw)
        monkeypatch.setattr(levelblobs, "HEIGHTS_THREAD_SAMPLES", 1 << 62)
        b = preprocess(src, tmp_path / "b.gt", tile_size=8, overwrite=True, **kw)
        assert a.read_bytes() == b.read_bytes(), name
        with monkeypatch.context() as m:  # every row at the end, as before on_rows
            m.setattr(pipeline, "tile_blobs",
                      lambda *a_, on_rows=None, **k: tb(*a_, **k))
            m.setattr(pipeline, "write_rows",
                      lambda *a_, rows=True, **k: wr(*a_, **k))
            c = preprocess(src, tmp_path / "c.gt", tile_size=8, overwrite=True, **kw)
        assert a.read_bytes() == c.read_bytes(), name


@pytest.mark.fast
@pytest.mark.parametrize(("module", "where"), [(levelblobs, "encode_pyramid"),
                                               (pipeline, "_normal_maps"),
                                               (pipeline, "_tile_bounds")])
def test_a_failure_on_a_thread_is_raised_and_writes_nothing(tmp_path, monkeypatch, module,
                                                            where):
    """The height codec's thread, the normals' and the tile bounds' (HeightsJob, Job)."""
    src = _sources(tmp_path)["square"][0]

    def broken(*args, **kwargs):
        raise MemoryError("no room for the heights")

    monkeypatch.setattr(levelblobs, "HEIGHTS_THREAD_SAMPLES", 0)
    monkeypatch.setattr(module, where, broken)
    with pytest.raises(MemoryError, match="no room"):
        preprocess(src, tmp_path / "a.gt", tile_size=8)
    assert not (tmp_path / "a.gt").exists()
    assert [p.name for p in tmp_path.iterdir() if p.suffix != ".tif"] == []

"""δ read in row bands (geoterrain.banddelta) against the whole-grid kernel.

The oracle is :func:`geoterrain.bounds.vertex_errors` on the whole grid in memory; the
banded values must be the same float32 bits for every band size, with the per-level
arrays in memory or in scratch files. That equality is what makes a streaming
preprocess give the same store whatever its block size.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.banddelta import band_vertex_errors, rows_of
from geoterrain.bounds import vertex_errors
from geoterrain.scratch import ScratchArrays
from tests.conftest import real_dem


def _grid(seed: int, n: int, holes: str) -> tuple[np.ndarray, np.ndarray]:
    N = (1 << n) + 1
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 5, (N, N)).cumsum(0).cumsum(1) / 4 + rng.normal(0, 2, (N, N))
    if seed % 3 == 0:
        z = np.round(z)  # ties on the planes, flat runs
    v = np.ones((N, N), bool)
    if holes == "sparse":
        v = rng.random((N, N)) > 0.03
    elif holes == "dense":
        v = rng.random((N, N)) > 0.4
    elif holes == "blocks":  # a void straddling band rows and coarse blocks
        i, j = rng.integers(0, N, 2)
        v[max(i - N // 3, 0):i + N // 4, max(j - N // 5, 0):j + N // 3] = False
    elif holes == "nan":  # valid but not finite: treated as invalid
        z[rng.random((N, N)) < 0.05] = np.nan
    return z, v


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7),
       holes=st.sampled_from(["none", "sparse", "dense", "blocks", "nan"]),
       band=st.sampled_from([2, 4, 8, 16, 64, 256]), on_disk=st.booleans())
def test_banded_delta_is_the_whole_grid_delta(tmp_path_factory, seed, n, holes, band, on_disk):
    """Same bits as vertex_errors for every band (fine levels in a band, coarse levels
    across bands, the band's top row carried, mixed diamonds swept in pieces)."""
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    ref = vertex_errors(z, v)
    folder = tmp_path_factory.mktemp("sa") if on_disk else None
    with ScratchArrays(folder) as sa:
        d = band_vertex_errors(rows_of(z, v), N, band=band, scratch=sa).grid()
    bad = np.argwhere(d != ref)
    assert not len(bad), (len(bad), bad[:4].tolist(), d[tuple(bad[0])], ref[tuple(bad[0])])


@pytest.mark.parametrize("band", [2, 16, 128])
def test_banded_delta_on_a_real_dem(band):
    """A real DEM's window (integer metres, ties and flats) gives the same bits."""
    import rasterio
    from rasterio.windows import Window

    path = real_dem("srtm1_japan.tif")
    with rasterio.open(path) as ds:
        N = min(ds.height, ds.width, 513)
        N = (1 << (N - 1).bit_length() - 1) + 1
        z = ds.read(1, window=Window(0, 0, N, N)).astype(np.float64)
        nd = ds.nodata
    v = np.isfinite(z) if nd is None else z != nd
    ref = vertex_errors(z, v)
    assert np.array_equal(band_vertex_errors(rows_of(z, v), N, band=band).grid(), ref)


def test_banded_delta_reads_rows_a_band_at_a_time():
    """No read is wider than the band's window (1.5·band + 1 rows)."""
    z, v = _grid(5, 7, "sparse")
    N = z.shape[0]
    spans = []

    def rows(i0, i1):
        spans.append(i1 - i0)
        return z[i0:i1], v[i0:i1]

    d = band_vertex_errors(rows, N, band=16)
    assert max(spans) <= 16 * 3 // 2 + 1
    assert np.array_equal(d.grid(), vertex_errors(z, v))


def test_banded_delta_refuses_bad_arguments():
    z, v = _grid(1, 4, "none")
    with pytest.raises(ValueError, match="power of two"):
        band_vertex_errors(rows_of(z, v), 17, band=6)
    with pytest.raises(ValueError, match="2\\*\\*n"):
        band_vertex_errors(rows_of(z, v), 16, band=4)
    with pytest.raises(ValueError, match="rows"):
        band_vertex_errors(lambda i0, i1: (z[i0:i1, :5], v[i0:i1, :5]), 17, band=4)


def test_scratch_arrays_round_trip_and_clean_up(tmp_path):
    with ScratchArrays(tmp_path) as sa:
        sa.create("a", (5, 3), np.float32)
        sa.write("a", 2, np.arange(6, dtype=np.float32).reshape(2, 3))
        assert sa.read("a", -1, 9).tolist() == [[0, 0, 0], [0, 0, 0], [0, 1, 2], [3, 4, 5],
                                                [0, 0, 0]]
        assert sa.read("a", 3, 3).shape == (0, 3)
        with pytest.raises(ValueError):
            sa.write("a", 4, np.zeros((2, 3), np.float32))
        assert len(os.listdir(tmp_path)) == 1
    assert os.listdir(tmp_path) == []

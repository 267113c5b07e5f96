"""quantise() shares the heights as the scene heights where decoding gives them back
unchanged (the bit-exact float quantizer, heights in metres, no exaggeration): the same
bits as decoding them, and the heights never written."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.codec.pyramid import decoded_heights
from geoterrain.preprocessing.request import request
from geoterrain.preprocessing.surface import pad, quantise, read_dem
from tests.conftest import write_tif


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, np.float64).view(np.uint64)


def _surface(path, tmp, z_scale, z_units, codec_error=None):
    req = request(str(path), str(tmp / "o.geoterrain"), tile_size=8, codec_error=codec_error,
                  pixel_size=None, overwrite=True, scheduler="sync", resume=False)
    dem = read_dem(req, band=None, encoding="auto", nodata=None, tile=None, pixel_size=None,
                   z_units=z_units, z_scale=z_scale)
    return dem, pad(dem)


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(rows=st.integers(2, 20), cols=st.integers(2, 20), seed=st.integers(0, 2**16),
       dtype=st.sampled_from(["float32", "float64", "int16"]),
       voids=st.booleans(), z=st.sampled_from([(None, "m"), (2.0, "m"), (None, "ft")]),
       lossy=st.booleans())
def test_the_scene_heights_are_the_decoded_heights_and_the_heights_stay(
        tmp_path_factory, rows, cols, seed, dtype, voids, z, lossy):
    tmp = tmp_path_factory.mktemp("q")
    rng = np.random.default_rng(seed)
    h = rng.normal(0.0, 300.0, (rows, cols))
    if dtype == "int16":
        h = np.round(h)
    h.flat[rng.integers(0, h.size)] = -0.0
    if voids:
        h[rng.random(h.shape) < 0.2] = np.nan
        h.flat[0] = 1.5  # at least one valid sample
    path = write_tif(tmp / "d.tif", h if dtype != "int16" else np.nan_to_num(h, nan=-32768),
                     dtype=dtype, nodata=-32768 if dtype == "int16" else None)
    dem, s = _surface(path, tmp, *z, codec_error=0.5 if lossy else None)
    before = s.heights.copy()
    out = quantise(dem, s, 0.5 if lossy else None)
    assert np.array_equal(_bits(out.heights), _bits(before))  # never written
    if out.q.bins == 1:  # the pyramid's own decoding otherwise (tested with the codec)
        ref = dem.frame.z(decoded_heights(before, s.valid, out.q))
        assert np.array_equal(_bits(out.Z)[s.valid], _bits(ref)[s.valid])
    assert np.isnan(out.Z[~s.valid]).all()
    factor = dem.frame.z_to_m * dem.frame.z_scale
    assert (out.Z is out.heights) == (out.q.mode == "float" and factor == 1.0)


@pytest.mark.fast
def test_a_float32_dem_in_metres_shares_its_heights(tmp_path):
    h = np.random.default_rng(3).normal(0.0, 300.0, (17, 17)).astype(np.float32)
    dem, s = _surface(write_tif(tmp_path / "d.tif", h), tmp_path, None, "m")
    out = quantise(dem, s, None)
    assert out.q.mode == "float" and out.q.float_bits == 32 and out.Z is out.heights

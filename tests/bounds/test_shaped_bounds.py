"""Schema 6's CENTRES bounds payloads (vertexdata.shape_codes) decode to the codes."""

from __future__ import annotations

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.log8codes import log8_table, new_mask
from geoterrain.bounds.vertexdata import CENTRES, decode_bounds, pack_bounds_v2, shape_codes

pytestmark = pytest.mark.fast


@settings(max_examples=60, deadline=None)
@given(t=st.integers(1, 5), seed=st.integers(0, 2**31), leaves_zero=st.booleans(),
       px=st.integers(0, 1), py=st.integers(0, 1), e=st.integers(-20, 20))
def test_centres_blobs_decode_to_their_codes(t, seed, leaves_zero, px, py, e):
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    codes = rng.integers(0, 256, (T, T)).astype(np.uint8)
    off = new_mask(T)
    off[1::2, 1::2] = False  # the new vertices that are not cell centres
    if leaves_zero:
        codes[off] = 0
    elif rng.random() < 0.5:  # one leaf not zero: stored whole
        codes[off] = 0
        codes[tuple(np.argwhere(off)[rng.integers(off.sum())])] = 1
    table = log8_table(e)
    parent = table[rng.integers(0, 256, (T, T))]
    h = (T - 1) // 2  # the vertices shared with the parent: the same codes (PRED reads them)
    parent[py * h: py * h + h + 1, px * h: px * h + h + 1] = table[codes[::2, ::2]]
    blob = pack_bounds_v2(codes, e, True, True, zstandard.ZstdCompressor(level=3))
    assert bool(blob[1] & CENTRES) == leaves_zero
    out = decode_bounds(blob, (T, T), parent, (px, py))
    new = new_mask(T)
    np.testing.assert_array_equal(out[new], table[codes[new]])
    # the parent's vertices from the parent, as before
    np.testing.assert_array_equal(out[::2, ::2],
                                  parent[py * h: py * h + h + 1, px * h: px * h + h + 1])


def test_centres_store_a_quarter_of_the_new_vertices():
    T = 17
    codes = np.zeros((T, T), np.uint8)
    codes[1::2, 1::2] = np.arange(64).reshape(8, 8)
    rows, flags = shape_codes(codes[new_mask(T)][None])
    assert flags.tolist() == [CENTRES] and rows[0].tolist() == list(range(64))


def test_a_centres_flag_on_a_ring_blob_is_refused():
    codes = np.zeros((9, 9), np.uint8)
    blob = bytearray(pack_bounds_v2(codes, 0, True, True, zstandard.ZstdCompressor()))
    blob[1] |= 4  # RING
    with pytest.raises(ValueError, match="centres"):
        decode_bounds(bytes(blob), (9, 9), np.zeros((9, 9), np.float32), (0, 0),
                      derive=lambda *a: np.zeros((9, 9), np.float32))

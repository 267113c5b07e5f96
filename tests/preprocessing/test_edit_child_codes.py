"""An edit's decoded codes of a tile it codes again (``local.child_codes``): the codes it
coded where every sample is valid and the tile's even samples are its parent's, the blob
decoded otherwise, and always what :func:`decode_tile_valid` gives."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.codec.pyramid import decode_tile_valid, encode_child
from geoterrain.preprocessing.edit.local import child_codes

pytestmark = pytest.mark.fast


@settings(max_examples=200, deadline=None)
@given(te=st.integers(1, 5), seed=st.integers(0, 2**32 - 1), wide=st.booleans(),
       cubic=st.booleans(), px=st.integers(0, 1), py=st.integers(0, 1),
       how=st.sampled_from(["kept", "kept", "corner", "invalid", "none valid"]))
def test_child_codes_are_the_decoded_codes(te, seed, wide, cubic, px, py, how):
    """Lossless blobs (range-coded and a float store's wide ones, linear and cubic) of
    random tiles: the codes themselves (no decode) where the shortcut holds; a tile one
    of whose even samples is not its parent's, or with an invalid sample, decoded."""
    rng = np.random.default_rng(seed)
    T, h = (1 << te) + 1, 1 << (te - 1)
    top = 1 << 40 if wide else 4000
    codes = rng.integers(-top, top, (T, T))
    ok = np.ones((T, T), bool)
    parent = rng.integers(-top, top, (T, T))
    parent[py * h:py * h + h + 1, px * h:px * h + h + 1] = codes[::2, ::2]
    if how == "corner":  # an even sample the parent does not hold
        i, j = rng.integers(0, h + 1, 2)
        codes[2 * i, 2 * j] += 1
    elif how == "invalid":
        ok[tuple(rng.integers(0, T, 2))] = False
    elif how == "none valid":
        ok[:] = False
    blob = encode_child(codes, ok, parent, (px, py), te, cubic, 1, wide)
    want = decode_tile_valid(blob, parent, (px, py), te, 1)[0]
    got = child_codes(blob, codes, ok, parent, (px, py), te, 1)
    np.testing.assert_array_equal(got, want)
    assert (got is codes) == (how == "kept")

"""An edit's codes of stored values (``localblobs._codes``): the binary search's."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.log8codes import log8_table
from geoterrain.preprocessing.edit.localblobs import _codes

pytestmark = pytest.mark.fast


@settings(max_examples=300, deadline=None)
@given(e=st.integers(-128, 127), seed=st.integers(0, 2**32 - 1), n=st.integers(0, 300),
       how=st.sampled_from(["entries", "between", "any", "specials"]))
def test_codes_are_the_first_entry_at_or_above(e, seed, n, how):
    """Table entries (the values an edit reads back), values between them, any float64,
    and 0, ±inf, NaN and negatives among them: the codes ``np.searchsorted`` gives, for
    every code exponent a store takes (log8_exponent's −128 … 127: subnormal entries at
    the low end, an infinite code 254 at the high end)."""
    table = log8_table(e).astype(np.float64)
    rng = np.random.default_rng(seed)
    c = rng.integers(0, 256, n)
    if how == "entries":
        v = table[c]
    elif how == "between":
        v = np.nextafter(table[c], np.where(rng.random(n) < 0.5, 0.0, np.inf))
    elif how == "any":
        v = np.exp2(rng.uniform(e - 4, e + 20, n))
    else:
        v = table[c]
        v[rng.random(n) < 0.2] = rng.choice([0.0, -0.0, np.inf, -np.inf, np.nan, -1.0])
    want = np.searchsorted(table, v).astype(np.uint8)
    assert np.array_equal(_codes(table, v), want)
    assert np.array_equal(_codes(table, v.astype(np.float32).reshape(-1, 1))[:, 0],
                          np.searchsorted(table, v.astype(np.float32).astype(np.float64))
                          .astype(np.uint8))

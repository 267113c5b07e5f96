"""radii.numpy_range: numpy's min and max of the valid samples, bit for bit (a store
records its height range, ±0.0 included), without copying them where one zero sign occurs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.bounds.radii import numpy_range, zero_signs


@pytest.mark.fast
@given(rows=st.integers(1, 12), cols=st.integers(1, 12), seed=st.integers(0, 2**16),
       zeros=st.sampled_from(["+", "-", "both", "none"]), lift=st.sampled_from([0.0, 1.0, -1.0]))
def test_numpy_range_is_numpys_bit_for_bit(rows, cols, seed, zeros, lift):
    rng = np.random.default_rng(seed)
    z = rng.integers(0, 4, (rows, cols)).astype(np.float64) * lift  # ends at a zero often
    z[rng.random((rows, cols)) < 0.3] = {"+": 0.0, "-": -0.0, "both": 0.0, "none": 2.0}[zeros]
    if zeros == "both":
        z[rng.random((rows, cols)) < 0.3] = -0.0
    if zeros != "both":  # one sign only: the other one's zeros turned
        z[z == 0.0] = -0.0 if zeros == "-" else 0.0
    valid = rng.random((rows, cols)) < 0.8
    valid.flat[0] = True
    z[~valid] = np.nan
    lo, hi = numpy_range(z, valid)
    want = z[valid]
    for got, ref in ((lo, want.min()), (hi, want.max())):
        assert got == ref and np.signbit(got) == np.signbit(ref)
    pos, neg = zero_signs(z, valid)
    assert (pos, neg) == (int(np.sum((want == 0) & ~np.signbit(want))),
                          int(np.sum((want == 0) & np.signbit(want))))

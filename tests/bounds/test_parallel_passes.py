"""Whole-grid passes run on every core against their one-thread forms, bit for bit: δ's
saturation by pulls (delta._saturate_pull_nb) against the reference's pushes, fine to
coarse, with strided slices (testing.reference.saturate); the valid range's rows
(radii._valid_range_nb)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import _saturate_pull_nb, saturate
from geoterrain.testing.reference import saturate as reference_saturate

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 6), roots=st.sampled_from([(1, 1), (2, 1), (1, 2), (3, 2)]),
       seed=st.integers(0, 2**32 - 1), inf=st.floats(0.0, 0.05), zeros=st.floats(0.0, 0.5))
def test_pulled_saturation_is_the_pushed_one(n, roots, seed, inf, zeros):
    span = 1 << n
    rx, ry = roots
    rng = np.random.default_rng(seed)
    d = rng.exponential(1.0, (ry * span + 1, rx * span + 1)).astype(np.float32)
    d[rng.random(d.shape) < zeros] = 0.0
    d[rng.random(d.shape) < inf] = np.inf
    want = reference_saturate(d.copy(), span)
    got = _saturate_pull_nb.parallel(d.copy(), span)
    assert got.tobytes() == want.tobytes()
    assert _saturate_pull_nb.serial(d.copy(), span).tobytes() == want.tobytes()
    assert saturate(d.copy(), span).tobytes() == want.tobytes()  # what callers call


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), p=st.floats(0.0, 1.0), zeros=st.booleans(),
       rows=st.integers(1, 40))
def test_the_valid_range_by_rows_is_the_one_pass_range(seed, p, zeros, rows):
    from geoterrain.bounds.radii import _valid_range_nb

    rng = np.random.default_rng(seed)
    z = rng.normal(0, 10, (rows, 37))
    if zeros:  # signed zeros: the same one kept
        z = np.where(rng.random(z.shape) < 0.5, 0.0, -0.0) * rng.integers(0, 2, z.shape)
    z[rng.random(z.shape) < 0.05] = np.nan
    valid = rng.random(z.shape) < p
    want = _valid_range_nb.serial(z, valid)
    got = _valid_range_nb.parallel(z, valid)
    assert np.array([got[0], got[1]]).tobytes() == np.array([want[0], want[1]]).tobytes()
    assert got[2] == want[2] == int((valid & np.isfinite(z)).sum())
    flat = z[valid & np.isfinite(z)]  # the one-pass rule: the first of equal values
    if flat.size:
        first = flat[np.flatnonzero(flat == flat.min())[0]]
        assert np.array(want[0]).tobytes() == np.array(first).tobytes()

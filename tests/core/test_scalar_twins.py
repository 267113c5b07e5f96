"""The edit's Python code calls the bintree's and the rounding's scalar helpers as Python
(``.py_func``: no numba cache load per process, docs/lab/editing.md); they must return
what the compiled helpers return."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core.bintree import child_nb, main_diagonal_nb
from geoterrain.core.rounding import round_up, round_up32
from geoterrain.preprocessing.edit.localbounds import _child, _main_diagonal, _round_up32

EDGES = [0.0, 0.1, 0.5, 1.0, 1.0 + 2.0**-30, 2.0**-149, 2.0**-140 + 2.0**-160, 3.4e38,
         np.nextafter(2.0, 0.0), np.nextafter(2.0, 4.0), 1e-45, 1e-300, float(np.inf)]


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.floats(0.0, 3.4e38, allow_nan=False),
                 st.sampled_from(EDGES),
                 st.integers(-149, 127).map(lambda e: 2.0**e)))
def test_round_up32_twin_equals_the_compiled(a):
    got = _round_up32(a)
    want = round_up32(a)
    assert type(got) is type(want) is float
    assert got == want or (np.isnan(got) and np.isnan(want))
    assert got == float(round_up(np.array([a]))[0])
    assert got >= a


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 12), st.integers(0, 4096), st.integers(0, 4096), st.integers(0, 3))
def test_bintree_twins_equal_the_compiled(e, i, j, k):
    h = 1 << e  # any integers: the twins must agree wherever the compiled ones are called
    assert _child(i, j, h, k) == child_nb(i, j, h, k)
    assert _main_diagonal(i, j) == main_diagonal_nb(i, j)
    assert _main_diagonal(-i, j) == main_diagonal_nb(-i, j)

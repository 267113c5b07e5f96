"""The view ranges' set iteration (:func:`geoterrain.globe.ranges.settle`): whatever the
ranges do to the sets, the ranges kept draw no node outside the set they were made over."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.globe.ranges import settle

pytestmark = pytest.mark.fast


@given(st.integers(1, 10), st.integers(0, 2 ** 32 - 1))
def test_the_kept_ranges_draw_only_nodes_of_their_own_set(n, seed):
    """Random maps from a set's ranges to the nodes they draw (always within the first set:
    the view's visible nodes), cycles included: the set kept holds every node its ranges
    draw, and the ranges are the ones made over it."""
    rng = np.random.default_rng(seed)
    vis = rng.random(n) < 0.8
    table = {}

    def ranges_of(A):  # "ranges": any value fixed by the set
        return A.tobytes()

    def drawn(key):
        if key not in table:
            table[key] = vis & (rng.random(n) < rng.random())
        return table[key]

    out, A = settle(ranges_of, drawn, vis.copy())
    assert out == ranges_of(A)
    assert not (drawn(out) & ~A).any()


def test_a_two_set_cycle_keeps_the_set_that_holds_what_it_draws():
    """Two sets that draw each other in turn (a flight's frame 0.7–1.9 Mm up did: 6 and 8
    measured nodes, 64 sets before): the iteration stops at the cycle and keeps the larger,
    whose ranges draw the smaller; the smaller's ranges draw nodes outside it."""
    every = np.ones(5, bool)
    small, large = every.copy(), every.copy()
    small[2:] = False
    large[3:] = False
    calls = []

    def ranges_of(A):
        calls.append(int(A.sum()))
        return int(A.sum())

    nxt = {5: small, 2: large, 3: small}
    out, A = settle(ranges_of, lambda k: nxt[k], every)
    assert out == 3 and np.array_equal(A, large)
    assert calls == [5, 2, 3]

"""encode_gaps_rows: a level's range-coded δ payloads in one compiled call, byte for byte
each payload coded alone (a reference kernel compiled here from the coder's parts, as
encode_gaps was before it took the rows' kernel), rows past the batch's byte-a-value slot
included."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds import gapcoder
from geoterrain.bounds.gapcoder import GapDecoder, encode_gaps, encode_gaps_rows
from geoterrain.codec.entropy import _finish, _start

pytestmark = pytest.mark.fast


@numba.njit(cache=False)
def _one(r, gap, buf):  # one payload alone: the coder's state from start to finish
    m = np.zeros((gapcoder._GAP_ROWS, 2), np.int64)
    S = _start(True, buf)
    S = gapcoder._gap_values(np.bool_(True), S, buf, m, r, gap)
    return _finish(S, buf)


def _alone(r: np.ndarray, gap: np.ndarray) -> bytes:
    r = np.array(r, np.int64)
    buf = np.zeros(16 * len(r) + 64, np.uint8)
    return buf[:_one(r, np.ascontiguousarray(gap, np.int64), buf)].tobytes()


@settings(max_examples=60, deadline=None)
@given(k=st.integers(0, 6), n=st.integers(0, 300), seed=st.integers(0, 2**31),
       kind=st.sampled_from(["zeros", "sparse", "uniform", "mixed"]))
def test_rows_are_each_payload_coded_alone(k, n, seed, kind):
    rng = np.random.default_rng(seed)
    r = rng.integers(0, 256, (k, n))
    if kind == "zeros":
        r[:] = 0
    elif kind == "sparse":
        r[rng.random((k, n)) < 0.9] = 0
    elif kind == "mixed" and k:  # some rows cheap, some dear
        r[::2] = 0
    gap = rng.integers(0, 300, (k, n))
    before = r.copy()
    got = encode_gaps_rows(r, gap)
    assert got == [_alone(r[i], gap[i]) for i in range(k)]
    assert got == [encode_gaps(r[i], gap[i]) for i in range(k)]
    np.testing.assert_array_equal(r, before)  # the caller's values untouched
    for i in range(k):
        d = GapDecoder(got[i])
        assert d.take(gap[i]).tolist() == r[i].tolist()
        d.check()


@settings(max_examples=30, deadline=None)
@given(slot=st.integers(0, 60), seed=st.integers(0, 2**31))
def test_rows_past_the_slot_are_coded_again(slot, seed):
    """A row longer than the batch's slot (the coder stops writing at its end and says
    so) is coded again with the worst case's room: the same bytes as one that fits."""
    rng = np.random.default_rng(seed)
    r = rng.integers(0, 256, (4, 100))
    r[1] = 0  # a short row beside the long ones
    gap = rng.integers(0, 300, (4, 100))
    got = encode_gaps_rows(r, gap, slot=slot)
    assert got == [_alone(r[i], gap[i]) for i in range(4)]
    assert max(map(len, got)) > slot  # the retry ran


def test_one_kernel_one_signature():
    """One payload and a level's run the same kernel, compiled once."""
    encode_gaps_rows(np.zeros((2, 5), np.int64), np.zeros((2, 5), np.int64))
    encode_gaps(np.zeros(5, np.int64), np.zeros(5, np.int64))
    assert len(gapcoder._encode_gaps_rows.signatures) == 1, gapcoder._encode_gaps_rows.signatures
    assert not hasattr(gapcoder, "_encode_gaps")

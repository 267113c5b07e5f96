"""Schema 20's δ guessed from the tile's heights (ownguess.own_codes): ``PRED`` payloads
range-coded in the contexts of their vertices' gaps between the parents' bound and the own
errors' codes (``PRED`` with ``SLACK``), level-0 ``RING`` δ as differences from the own
errors' codes, range-coded (``RING`` with ``PRED``). Exact whatever the guess; small where
the guess is right; the writer's guess and the reader's equal bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.gapcoder import GapDecoder, encode_gaps
from geoterrain.bounds.log8codes import (
    _pred_centres,
    _pred_index,
    log8_codes,
    log8_exponent,
    log8_table,
    pred_residuals,
    ring_new_index,
)
from geoterrain.bounds.ownguess import (
    guess_check,
    new_codes_same,
    own_codes,
    pred_codes_own,
    pred_gaps,
    pred_payload_same,
    pred_payloads_own,
    ring_codes_own,
    ring_payloads_own,
)
from geoterrain.bounds.tileblobs import BoundsCoding, OwnHeights, level_blobs
from geoterrain.bounds.vertexdata import PRED, RING, SLACK, decode_bounds
from geoterrain.core import zstdsafe
from tests.bounds.test_guessed_bounds import _heights

pytestmark = pytest.mark.fast


@settings(max_examples=60, deadline=None)
@given(t=st.integers(1, 5), seed=st.integers(0, 2**31), k=st.integers(1, 4),
       guess=st.sampled_from(["random", "codes", "perturbed"]))
def test_coded_payloads_invert_whatever_the_guess(t, seed, k, guess):
    """The contexts are what the decoder has already decoded and the guess: exact on any
    codes and any guess (a wrong guess costs bytes only)."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    W = rng.integers(0, 256, (k, T, T)).astype(np.uint8)
    if guess == "random":
        lo = rng.integers(0, 256, (k, T, T)).astype(np.uint8)
    else:
        lo = W.copy()
        if guess == "perturbed":
            lo = (lo.astype(np.int64) + rng.integers(-3, 4, lo.shape)).clip(0, 255).astype(np.uint8)
    P = pred_payloads_own(W, lo)
    assert len(P) == k and all(isinstance(p, bytes) for p in P)
    # the values coded are the raster-order payload's (centres, then the others)
    np.testing.assert_array_equal(pred_gaps(W, lo)[0], pred_residuals(W))
    for n in range(k):
        np.testing.assert_array_equal(pred_codes_own(W[n, ::2, ::2], P[n], lo[n]), W[n])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(0, 300), parts=st.integers(1, 3))
def test_gap_payloads_decode_in_parts_and_strangers_bytes_stay_bounded(seed, n, parts):
    """Any values 0 … 255 in any contexts round-trip, decoded in parts; any bytes decode
    to values 0 … 255 (a stranger's payload never reads past its end or loops)."""
    rng = np.random.default_rng(seed)
    r = rng.integers(0, 256, n) * (rng.random(n) < 0.5)
    gap = rng.integers(-300, 300, n)
    d = GapDecoder(encode_gaps(r, gap))
    cuts = np.sort(rng.integers(0, n + 1, parts - 1))
    got = np.concatenate([d.take(g) for g in np.split(gap, cuts)])
    np.testing.assert_array_equal(got, r)
    d.check()  # the encoder's stream: every byte read
    padded = GapDecoder(encode_gaps(r, gap) + b"\x07" * 8)  # a spliced or padded payload
    padded.take(gap)
    with pytest.raises(ValueError, match="not the encoder's stream"):
        padded.check()
    junk = GapDecoder(rng.integers(0, 256, rng.integers(0, 40)).astype(np.uint8).tobytes())
    v = junk.take(gap)
    assert v.shape == (n,) and ((v >= 0) & (v <= 255)).all()


def test_a_reader_with_another_guess_decodes_other_codes():
    """Writer and reader must agree on the guess: a reader whose own-error codes differ
    (here one tile's guess flipped) decodes other codes or refuses the payload, so the
    store tests that compare decoded δ with the whole grid's would see a disagreement."""
    rng = np.random.default_rng(3)
    T = 17
    W = rng.integers(0, 200, (1, T, T)).astype(np.uint8)
    lo = rng.integers(0, 200, (1, T, T)).astype(np.uint8)
    P = pred_payloads_own(W, lo)
    other = (255 - lo[0]).astype(np.uint8)
    try:
        got = pred_codes_own(W[0, ::2, ::2], P[0], other)
    except ValueError as exc:  # its check byte, or the stream is not the encoder's
        assert "other heights" in str(exc) or "not the encoder's stream" in str(exc)
    else:
        assert not np.array_equal(got, W[0])


def _own_windows(z, v, stand_in, t, L, xy, e):
    # the reader's guess of each tile: its own (T, T) heights, as Terrain reads them
    T, s = (1 << t) + 1, 1 << L
    out = []
    for x, y in xy:
        win = np.s_[(y << (t + L)):(y << (t + L)) + (T - 1) * s + 1:s,
                    (x << (t + L)):(x << (t + L)) + (T - 1) * s + 1:s]
        out.append(own_codes(z[win], v[win], stand_in, e)[0])
    return np.array(out)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(3, 6), t=st.integers(2, 3), seed=st.integers(0, 2**31),
       relief=st.sampled_from([0.1, 10.0, 1000.0]), holes=st.sampled_from([0.0, 0.1]))
def test_own_errors_bound_delta_below_and_the_writer_guesses_as_the_reader(n, t, seed,
                                                                             relief, holes):
    """On fBm-like DEMs with holes: (1) a vertex's stored δ code is never below its own
    errors' code where the samples it reads are valid (the gap is the payload's order
    key, ≥ 0 where the bound holds); (2) the guess cut from the whole grid (the writers',
    ``OwnHeights``, any level) equals each tile's own from its own samples (the
    reader's), bit for bit; (3) the level's PRED blobs decode to the codes."""
    rng = np.random.default_rng(seed)
    N = (1 << n) + 1
    z, v = _heights(rng, (N, N), relief, holes)
    d = vertex_errors(np.where(v, z, 0.0), v)
    e = log8_exponent(d)
    dc = log8_codes(d, e)
    stand_in = float(np.nanmean(z)) if v.any() else 0.0
    T = (1 << t) + 1
    coding = BoundsCoding(d.astype(np.float32), None, e, r_codes=(np.zeros((N, N), np.uint8), 0))
    for L in range(0, n - t):
        m = 1 << (n - t - L)
        xy = [(x, y) for y in range(m) for x in range(m)]
        origins = np.array([(y << (t + L), x << (t + L)) for x, y in xy])
        writer = own_codes(z, v, stand_in, e, origins, T, 1 << L)
        reader = _own_windows(z, v, stand_in, t, L, xy, e)
        np.testing.assert_array_equal(writer, reader)
        s = 1 << L
        for k, (x, y) in enumerate(xy):
            W = dc[(y << (t + L)):(y << (t + L)) + (T - 1) * s + 1:s,
                   (x << (t + L)):(x << (t + L)) + (T - 1) * s + 1:s]
            vv = v[(y << (t + L)):(y << (t + L)) + (T - 1) * s + 1:s,
                   (x << (t + L)):(x << (t + L)) + (T - 1) * s + 1:s]
            # the lower bound where the vertex, its split edge's ends (and a centre's
            # cell) are valid
            ok = np.zeros((T, T), bool)
            ok[1::2, 0::2] = vv[1::2, 0::2] & vv[0:-1:2, 0::2] & vv[2::2, 0::2]
            ok[0::2, 1::2] = vv[0::2, 1::2] & vv[0::2, 0:-1:2] & vv[0::2, 2::2]
            cell = (vv[0:-1:2, 0:-1:2] & vv[0:-1:2, 2::2] & vv[2::2, 0:-1:2] & vv[2::2, 2::2]
                    & vv[1::2, 0:-1:2] & vv[1::2, 2::2] & vv[0:-1:2, 1::2] & vv[2::2, 1::2])
            ok[1::2, 1::2] = vv[1::2, 1::2] & cell
            assert (W[ok] >= writer[k][ok]).all()
        if L == n - t - 1 or L == 0:
            continue
        blobs, _, _ = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), t, L, n - t, xy,
                                  ("delta",), own=OwnHeights(z, v, stand_in))
        for k, (x, y) in enumerate(xy):
            blob = blobs["delta"][(L, x, y)]
            if not blob[1] & PRED:  # a CENTRES shape: no guess
                continue
            assert blob[1] & SLACK
            W = dc[(y << (t + L)):(y << (t + L)) + (T - 1) * s + 1:s,
                   (x << (t + L)):(x << (t + L)) + (T - 1) * s + 1:s]
            parent = np.zeros((T, T), np.float32)
            h = (T - 1) // 2
            parent[(y & 1) * h:(y & 1) * h + h + 1,
                   (x & 1) * h:(x & 1) * h + h + 1] = log8_table(e)[W[::2, ::2]]
            got = decode_bounds(blob, (T, T), parent, (x % 2, y % 2),
                                own=lambda ee, g=reader[k]: g)
            np.testing.assert_array_equal(log8_codes(got, e), W)


def test_coded_payloads_are_smaller_on_a_real_delta():
    """On a DEM's saturated δ, the PRED differences range-coded in the contexts of their
    own-error gaps take fewer bytes than the same differences at zstd 11 (schema 14's
    payloads as written)."""
    from geoterrain.ingest.synth import generate

    N, t = 257, 5
    z = generate("fbm", N, seed=3) * 300
    ok = np.ones((N, N), bool)
    d = vertex_errors(z, ok)
    e = log8_exponent(d)
    dc = log8_codes(d, e)
    T, span = (1 << t) + 1, 1 << (t + 1)
    xy = [(x, y) for y in range((N - 1) // span) for x in range((N - 1) // span)]
    W = np.array([dc[y * span:y * span + span + 1:2, x * span:x * span + span + 1:2]
                  for x, y in xy])
    lo = own_codes(z, None, 0.0, e, np.array([(y * span, x * span) for x, y in xy]), T, 2)

    plain = sum(len(zstdsafe.compress_one(r.tobytes(), 11)) for r in pred_residuals(W))
    coded = sum(len(p) for p in pred_payloads_own(W, lo))
    assert coded < 0.95 * plain, (coded, plain)
    # the gap is ≥ 0 everywhere (the own errors bound δ below, the parents above)
    other, n1, n2, main = _pred_index(T)
    assert (_pred_centres(W.astype(np.int16), main) >= lo[:, 1::2, 1::2]).all()


@settings(max_examples=30, deadline=None)
@given(t=st.integers(1, 4), seed=st.integers(0, 2**31), relief=st.sampled_from([0.1, 10.0]),
       holes=st.sampled_from([0.0, 0.2]), codes=st.sampled_from(["delta", "random"]))
def test_guessed_rings_decode_to_the_stored_codes(t, seed, relief, holes, codes):
    """A level-0 RING δ written with the heights holds (code − own code) mod 256 and
    decodes exactly, the codes δ's own (mostly the guess: a small payload) or random (a
    wrong guess costs bytes only); read against another guess it is refused (its first
    byte checks the guess it was coded against) or, one guess in 256, decodes other codes."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    N = 2 * (T - 1) + 1
    z, v = _heights(rng, (N, N), relief, holes)
    stand_in = 0.5
    d = vertex_errors(np.where(v, z, 0.0), v)
    if codes == "random":
        d = log8_table(-4)[rng.integers(0, 255, (N, N))]
    e = log8_exponent(d)
    coding = BoundsCoding(d.astype(np.float32), None, e, r_codes=(np.zeros((N, N), np.uint8), 0))
    xy = [(0, 0), (1, 0), (0, 1), (1, 1)]
    blobs, _, _ = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), t, 0, 1, xy, ("delta",),
                              ring=("delta",), own=OwnHeights(z, v, stand_in))
    dc = log8_codes(d, e)
    rr, rc = ring_new_index(T)
    for x, y in xy:
        blob = blobs["delta"][(0, x, y)]
        assert blob[1] & (RING | PRED) == RING | PRED
        win = np.s_[y * (T - 1):y * (T - 1) + T, x * (T - 1):x * (T - 1) + T]
        seen = {}

        def derive(rows, cols, ring, log8, ee, slack, seen=seen):
            seen["ring"] = ring
            return np.zeros((T, T), np.float32)

        decode_bounds(blob, (T, T), np.zeros((T, T), np.float32), (x % 2, y % 2), derive,
                      own=lambda ee, win=win: own_codes(z[win], v[win], stand_in, ee)[0])
        np.testing.assert_array_equal(log8_codes(seen["ring"], e), dc[win][rr, rc])
        g = own_codes(z[win], v[win], stand_in, e)[0]
        try:  # its check byte refuses it (but for one guess in 256: other codes then)
            decode_bounds(blob, (T, T), np.zeros((T, T), np.float32), (0, 0), derive,
                          own=lambda ee, g=g: g + 1)
        except ValueError as exc:
            assert "other heights" in str(exc)
        else:
            assert not np.array_equal(log8_codes(seen["ring"], e), dc[win][rr, rc])
        np.testing.assert_array_equal(
            ring_codes_own(ring_payloads_own(dc[win][rr, rc][None], g[rr, rc][None])[0],
                           g[rr, rc]), dc[win][rr, rc])


@pytest.mark.parametrize("flags", [PRED | SLACK, RING | PRED])
def test_a_guessed_delta_blob_without_its_heights_is_refused(flags):
    from geoterrain.bounds.vertexdata import LOG8, NEW_ONLY, VERSION_2

    g0 = np.zeros(len(ring_new_index(9)[0]) if flags & RING else (9, 9), np.uint8)
    blob = bytes([VERSION_2, NEW_ONLY | LOG8 | flags, 0, guess_check(g0), 2])
    args = (blob, (9, 9), np.zeros((9, 9), np.float32), (0, 0),
            lambda *a: np.zeros((9, 9), np.float32))
    with pytest.raises(ValueError, match="needs the tile's heights"):
        decode_bounds(*args)
    with pytest.raises(ValueError, match="wrong shape"):
        decode_bounds(*args, own=lambda e: np.zeros((7, 7), np.uint8))
    assert decode_bounds(*args, own=lambda e: np.zeros((9, 9), np.uint8)).shape == (9, 9)
    with pytest.raises(ValueError, match="other heights"):  # the check byte: 0 against 1s
        decode_bounds(*args, own=lambda e: np.ones((9, 9), np.uint8))



def _delta_blob(W: np.ndarray, z: np.ndarray, e: int) -> bytes:
    # the δ blob an edit writes for a tile below the top and above level 0
    T = W.shape[0]
    coding = BoundsCoding.of_codes(W, e, np.zeros((T, T), np.uint8), 0)
    blobs, _, _ = level_blobs(coding, np.zeros((T, T, 2), np.uint8), (T - 1).bit_length() - 1,
                              0, 1, [(0, 0)], ("delta",), mids=True,
                              own=OwnHeights(z, None, 0.0))
    return blobs["delta"][(0, 0, 0)]


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.sampled_from([1, 2, 4, 8]),
       where=st.sampled_from(["corner", "centre", "midpoint", "height", "none"]),
       zeros=st.booleans())
def test_a_payload_decided_the_same_is_the_same(seed, h, where, zeros):
    """Where ``pred_payload_same`` says two tiles' schema-20 δ blobs are the same bytes
    (an edit then keeps the stored blob without coding it), the blobs coded are equal:
    tiles and heights moved at one place (a corner, a centre, an edge midpoint, a
    height) or nowhere, some with every new vertex off the centres 0 (CENTRES: never
    decided the same)."""
    rng = np.random.default_rng(seed)
    T, e = 2 * h + 1, -3
    W0 = rng.integers(0, 60, (T, T)).astype(np.uint8)
    if zeros:
        W0.ravel()[_pred_index(T)[0]] = 0
    z0 = rng.normal(0.0, 2.0, (T, T))
    W1, z1 = W0.copy(), z0.copy()
    i, j = (2 * int(rng.integers(0, h + 1)), 2 * int(rng.integers(0, h + 1)))
    if where == "corner":
        W1[i, j] = rng.integers(0, 60)
    elif where == "centre":
        W1[2 * int(rng.integers(0, h)) + 1, 2 * int(rng.integers(0, h)) + 1] += 1
    elif where == "midpoint":
        W1[2 * int(rng.integers(0, h)) + 1, j] += 1
    elif where == "height":
        z1[int(rng.integers(0, T)), int(rng.integers(0, T))] += float(rng.normal(0.0, 3.0))
    lo0, lo1 = own_codes(z0, None, 0.0, e)[0], own_codes(z1, None, 0.0, e)[0]
    same = pred_payload_same(W0, lo0, W1, lo1)
    assert not same or _delta_blob(W0, z0, e) == _delta_blob(W1, z1, e)
    if where == "none" and not zeros:
        assert same
    # exactly where the payload's inputs are the same: the same own errors and the same
    # pred_gaps' differences and gaps (PRED shape)
    gaps0, gaps1 = pred_gaps(W0[None], lo0[None]), pred_gaps(W1[None], lo1[None])
    pred = W0.ravel()[_pred_index(T)[0]].any() and W1.ravel()[_pred_index(T)[0]].any()
    assert same == (pred and np.array_equal(lo0, lo1) and new_codes_same(W0, W1)
                    and all(np.array_equal(a, b) for a, b in zip(gaps0, gaps1, strict=True)))

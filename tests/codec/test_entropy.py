"""Tests of the height codec's entropy stage (geoterrain.codec.entropy)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.codec import entropy
from geoterrain.codec.entropy import MASK_ALL_INVALID, MASK_ALL_VALID, MASK_STORED
from geoterrain.codec.predict import fill_level
from geoterrain.codec.pyramid import decode_tile, encode_pyramid
from geoterrain.codec.quantize import Quantizer
from geoterrain.core.zstdsafe import MAGIC, compress_one

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def _new(t: int) -> np.ndarray:
    """The samples new at a child tile's level (not on its parent's grid)."""
    new = np.ones((t, t), bool)
    new[::2, ::2] = False
    return new


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.sampled_from([1, 2, 3, 4, 8, 32]),
       scale=st.sampled_from([0, 3, 1000, 2**40, 2**62]),
       kind=st.sampled_from([MASK_ALL_VALID, MASK_ALL_INVALID, MASK_STORED]),
       holes=st.floats(0.0, 1.0), cubic=st.booleans(), px=st.integers(0, 1),
       py=st.integers(0, 1))
def test_a_tile_stream_decodes_to_its_codes_and_mask(seed, h, scale, kind, holes, cubic, px,
                                                      py):
    """Every valid new sample's code and the whole mask come back, the parent's samples
    are copied, and the stream is exactly the one the encoder wrote."""
    rng = np.random.default_rng(seed)
    t = 2 * h + 1
    ok = {MASK_ALL_VALID: np.ones((t, t), bool), MASK_ALL_INVALID: np.zeros((t, t), bool),
          MASK_STORED: rng.random((t, t)) >= holes}[kind]
    parent = rng.integers(-scale - 1, scale + 1, (t, t))
    child = rng.integers(-scale - 1, scale + 1, (t, t))
    data = entropy.encode_tile(child, ok, parent, (px, py), cubic, kind)
    out, mask, exact = entropy.decode_tile(np.frombuffer(data, np.uint8), parent, px, py,
                                           cubic, kind)
    assert exact
    np.testing.assert_array_equal(out[ok & _new(t)], child[ok & _new(t)])
    np.testing.assert_array_equal(out[::2, ::2], parent[py * h:py * h + h + 1,
                                                        px * h:px * h + h + 1])
    np.testing.assert_array_equal(mask, ok)
    np.testing.assert_array_equal(
        entropy.decode_mask(np.frombuffer(data, np.uint8), t, kind), ok)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), te=st.integers(1, 6), cubic=st.booleans(),
       holes=st.floats(0.0, 1.0), scale=st.sampled_from([0, 1, 100, 2**40]),
       W=st.sampled_from([1, 3, 41]))
def test_the_top_tile_decodes_to_its_fill(seed, te, cubic, holes, scale, W):
    """Coarse to fine inside the top tile: the decoded tile is the encoder's codes with
    every invalid sample but the corners filled by fill_level, level by level (the rule
    the encoder's whole-grid fill follows), and with residual bins W every valid one
    binned by it, within (W - 1) / 2 of its code."""
    rng = np.random.default_rng(seed)
    t = (1 << te) + 1
    top = np.round(rng.normal(0, 1, (t, t)).cumsum(0) * scale).astype(np.int64)
    ok = rng.random((t, t)) >= holes
    kind = MASK_ALL_VALID if ok.all() else MASK_ALL_INVALID if not ok.any() else MASK_STORED
    want = top.copy()
    for k in range(te - 1, -1, -1):
        fill_level(want, ok, 1 << k, (1 << te) if cubic else 0, W)
    assert np.all(np.abs(want - top)[ok] <= (W - 1) // 2)
    data = entropy.encode_top(want, ok, te, cubic, kind, W)
    got, mask, exact = entropy.decode_top(np.frombuffer(data, np.uint8), te, cubic, kind,
                                          W)
    assert exact
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(mask, ok)


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=300), h=st.sampled_from([1, 4, 32]),
       kind=st.sampled_from([MASK_ALL_VALID, MASK_ALL_INVALID, MASK_STORED]),
       te=st.integers(1, 6), cubic=st.booleans(), W=st.sampled_from([1, 3, 1025]))
def test_any_bytes_decode_to_some_codes(data, h, kind, te, cubic, W):
    """A stream from a stranger is never refused and never runs away: any bytes decode,
    in bounded time, to arrays of the tile's shape (residual bins too)."""
    buf = np.frombuffer(data, np.uint8)
    t = 2 * h + 1
    out, ok, _ = entropy.decode_tile(buf, np.zeros((t, t), np.int64), 1, 0, cubic, kind, W)
    assert out.shape == ok.shape == (t, t)
    top, ok, _ = entropy.decode_top(buf, te, cubic, kind, W)
    assert top.shape == ok.shape == ((1 << te) + 1,) * 2


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), extra=st.binary(min_size=32, max_size=200))
def test_bytes_past_a_streams_end_are_refused(seed, extra):
    """A stream is decoded whole: the same stream with bytes appended (a spliced blob,
    a frame of another format) or a zero byte appended (a padded one) is told apart from
    the encoder's. (A few bytes just past the end can be read as part of the stream:
    the encoder drops its trailing zeros, which the decoder reads back as zeros.)"""
    rng = np.random.default_rng(seed)
    t = 9
    parent = np.zeros((t, t), np.int64)
    child = rng.geometric(0.4, (t, t)) - 1
    ok = np.ones((t, t), bool)
    data = entropy.encode_tile(child, ok, parent, (0, 0), False, MASK_ALL_VALID)
    for bad in (data + extra, data + b"\0"):
        *_, exact = entropy.decode_tile(np.frombuffer(bad, np.uint8), parent, 0, 0, False,
                                        MASK_ALL_VALID)
        assert not exact


def test_a_flat_tile_costs_a_few_bytes():
    """The adaptive models learn a flat 65² tile at once: 4 160 new samples in at most
    8 bytes (a per-tile table, as zstd's frames carry, would cost more)."""
    t = 65
    z = np.zeros((t, t), np.int64)
    data = entropy.encode_tile(z, np.ones((t, t), bool), z, (0, 0), True, MASK_ALL_VALID)
    assert len(data) <= 8


def test_contexts_beat_one_model_on_mixed_activity():
    """Half the tile rough, half flat: the activity contexts code it in fewer bytes
    than the same values shuffled among the new samples (where neighbours tell
    nothing)."""
    rng = np.random.default_rng(3)
    t = 65
    amp = np.where(np.arange(t)[None, :] < t // 2, 200.0, 0.3) * np.ones((t, t))
    child = np.round(rng.normal(0, 1, (t, t)) * amp).astype(np.int64)
    parent = np.zeros((t, t), np.int64)
    child[::2, ::2] = 0
    ok = np.ones((t, t), bool)
    shuffled = child.copy()
    shuffled[_new(t)] = rng.permutation(child[_new(t)])
    as_is = len(entropy.encode_tile(child, ok, parent, (0, 0), False, MASK_ALL_VALID))
    mixed = len(entropy.encode_tile(shuffled, ok, parent, (0, 0), False, MASK_ALL_VALID))
    assert as_is < 0.9 * mixed


def test_the_phase_of_a_prediction_is_a_context():
    """Codes on a grid coarser than the surface (ε-quantised heights): where the
    floor-mean of the neighbours sits half a code below the truth, the residual leans
    up. Coded with the phase, such a tile costs less than the same residuals with the
    phases scrambled."""
    rng = np.random.default_rng(4)
    t = 65
    parent = rng.integers(0, 8, (t, t)).cumsum(1)  # a ramp of small integer steps
    child = np.zeros((t, t), np.int64)
    ok = np.ones((t, t), bool)
    # the truth is the exact midpoint, rounded up: residual 1 where the mean is a half
    h = t // 2
    c = parent[:h + 1, :h + 1]
    child[::2, ::2] = c
    child[::2, 1::2] = (c[:, :-1] + c[:, 1:] + 1) // 2
    child[1::2, ::2] = (c[:-1] + c[1:] + 1) // 2
    child[1::2, 1::2] = (child[:-2:2, 1::2] + child[2::2, 1::2] + 1) // 2
    with_phase = len(entropy.encode_tile(child, ok, parent, (0, 0), False, MASK_ALL_VALID))
    # the same residuals where the phase says nothing: the parents all even
    even = parent * 2
    c2 = even[:h + 1, :h + 1]
    child2 = np.zeros_like(child)
    child2[::2, ::2] = c2
    r = child
    child2[::2, 1::2] = (c2[:, :-1] + c2[:, 1:]) // 2 + (r[::2, 1::2] - (c[:, :-1] + c[:, 1:]) // 2)
    child2[1::2, ::2] = (c2[:-1] + c2[1:]) // 2 + (r[1::2, ::2] - (c[:-1] + c[1:]) // 2)
    child2[1::2, 1::2] = (child2[:-2:2, 1::2] + child2[2::2, 1::2]) // 2 + (
        r[1::2, 1::2] - (child[:-2:2, 1::2] + child[2::2, 1::2]) // 2)
    scrambled = len(entropy.encode_tile(child2, ok, even, (0, 0), False, MASK_ALL_VALID))
    assert with_phase < 0.8 * scrambled


def test_a_tile_past_its_first_row_is_coded_again():
    """Integer noise of about 40 bits a residual overflows the 8 bits a sample that a
    level's rows start with; those tiles are coded again and decode exactly."""
    rng = np.random.default_rng(5)
    z = np.round(rng.normal(0, 2.0**40, (129, 129)))
    v = np.ones(z.shape, bool)
    q = Quantizer("int")
    blobs = encode_pyramid(z, v, 6, q)
    assert len(blobs[(0, 0, 0)]) > 64 + 65 * 65  # more than the first row held
    assert not blobs[(0, 0, 0)][1] & 16  # range-coded, not a wide blob
    top = decode_tile(blobs[(1, 0, 0)], None, q)
    child = decode_tile(blobs[(0, 1, 1)], top, q, (1, 1))
    np.testing.assert_array_equal(child, z[64:, 64:].astype(np.int64))


def test_a_lossless_float_store_has_wide_blobs_below_its_top():
    """Float bit patterns (10-30 bits a residual) go to the byte-shuffled zstd blobs;
    they decode exactly like the range-coded ones, and a frame holding more or less
    than its size is refused."""
    import pytest

    rng = np.random.default_rng(6)
    z = rng.normal(0, 100, (129, 129)).astype(np.float32).astype(np.float64)
    v = rng.random(z.shape) > 0.05
    q = Quantizer("float", float_bits=32)
    blobs = encode_pyramid(z, v, 6, q)
    assert blobs[(0, 1, 0)][1] & 16 and not blobs[(1, 0, 0)][1] & 16
    top = decode_tile(blobs[(1, 0, 0)], None, q)
    child = decode_tile(blobs[(0, 1, 0)], top, q, (1, 0))
    from geoterrain.codec.quantize import codes_to_heights
    ok = v[:65, 64:]
    np.testing.assert_array_equal(codes_to_heights(child, q)[ok], z[:65, 64:][ok])
    import zstandard
    b = blobs[(0, 1, 0)]
    raw = zstandard.ZstdDecompressor().decompress(MAGIC + b[4:])  # stored without it
    for bad in (raw + b"x", raw[:-1]):
        for frame in (zstandard.ZstdCompressor().compress(bad), compress_one(bad)):
            with pytest.raises(ValueError):
                decode_tile(b[:4] + frame, top, q, (1, 0))


@settings(max_examples=60, deadline=None)
@given(w=st.sampled_from([0, 1, 2, 4, 8]), seed=st.integers(0, 2**32 - 1),
       cubic=st.booleans(), off=st.integers(0, 3), py=st.integers(0, 1), px=st.integers(0, 1))
def test_wide_residuals_of_every_width(w, seed, cubic, off, py, px):
    """A wide blob's residuals, w little-endian bytes in w planes, zig-zag coded (the top
    bit set too at w = 8), are added to the predictions as numpy unpacks them."""
    from geoterrain.codec.predict import cubic_child, linear_child
    from geoterrain.codec.pyramid.decode import _wide_child

    rng = np.random.default_rng(seed)
    h = 4
    n, tt = 3 * h * h + 2 * h, 2 * h + 1
    data = rng.integers(0, 256, off + w * n, dtype=np.uint8)
    parent = rng.integers(-2**40, 2**40, (tt, tt))
    v = np.zeros(n, np.uint64)
    for b in range(w):
        v |= data[off + b * n:off + (b + 1) * n].astype(np.uint64) << np.uint64(8 * b)
    r = (v >> np.uint64(1)).astype(np.int64) ^ -(v & np.uint64(1)).astype(np.int64)
    want = np.empty((tt, tt), np.int64)
    if cubic:
        cubic_child(parent, py * h, px * h, h, r, want)
    else:
        linear_child(np.ascontiguousarray(parent[py * h:py * h + h + 1,
                                                 px * h:px * h + h + 1]), h, r, want)
    got = np.empty((tt, tt), np.int64)
    _wide_child(data, off, w, n, parent, py, px, h, cubic, got)
    np.testing.assert_array_equal(got, want)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), cubic=st.booleans(), holes=st.sampled_from([0.0, 0.1]))
def test_wide_blobs_of_a_level_are_each_tiles_own(seed, cubic, holes):
    """The level's byte planes, built a width at a time, are each tile's own: its
    residuals in the fewest little-endian bytes, plane by plane, after its mask."""
    import zstandard

    from geoterrain.codec.pyramid.encode import _wide_blobs
    from geoterrain.codec.pyramid.layout import _header, _period

    rng = np.random.default_rng(seed)
    te, s, h = 2, 1, 2
    n = 4 * 2 * h + 1  # a 4 × 4 level of tiles of side 2h
    scale = rng.choice([0, 2, 100, 2**12, 2**24, 2**40, 2**61], (4, 4))  # every width
    scale[:2, :2] = rng.choice([0, 2])  # tile (0, 0)'s closed footprint is all small and
    scale[3, 3] = 2**61  # tile (3, 3)'s all large: at least two widths in every example
    d = (rng.normal(0, 1, (n, n)) * np.kron(scale, np.ones((2 * h, 2 * h)))[
        np.minimum(np.arange(n), n - 2)][:, np.minimum(np.arange(n), n - 2)]).astype(np.int64)
    valid = rng.random((n, n)) >= holes
    ys, xs = (a.ravel() for a in np.indices((4, 4)))
    def window(q):  # tile q's closed footprint
        return (slice(ys[q] * 2 * h, ys[q] * 2 * h + 2 * h + 1),
                slice(xs[q] * 2 * h, xs[q] * 2 * h + 2 * h + 1))

    kinds = np.array([MASK_ALL_VALID if valid[window(q)].all() else MASK_STORED
                      for q in range(ys.size)])
    got = _wide_blobs(0, d, valid, s, h, te, ys, xs, kinds, cubic)
    zz = np.empty((ys.size, 3 * h * h + 2 * h), np.uint64)
    zmax = np.empty(ys.size, np.uint64)
    entropy.level_zigzag(d, s, h, _period(te, cubic), ys, xs, zz, zmax)
    widths = set()
    for q in range(ys.size):  # the per-tile rule
        zm = int(zz[q].max())
        w = 0 if zm == 0 else next(b for b in (1, 2, 4, 8) if zm < 1 << (8 * b))
        widths.add(w)
        mask = np.packbits(valid[window(q)]).tobytes() if kinds[q] == MASK_STORED else b""
        body = b"".join(((zz[q] >> np.uint64(8 * b)) & np.uint64(255)).astype(np.uint8).tobytes()
                        for b in range(w))
        blob = got[(0, int(xs[q]), int(ys[q]))]
        assert blob[:4] == _header(False, int(kinds[q]), te, cubic, w)
        assert blob[4:8] != MAGIC  # stored without zstd's magic number (schema 10)
        assert zstandard.ZstdDecompressor().decompress(MAGIC + blob[4:]) == mask + body
    assert cubic or len(widths) >= 2  # (the cubic stencil reaches the neighbours' scales)

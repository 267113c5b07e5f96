"""Tests of the height codec's entropy stage (geoterrain.entropy)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain import entropy
from geoterrain.codec import decode_tile, encode_pyramid
from geoterrain.entropy import MASK_ALL_INVALID, MASK_ALL_VALID, MASK_STORED
from geoterrain.predict import fill_level
from geoterrain.quantize import Quantizer


def _codec_order_valid(ok: np.ndarray, h: int) -> np.ndarray:
    """The valid flag of each residual, in the codec's order (classes A, B, C)."""
    return np.concatenate([ok[0::2, 1::2].ravel(), ok[1::2, 0::2].ravel(),
                           ok[1::2, 1::2].ravel()])


def _residuals(rng: np.random.Generator, n: int, kind: str) -> np.ndarray:
    if kind == "zeros":
        return np.zeros(n, np.uint64)
    if kind == "geometric":
        return (rng.geometric(rng.uniform(0.02, 0.95), n) - 1).astype(np.uint64)
    if kind == "outliers":
        zz = rng.poisson(1.0, n).astype(np.uint64)
        hit = rng.random(n) < 0.02
        zz[hit] = rng.integers(0, 2**63, hit.sum(), dtype=np.int64).astype(np.uint64) * 2 + 1
        return zz
    return rng.integers(0, 2**63, n, dtype=np.int64).astype(np.uint64) * 2  # "wide"


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.sampled_from([1, 2, 3, 4, 8, 32]),
       dist=st.sampled_from(["zeros", "geometric", "outliers", "wide"]),
       kind=st.sampled_from([MASK_ALL_VALID, MASK_ALL_INVALID, MASK_STORED]),
       holes=st.floats(0.0, 1.0))
def test_a_tile_stream_decodes_to_its_residuals_and_mask(seed, h, dist, kind, holes):
    """Every valid sample's residual and the whole mask come back; invalid samples
    decode to 0 (the codec's rule: their code is their prediction)."""
    rng = np.random.default_rng(seed)
    t = 2 * h + 1
    ok = {MASK_ALL_VALID: np.ones((t, t), bool), MASK_ALL_INVALID: np.zeros((t, t), bool),
          MASK_STORED: rng.random((t, t)) >= holes}[kind]
    zz = _residuals(rng, 3 * h * h + 2 * h, dist)
    c = rng.integers(-2**62, 2**62, (h + 1, h + 1))
    data = entropy.encode_tile(zz, ok, c, h, kind)
    got, mask, exact = entropy.decode_tile(np.frombuffer(data, np.uint8), c, h, kind)
    assert exact
    want = np.where(_codec_order_valid(ok, h), zz, np.uint64(0))
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(mask, ok)
    np.testing.assert_array_equal(
        entropy.decode_mask(np.frombuffer(data, np.uint8), t, kind), ok)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), te=st.integers(1, 6), cubic=st.booleans(),
       holes=st.floats(0.0, 1.0), scale=st.sampled_from([0, 1, 100, 2**40]))
def test_the_top_tile_decodes_to_its_codes(seed, te, cubic, holes, scale):
    """Coarse to fine inside the top tile: valid codes come back exactly, invalid ones
    as the fill the encoder was given (corners as given, the rest their prediction)."""
    rng = np.random.default_rng(seed)
    t = (1 << te) + 1
    top = np.round(rng.normal(0, 1, (t, t)).cumsum(0) * scale).astype(np.int64)
    ok = rng.random((t, t)) >= holes
    period = (1 << te) if cubic else 0
    for k in range(te - 1, -1, -1):
        fill_level(top, ok, 1 << k, period)
    kind = MASK_ALL_VALID if ok.all() else MASK_ALL_INVALID if not ok.any() else MASK_STORED
    data = entropy.encode_top(top, ok, te, period, kind)
    got, mask, exact = entropy.decode_top(np.frombuffer(data, np.uint8), te, period, kind)
    assert exact
    np.testing.assert_array_equal(got, top)
    np.testing.assert_array_equal(mask, ok)


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=300), h=st.sampled_from([1, 4, 32]),
       kind=st.sampled_from([MASK_ALL_VALID, MASK_ALL_INVALID, MASK_STORED]),
       te=st.integers(1, 6))
def test_any_bytes_decode_to_some_codes(data, h, kind, te):
    """A stream from a stranger is never refused and never runs away: any bytes decode,
    in bounded time, to arrays of the tile's shape."""
    buf = np.frombuffer(data, np.uint8)
    zz, ok, _ = entropy.decode_tile(buf, np.zeros((h + 1, h + 1), np.int64), h, kind)
    assert zz.shape == (3 * h * h + 2 * h,) and ok.shape == (2 * h + 1, 2 * h + 1)
    top, ok, _ = entropy.decode_top(buf, te, 1 << te, kind)
    assert top.shape == ok.shape == ((1 << te) + 1,) * 2


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), extra=st.binary(min_size=32, max_size=200))
def test_bytes_past_a_streams_end_are_refused(seed, extra):
    """A stream is decoded whole: the same stream with bytes appended (a spliced blob,
    a frame of another format) or a zero byte appended (a padded one) is told apart from
    the encoder's. (A few bytes just past the end can be read as part of the stream:
    the encoder drops its trailing zeros, which the decoder reads back as zeros.)"""
    rng = np.random.default_rng(seed)
    h = 4
    zz = (rng.geometric(0.4, 3 * h * h + 2 * h) - 1).astype(np.uint64)
    c = np.zeros((h + 1, h + 1), np.int64)
    ok = np.ones((2 * h + 1,) * 2, bool)
    data = entropy.encode_tile(zz, ok, c, h, MASK_ALL_VALID)
    for bad in (data + extra, data + b"\0"):
        *_, exact = entropy.decode_tile(np.frombuffer(bad, np.uint8), c, h, MASK_ALL_VALID)
        assert not exact


def test_a_flat_tile_costs_a_few_bytes():
    """The adaptive models learn a tile of zero residuals at once: 3 136 zero flags in
    at most 8 bytes (a per-tile table, as zstd's frames carry, would cost more)."""
    h = 32
    data = entropy.encode_tile(np.zeros(3 * h * h + 2 * h, np.uint64),
                               np.ones((2 * h + 1,) * 2, bool), np.zeros((h + 1,) * 2, np.int64),
                               h, MASK_ALL_VALID)
    assert len(data) <= 8


def test_contexts_beat_one_model_on_mixed_activity():
    """Half the tile rough, half flat: the activity contexts code it in fewer bytes
    than the same residuals shuffled (where neighbours tell nothing)."""
    rng = np.random.default_rng(3)
    h = 32
    t = 2 * h + 1
    amp = np.where(np.arange(t)[None, :] < h, 200.0, 0.3) * np.ones((t, t))
    r = np.round(rng.normal(0, 1, (t, t)) * amp).astype(np.int64)
    zz = (r << 1) ^ (r >> 63)
    order = np.concatenate([zz[0::2, 1::2].ravel(), zz[1::2, 0::2].ravel(),
                            zz[1::2, 1::2].ravel()]).astype(np.uint64)
    ok = np.ones((t, t), bool)
    c = np.zeros((h + 1, h + 1), np.int64)
    as_is = len(entropy.encode_tile(order, ok, c, h, MASK_ALL_VALID))
    shuffled = len(entropy.encode_tile(rng.permutation(order), ok, c, h, MASK_ALL_VALID))
    assert as_is < 0.9 * shuffled


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
    from geoterrain.quantize import codes_to_heights
    ok = v[:65, 64:]
    np.testing.assert_array_equal(codes_to_heights(child, q)[ok], z[:65, 64:][ok])
    import zstandard
    b = blobs[(0, 1, 0)]
    raw = zstandard.ZstdDecompressor().decompress(b[4:])
    for bad in (raw + b"x", raw[:-1]):
        with pytest.raises(ValueError):
            decode_tile(b[:4] + zstandard.ZstdCompressor().compress(bad), top, q, (1, 0))

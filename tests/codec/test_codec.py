"""Tests of the residual pyramid codec (geoterrain.codec.pyramid)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from geoterrain.codec.pyramid import (
    BLOB_VERSION,
    decode_tile,
    decoded_codes,
    decoded_heights,
    encode_pyramid,
    pyramid_shape,
    tile_valid,
)
from geoterrain.codec.quantchoice import FLOAT_BINS, choose_quantizer
from geoterrain.codec.quantize import (
    MAX_BINS,
    Quantizer,
    codes_to_heights,
    heights_to_codes,
    roundtrip,
    tile_heights,
)

# ----------------------------------------------------------------------------- helpers


def decode_all(blobs, n_samples, t, qz):
    """Decode every stored tile top-down; returns {level: (codes grid, covered mask)}."""
    n, te = pyramid_shape(n_samples, t)
    span = 1 << te
    cache: dict = {}
    out = {}
    for lev in range(n - te + 1):
        m = (1 << (n - lev)) + 1
        out[lev] = (np.zeros((m, m), np.int64), np.zeros((m, m), bool))
    for key in sorted(blobs, key=lambda k: -k[0]):  # parents first
        lev, x, y = key
        parent = cache.get((lev + 1, x // 2, y // 2))  # None for the top tile
        codes = cache[key] = decode_tile(blobs[key], parent, qz, (x % 2, y % 2))
        g, cov = out[lev]
        sl = (slice(y * span, y * span + span + 1), slice(x * span, x * span + span + 1))
        # shared borders must agree between neighbouring tiles
        assert np.array_equal(g[sl][cov[sl]], codes[cov[sl]])
        g[sl] = codes
        cov[sl] = True
    return out


def expected_keys(valid, t):
    """Tiles whose footprint holds a valid sample, by brute force."""
    n, te = pyramid_shape(valid.shape[0], t)
    keys = set()
    for lev in range(n - te + 1):
        span = (1 << te) << lev
        nt = 1 << (n - lev - te)
        for y in range(nt):
            for x in range(nt):
                if valid[y * span : y * span + span + 1, x * span : x * span + span + 1].any():
                    keys.add((lev, x, y))
    return keys


def check_pyramid(z, valid, t, qz, codec_error=0.0, predictor="auto"):
    """Encode, decode every tile and check against decoded_codes / decoded_heights / z."""
    blobs = encode_pyramid(z, valid, t, qz, predictor=predictor)
    assert set(blobs) == expected_keys(valid, t)
    assert all(b[0] == BLOB_VERSION for b in blobs.values())
    if not blobs:
        return blobs
    ref = decoded_codes(z, valid, t, qz, predictor)
    levels = decode_all(blobs, z.shape[0], t, qz)
    for lev, (g, cov) in levels.items():
        s = 1 << lev
        assert np.array_equal(g[cov], ref[::s, ::s][cov])
    g0, cov0 = levels[0]
    assert cov0[valid].all()
    h = codes_to_heights(g0, qz)
    hv = h[valid]
    if qz.mode == "quantized":
        assert np.all(np.abs(hv - z[valid]) <= codec_error)
    else:
        assert np.array_equal(hv.view(np.int64), z[valid].view(np.int64))  # bit-exact
    if qz.bins == 1:  # each code decodes to itself
        dh = decoded_heights(z, valid, qz)
        assert np.array_equal(dh[valid], hv)
        assert np.all(np.isnan(dh[~valid]))
    else:  # residual bins: the decoded heights depend on the pyramid
        with pytest.raises(ValueError, match="pass t"):
            decoded_heights(z, valid, qz)
    dht = decoded_heights(z, valid, qz, t=t, predictor=predictor)
    assert np.array_equal(dht[cov0], h[cov0], equal_nan=True)
    return blobs


def fractal(n_samples, seed=0, relief=1000.0):
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(n_samples)[:, None]
    f = np.sqrt(k**2 + np.fft.rfftfreq(n_samples)[None, :] ** 2)
    f[0, 0] = 1.0
    spec = (rng.normal(size=f.shape) + 1j * rng.normal(size=f.shape)) / f**1.2
    z = np.fft.irfft2(spec, s=(n_samples, n_samples))
    return (z - z.min()) / (z.max() - z.min()) * relief


# ----------------------------------------------------------------------------- lossless


@pytest.mark.fast
@pytest.mark.parametrize(
    "n_samples,t", [(3, 1), (3, 6), (5, 1), (5, 6), (17, 2), (65, 3), (129, 6)]
)
@pytest.mark.parametrize("predictor", ["linear", "cubic"])
def test_int_roundtrip_exact(n_samples, t, predictor):
    rng = np.random.default_rng(n_samples + t)
    z = np.round(fractal(n_samples, n_samples) + rng.integers(-3, 4, (n_samples,) * 2))
    valid = rng.random(z.shape) > 0.1
    qz = choose_quantizer(z[valid], np.int16)
    assert qz.mode == "int"
    blobs = check_pyramid(z, valid, t, qz, predictor=predictor)
    n, te = pyramid_shape(n_samples, t)
    used_cubic = {bool(b[1] & 8) for b in blobs.values()}
    assert used_cubic == {predictor == "cubic" and te >= 2 and n > te}


@pytest.mark.fast
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_float_roundtrip_bit_exact(dtype):
    rng = np.random.default_rng(3)
    z = fractal(65, 1) - 300.0 + rng.normal(0, 1e-3, (65, 65))
    z[0, 0], z[1, 1], z[2, 2] = -0.0, 1e-30, -1e-30
    z = z.astype(dtype).astype(np.float64)
    valid = np.ones(z.shape, bool)
    valid[10:20, 30:33] = False
    qz = choose_quantizer(z, dtype)
    assert qz.mode == "float" and qz.float_bits == (32 if dtype == np.float32 else 64)
    check_pyramid(z, valid, 3, qz)


@pytest.mark.fast
def test_known_scale_terrain_rgb_is_lossless_int():
    rng = np.random.default_rng(4)
    k = rng.integers(100000, 140000, (33, 33))
    z = -10000 + k * 0.1  # Terrain-RGB decoding
    qz = choose_quantizer(z, np.float64, scale=0.1, offset=-10000.0)
    assert qz.mode == "int"
    check_pyramid(z, np.ones(z.shape, bool), 2, qz)
    # integer-valued floats are detected without a scale
    assert choose_quantizer(np.round(z), np.float32).mode == "int"
    # an inexact scale falls back to float
    assert choose_quantizer(z + 0.01234, np.float64, scale=0.1).mode == "float"


@pytest.mark.fast
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n=st.integers(1, 5),
    t=st.integers(1, 7),
    seed=st.integers(0, 2**31),
    hole_p=st.sampled_from([0.0, 0.3, 0.9, 1.0]),
    amp=st.sampled_from([1, 100, 30000, 2**40]),
    predictor=st.sampled_from(["linear", "cubic", "auto"]),
)
def test_int_roundtrip_hypothesis(n, t, seed, hole_p, amp, predictor):
    rng = np.random.default_rng(seed)
    size = (1 << n) + 1
    z = rng.integers(-amp, amp + 1, (size, size)).astype(np.float64)
    valid = rng.random(z.shape) >= hole_p
    check_pyramid(z, valid, t, Quantizer("int"), predictor=predictor)


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(1, 5),
    t=st.integers(1, 4),
    seed=st.integers(0, 2**31),
    predictor=st.sampled_from(["linear", "cubic"]),
)
def test_float64_roundtrip_hypothesis(n, t, seed, predictor):
    rng = np.random.default_rng(seed)
    size = (1 << n) + 1
    z = rng.normal(0, 1, (size, size)) * 10.0 ** rng.integers(-30, 30, (size, size))
    valid = rng.random(z.shape) > 0.2
    check_pyramid(z, valid, t, choose_quantizer(z[valid], np.float64), predictor=predictor)


# ----------------------------------------------------------------------------- quantized


def _fields(size, seed):
    rng = np.random.default_rng(seed)
    spiky = fractal(size, seed, 50.0)
    spikes = rng.random(spiky.shape) < 0.02
    spiky[spikes] += rng.normal(0, 3000, int(spikes.sum()))
    spiky.ravel()[rng.integers(0, spiky.size, 20)] = rng.normal(0, 5000, 20)
    return {
        "random": rng.normal(0, 500, (size, size)),
        "fractal": fractal(size, seed, 3000.0),
        "spiky": spiky,
        "everest": 8848.0 + rng.normal(0, 3, (size, size)),
        "trench": -11000.0 + rng.normal(0, 3, (size, size)),
    }


@pytest.mark.fast
@pytest.mark.parametrize("eps", [0.01, 0.1, 0.5, 2.0])
@pytest.mark.parametrize("kind", ["random", "fractal", "spiky", "everest", "trench"])
@pytest.mark.parametrize("predictor", ["linear", "cubic"])
def test_quantized_within_eps(eps, kind, predictor):
    z = _fields(65, 7)[kind]
    valid = np.ones(z.shape, bool)
    valid[5:9, 40:60] = False
    qz = choose_quantizer(z[valid], np.float32, codec_error=eps)
    assert qz.mode == "quantized" and qz.codec_error == eps and qz.step <= 2 * eps
    check_pyramid(z, valid, 3, qz, codec_error=eps, predictor=predictor)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(
    base=st.sampled_from([0.0, 8848.0, -11000.0, 1e6, -3.7e5]),
    eps=st.sampled_from([0.001, 0.01, 0.1, 0.5, 2.0]),
    seed=st.integers(0, 2**31),
)
def test_quantized_bound_hypothesis(base, eps, seed):
    rng = np.random.default_rng(seed)
    z = base + rng.normal(0, 10, (17, 17)) * rng.choice([1e-3, 1.0, 100.0])
    qz = choose_quantizer(z, np.float64, codec_error=eps)
    dec = codes_to_heights(heights_to_codes(z, qz), qz)
    assert np.all(np.abs(dec - z) <= eps)
    check_pyramid(z, np.ones(z.shape, bool), 2, qz, codec_error=eps)


@pytest.mark.fast
def test_int_source_with_small_eps_stays_lossless():
    z = np.arange(25.0).reshape(5, 5)
    assert choose_quantizer(z, np.int16, codec_error=0.4).mode == "int"
    assert choose_quantizer(z, np.int16, codec_error=2.0).mode == "quantized"


# ----------------------------------------------------------------------------- access


@pytest.mark.fast
def test_decode_tile_direct_api_and_errors():
    z = np.arange(81.0).reshape(9, 9)
    qz = Quantizer("int")
    blobs = encode_pyramid(z, np.ones(z.shape, bool), 2, qz)
    top = decode_tile(blobs[(1, 0, 0)], None, qz)
    assert np.array_equal(top, z[::2, ::2])
    for x in (0, 1):
        for y in (0, 1):
            c = decode_tile(blobs[(0, x, y)], top, qz, (x % 2, y % 2))
            assert np.array_equal(c, z[4 * y : 4 * y + 5, 4 * x : 4 * x + 5])
    with pytest.raises(ValueError):
        decode_tile(blobs[(0, 0, 0)], None, qz)
    with pytest.raises(ValueError):
        decode_tile(b"\x09" + blobs[(0, 0, 0)][1:], top, qz)


@pytest.mark.fast
def test_a_padded_dem_pays_little_for_its_padding():
    """A DEM padded to 2**n + 1 (its last row and column invalid) costs about what the
    same surface costs with them valid: the top tile's invalid samples are filled
    outward from the data, so the tiles along the data's edge are predicted from it.
    Measured 1.04-1.05 lossless and 1.52-1.64 with ε = 1 (mostly the edge tiles'
    masks); with the invalid samples' interpolated predictions, 1.13-1.20 and 2.10-2.54."""
    n = 129
    y, x = np.mgrid[0:n, 0:n].astype(float)
    padded = (y < n - 1) & (x < n - 1)
    for z in (0.004 * ((x - 50) ** 2 + (y - 70) ** 2) + 6 * np.sin(x / 13) * np.cos(y / 17)
              + 3 * x, np.hypot(x - 64, y - 80) * 1.7 + 2 * np.sin((x + y) / 9)):
        for eps, bound in ((None, 1.1), (1.0, 1.8)):
            zz = np.round(z) if eps is None else z
            q = choose_quantizer(zz[padded], np.float64, codec_error=eps)
            whole = encode_pyramid(zz, np.ones((n, n), bool), 4, q)
            blobs = check_pyramid(zz, padded, 4, q, codec_error=eps or 0.0)
            assert sum(map(len, blobs.values())) <= bound * sum(map(len, whole.values()))


# Blobs and decoded codes written by the codec before the top tile's outward fill
# (a 9 x 9 int grid, 3 y + 2 x + (x y) // 3 on its first 7 rows and columns, t = 2, the
# linear predictor): the decoder must still give the codes that codec gave.
_BEFORE_FILL = {
    (0, 0, 0): "02000227c86e3860", (0, 0, 1): "020402fd6befbc", (0, 1, 0): "020402d1ac868202",
    (0, 1, 1): "020402d1a9f513fa", (1, 0, 0): "020502dc721af55ad926d39fff40b5e583e5fe",
}
_BEFORE_FILL_CODES = [
    [0, 2, 4, 6, 8, 10, 12, 6, 0], [3, 5, 7, 10, 12, 14, 17, 8, 0],
    [6, 8, 11, 14, 16, 19, 22, 11, 0], [9, 12, 15, 18, 21, 24, 27, 13, 0],
    [12, 15, 18, 22, 25, 28, 32, 16, 0], [15, 18, 22, 26, 29, 33, 37, 18, 0],
    [18, 22, 26, 30, 34, 38, 42, 21, 0], [9, 11, 13, 15, 17, 19, 21, 10, 0],
    [0, 0, 0, 0, 0, 0, 0, 0, 0]]


@pytest.mark.fast
def test_blobs_of_version_2_are_refused_and_the_fill_flag_is_where_it_belongs():
    """Blobs of version 2 (cell centres predicted along their column only; these were
    written by that codec before the top tile's outward fill) are refused in one line;
    a top blob written now has the ``filled`` flag, and the flag on a tile it does not
    belong to is refused."""
    qz = Quantizer("int")
    blobs = {k: bytes.fromhex(v) for k, v in _BEFORE_FILL.items()}
    for key, blob in blobs.items():
        with pytest.raises(ValueError, match="not a version-3 tile blob"):
            decode_tile(blob, None if key[0] == 1 else np.zeros((3, 3), np.int64), qz,
                        (key[1], key[2]))
    want = np.array(_BEFORE_FILL_CODES)
    i, j = np.mgrid[0:9, 0:9]
    z = (3 * i + 2 * j + (i * j) // 3).astype(float)
    now = encode_pyramid(z, (i < 7) & (j < 7), 2, qz, predictor="linear")
    assert now[(1, 0, 0)][1] & 32 and not any(b[1] & 32 for k, b in now.items() if k[0] == 0)
    levels = decode_all(now, 9, 2, qz)
    assert np.array_equal(levels[0][0][:7, :7], want[:7, :7])
    bad = now[(0, 1, 1)]
    with pytest.raises(ValueError, match="header"):
        decode_tile(bad[:1] + bytes([bad[1] | 32]) + bad[2:], levels[1][0], qz, (1, 1))
    full = encode_pyramid(z, np.ones((9, 9), bool), 2, qz)[(1, 0, 0)]  # all valid: no flag
    with pytest.raises(ValueError, match="header"):
        decode_tile(full[:1] + bytes([full[1] | 32]) + full[2:], None, qz)


# ----------------------------------------------------------------------------- invalid data


@pytest.mark.fast
def test_all_invalid_grid_and_tiles_absent():
    z = np.zeros((33, 33))
    assert encode_pyramid(z, np.zeros(z.shape, bool), 2, Quantizer("int")) == {}
    valid = np.zeros(z.shape, bool)
    valid[:9, :9] = True
    blobs = check_pyramid(np.round(fractal(33)), valid, 2, Quantizer("int"))
    assert (0, 3, 3) not in blobs and (0, 0, 0) in blobs and (0, 2, 0) in blobs  # shares col 8


@pytest.mark.fast
def test_one_sample_wide_strip_at_odd_column():
    size, t = 65, 3
    z = np.round(fractal(size, 5))
    valid = np.zeros(z.shape, bool)
    valid[:, 13] = True
    blobs = check_pyramid(z, valid, t, Quantizer("int"))
    # a level-1 tile holds column 13 only in its footprint (not among its own samples)
    assert (1, 0, 0) in blobs
    assert not tile_valid(blobs[(1, 0, 0)]).any()
    assert tile_valid(blobs[(0, 1, 0)])[:, 13 - 8].all()
    assert tile_valid(blobs[(0, 1, 0)]).sum() == 9


@pytest.mark.fast
def test_checkerboard_holes_cost_little():
    size = 129
    z = np.round(fractal(size, 6))
    i, j = np.indices(z.shape)
    valid = (i + j) % 2 == 0
    qz = Quantizer("int")
    blobs = check_pyramid(z, valid, 4, qz)
    full = encode_pyramid(z, np.ones(z.shape, bool), 4, qz)
    assert sum(map(len, blobs.values())) < 0.8 * sum(map(len, full.values()))
    for key, blob in blobs.items():
        s = 1 << key[0]
        tv = tile_valid(blob)
        sl = (slice(key[2] * 16 * s, (key[2] * 16 + 16) * s + 1, s),) + (
            slice(key[1] * 16 * s, (key[1] * 16 + 16) * s + 1, s),
        )
        assert np.array_equal(tv, valid[sl])


@pytest.mark.fast
def test_invalid_values_are_ignored():
    z = np.round(fractal(33, 8))
    valid = np.ones(z.shape, bool)
    valid[3:7, 10:25] = False
    z2 = z.copy()
    z2[~valid] = np.nan
    z3 = z.copy()
    z3[~valid] = 1e300
    qz = Quantizer("int")
    b2 = encode_pyramid(z2, valid, 2, qz)
    assert b2 == encode_pyramid(z3, valid, 2, qz)
    check_pyramid(z2, valid, 2, qz)


@pytest.mark.fast
def test_pyramid_shape_rejects_bad_sizes():
    with pytest.raises(ValueError):
        pyramid_shape(6, 3)
    with pytest.raises(ValueError):
        encode_pyramid(np.zeros((4, 4)), np.ones((4, 4), bool), 2, Quantizer("int"))
    assert pyramid_shape(3, 9) == (1, 1)


@pytest.mark.slow
def test_4097_encode_makes_every_tile():
    # (its time is benchmarks/bench_codec.py's, not a test's)
    z = np.round(fractal(4097, 9))
    valid = np.ones(z.shape, bool)
    blobs = encode_pyramid(z, valid, 6, Quantizer("int"))
    assert len(blobs) == sum(4**k for k in range(7))


_QUANTIZERS = [Quantizer("int", 1.0, 0.0), Quantizer("int", 0.1, -10000.0),
               Quantizer("quantized", 0.37, 12.5, 0.2), Quantizer("float", float_bits=32),
               Quantizer("float", float_bits=64)]


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(q=st.sampled_from(_QUANTIZERS), seed=st.integers(0, 2**31),
       mag=st.sampled_from([1.0, 1e3, 1e6]))
def test_the_compiled_roundtrip_is_the_codes_roundtrip(q, seed, mag):
    rng = np.random.default_rng(seed)
    z = rng.normal(0, mag, (9, 13))
    if q.mode == "float" and q.float_bits == 32:
        z = z.astype(np.float32).astype(np.float64)
    elif q.mode == "int":
        z = q.offset + np.rint((z - q.offset) / q.step) * q.step
    z[0, :3] = [0.0, -0.0, np.nan]
    valid = rng.random(z.shape) < 0.8
    valid[0, 2] = False
    want = np.where(valid, codes_to_heights(heights_to_codes(np.where(valid, z, 0.0), q), q),
                    np.nan)
    got = roundtrip(z, valid, q)
    assert got.tobytes() == want.tobytes()  # bit for bit, signed zeros and NaN included


@pytest.mark.fast
@settings(max_examples=10, deadline=None)
@given(q=st.sampled_from(_QUANTIZERS), seed=st.integers(0, 2**31))
def test_a_whole_grid_s_codes_and_roundtrip_on_every_core_are_one_thread_s(q, seed):
    """A grid above the one-thread size runs its rows on every core: the same codes and
    heights, bit for bit, as the rows in order, and a code out of range is still refused."""
    from geoterrain.codec.quantize import _codes_nb, _roundtrip_nb, valid_codes
    from geoterrain.core.threads import PARALLEL_MIN_SAMPLES

    rng = np.random.default_rng(seed)
    rows = PARALLEL_MIN_SAMPLES // 700 + 3
    z = rng.normal(0, 1e3, (rows, 700))
    valid = rng.random(z.shape) < 0.9
    mode = (1 if q.float_bits == 32 else 2) if q.mode == "float" else 0
    for kernel, dtype, fn in ((_roundtrip_nb, np.float64, roundtrip),
                              (_codes_nb, np.int64, valid_codes)):
        want = np.empty(z.shape, dtype)
        peak = kernel.serial(z, valid, mode, float(q.step), float(q.offset), want)
        got = np.empty(z.shape, dtype)
        assert kernel.parallel(z, valid, mode, float(q.step), float(q.offset), got) == peak
        assert got.tobytes() == want.tobytes() == fn(z, valid, q).tobytes()
    if q.mode == "int":
        z[rows - 1, 5] = q.offset + 2.0**63 * q.step
        with pytest.raises(ValueError, match="out of range"):
            valid_codes(z, np.ones(z.shape, bool), q)


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), places=st.integers(1, 4), m=st.integers(1, 8),
       binary=st.booleans(), dtype=st.sampled_from([np.float16, np.float32, np.float64]),
       mag=st.sampled_from([1.0, 1e3, 1e5, 1e11, 1e15]), t=st.integers(1, 3),
       widened=st.booleans())
def test_heights_on_a_finer_grid_are_integer_codes(seed, places, m, binary, dtype, mag, t,
                                                   widened):
    """Float heights written on a grid finer than 1 (d decimal places rounded to the
    source float, or multiples of 2^-m; a float64 source may hold float32 decimals,
    ``widened``) are coded as integers of the coarsest candidate grid that holds them
    all, and decode bit for bit on every path (a −0 as +0)."""
    rng = np.random.default_rng(seed)
    n = (1 << t) * 2 + 1
    raw = rng.normal(0, mag, (n, n))
    written = np.float32 if widened and dtype == np.float64 else dtype
    z = (np.rint(raw * 2.0**m) / 2.0**m if binary
         else np.rint(raw * 10.0**places) / 10.0**places).astype(written).astype(np.float64)
    z += 0.0  # a −0 decodes as +0, the same height (as in the "int" mode): bits below
    valid = (rng.random(z.shape) > 0.1) & np.isfinite(z)  # (float16 overflows past 65504)
    assume(valid.any())
    qz = choose_quantizer(z[valid], dtype)
    fin = z[valid]

    def holds(step, decimal, f32):  # independent of the quantizer: numpy on the values
        k = np.rint(fin / step)
        back = k / round(1 / step) if decimal else k * step
        if f32:
            back = back.astype(np.float32).astype(np.float64)
        return bool(np.all(np.abs(k) < 2.0**52) and np.array_equal(back, fin))

    from geoterrain.codec.quantize import FINE_STEPS
    small = np.dtype(dtype).itemsize <= 4  # decimals decode to float32; float64 tries both
    cands = [(s, d, f) for s, d in FINE_STEPS
             for f in ((d,) if small else (False, True) if d else (False,))]
    good = [c for c in cands if holds(*c)]
    if holds(1.0, False, False):
        assert qz.mode == "int" and qz.step == 1.0
    elif good:  # (none where the codes would pass 2^52: huge heights, fine steps)
        s, d, f = good[0]  # the coarsest that holds
        assert (qz.step, qz.mode == "decimal") == (s, d)
        if d:
            assert qz.float_bits == (32 if f else 64)
        assert qz.codec_error == 0.0
    else:
        assert qz.mode == "float"
    check_pyramid(z, valid, t, qz)  # every tile decodes to z bit for bit
    codes = heights_to_codes(np.where(valid, z, 0.0), qz)
    h, lo, hi, nv = tile_heights(codes, valid, qz, 1.0)
    assert np.array_equal(h[valid].view(np.int64), fin.view(np.int64))
    assert (lo, hi, nv) == (fin.min(), fin.max(), fin.size)
    assert np.array_equal(roundtrip(z, valid, qz)[valid].view(np.int64), fin.view(np.int64))


@pytest.mark.fast
def test_float32_decimals_in_a_float64_raster_are_decimal_codes():
    """A float64 raster widened from float32 decimals (1238.6f as a double) is coded as
    decimals rounded to float32, losslessly, and not as 64-bit floats."""
    z = np.float32([1238.6, 1009.3, 1264.9, -3.7]).astype(np.float64)
    q = choose_quantizer(z, np.float64)
    assert (q.mode, q.step, q.float_bits) == ("decimal", 0.1, 32)
    assert codes_to_heights(heights_to_codes(z, q), q).tobytes() == z.tobytes()
    exact = np.array([1238.6, 1009.3])  # the doubles nearest the decimals: float64 kept
    q = choose_quantizer(exact, np.float64)
    assert (q.mode, q.step, q.float_bits) == ("decimal", 0.1, 64)


@pytest.mark.fast
def test_a_float32_decimal_is_not_its_float64_product():
    """1238.6 in a float32 is not 12386 × 0.1 in any float: the decimal mode divides."""
    z = np.float32([1238.6, 1009.3, 1264.9]).astype(np.float64)
    assert not np.array_equal(np.rint(z / 0.1) * 0.1, z)
    q = choose_quantizer(z, np.float32)
    assert (q.mode, q.step, q.float_bits) == ("decimal", 0.1, 32)
    assert np.array_equal(codes_to_heights(heights_to_codes(z, q), q), z)


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), kind=st.sampled_from(["int", "tenths", "f32", "f64"]),
       dtype=st.sampled_from([np.int16, np.float32, np.float64]))
def test_choose_quantizer_sees_the_grid_and_the_float_width(seed, kind, dtype):
    rng = np.random.default_rng(seed)
    v = rng.normal(500, 300, 200)
    v = {"int": np.rint(v), "tenths": -10000 + np.rint((v + 10000) / 0.1) * 0.1,
         "f32": v.astype(np.float32).astype(np.float64), "f64": v}[kind]
    v[:2] = [np.nan, np.inf]  # non-finite values are ignored
    sc, off = (0.1, -10000.0) if kind == "tenths" else (None, None)
    q = choose_quantizer(v, dtype, scale=sc, offset=off)
    fin = v[np.isfinite(v)]
    s, o = (sc or 1.0), (off or 0.0)
    k = np.rint((fin - o) / s)
    on_grid = bool(np.all(np.abs(k) < 2.0**52) and np.array_equal(o + k * s, fin))
    assert (q.mode == "int") == on_grid
    if not on_grid:
        f32 = np.array_equal(fin.astype(np.float32).astype(np.float64), fin)
        small = np.dtype(dtype) == np.float32 or np.dtype(dtype).itemsize <= 4
        assert q.float_bits == (32 if f32 and small else 64)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 60), eps=st.sampled_from([0.01, 0.5, 3.0]),
       mag=st.sampled_from([1.0, 1e3, 1e7]))
def test_the_lossy_quantiser_is_the_numpy_one(seed, n, eps, mag):
    """The in-place median and the compiled roundtrip check choose what numpy's would:
    codes within ε / W of each height, W = FLOAT_BINS residual bins."""
    rng = np.random.default_rng(seed)
    v = rng.normal(0, mag, n)
    q = choose_quantizer(v.copy(), np.float64, codec_error=eps)
    off = float(np.round(np.median(v)))
    vmax = float(np.max(np.abs(v)))
    e = eps / FLOAT_BINS
    margin = 8.0 * float(np.finfo(np.float64).eps * (2.0 * vmax + 2.0 * abs(off) + e))
    step = 2.0 * (e - margin)
    for _ in range(8):
        qz = Quantizer("quantized", step, off, e)
        if float(np.max(np.abs(codes_to_heights(heights_to_codes(v, qz), qz) - v))) <= e:
            break
        step *= 1.0 - 1e-9
    assert (q.mode, q.step, q.offset, q.bins, q.codec_error) == ("quantized", step, off,
                                                                 FLOAT_BINS, eps)


@pytest.mark.fast
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), bits=st.sampled_from([32, 64]),
       special=st.booleans())
def test_compiled_float_heights_are_codes_to_heights(seed, bits, special):
    """A float store's decoded heights (the compiled bit-pattern map of tile_heights) are
    codes_to_heights' to the bit: signs, zeros, subnormals, infinities and NaN payloads."""
    from geoterrain.codec.quantize import (
        Quantizer,
        codes_to_heights,
        heights_to_codes,
        tile_heights,
    )

    rng = np.random.default_rng(seed)
    z = rng.standard_cauchy((9, 7)) * 10.0 ** rng.integers(-40, 40, (9, 7))
    if special:
        z.flat[:6] = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-310]
    q = Quantizer("float", float_bits=bits)
    codes = heights_to_codes(z, q)
    if bits == 32:  # any int32 pattern, NaN payloads included
        codes.flat[-4:] = rng.integers(-2**31, 2**31, 4)
    valid = np.ones(z.shape, bool)
    h, *_ = tile_heights(codes, valid, q, 1.0)
    want = codes_to_heights(codes, q)
    assert np.array_equal(h.view(np.int64), want.view(np.int64))


# ----------------------------------------------------------------------------- residual bins


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), eps=st.sampled_from([0.3, 0.5, 1.0, 2.0, 7.5]),
       grid=st.sampled_from([(1.0, 0.0), (0.1, -10000.0), (1 / 256, -32768.0), (0.25, 3.0),
                             (0.3, 0.7)]),
       holes=st.booleans(), t=st.integers(1, 4))
def test_grid_bins_stay_within_eps(seed, eps, grid, holes, t):
    """Heights on a grid (whole metres, Terrain-RGB's 0.1 m, Terrarium's 1/256, others)
    with a bound ε ≥ half the grid step: the grid's own codes in residual bins of odd
    width W, (W - 1) / 2 steps within ε, every decoded height within ε of its source
    (the float64 arithmetic included), whatever the pyramid."""
    sc, off = grid
    rng = np.random.default_rng(seed)
    n = 33
    codes = np.round(rng.normal(0, 3 / sc, (n, n)).cumsum(0).cumsum(1) / 8) + 1000 / sc
    z = off + codes * sc  # on the grid, as a decoder of the source computes it
    valid = rng.random(z.shape) > 0.2 if holes else np.ones(z.shape, bool)
    qz = choose_quantizer(z[valid], np.float64, codec_error=eps, scale=sc, offset=off)
    if 2 * eps <= sc:
        assert qz.mode == "int"
        return
    if qz.mode == "int":  # the float margin left no room for a bin
        assert sc <= eps < 1.01 * sc
        return
    if qz.step == sc:  # the grid's codes (else a grid float64 cannot check: 2ε / 15)
        assert qz.bins % 2 == 1 and qz.bins >= 3 and (qz.bins - 1) // 2 * sc <= eps
        assert (qz.bins + 1) // 2 * sc > eps * (1 - 1e-6) or qz.bins == MAX_BINS
    else:
        assert qz.bins == FLOAT_BINS
    check_pyramid(z, valid, t, qz, codec_error=eps)


@pytest.mark.fast
@pytest.mark.parametrize("eps", [0.5, 2.0])
def test_bins_shrink_a_smooth_surface(eps):
    """On a surface smooth against ε, residual bins (the prediction's error within the
    zero bin) take under half the bytes of each height rounded on its own to a step of
    2ε (which leaves the staircase of the rounding in every residual): measured 0.14 to
    0.22 on these two surfaces."""
    y, x = np.mgrid[0:129, 0:129].astype(float)
    v = np.ones((129, 129), bool)
    for z in (0.004 * ((x - 50) ** 2 + (y - 70) ** 2) + 6 * np.sin(x / 13) * np.cos(y / 17),
              np.hypot(x - 64, y - 64) * 1.7 + 2 * np.sin((x + y) / 9)):
        qb = choose_quantizer(z[v], np.float64, codec_error=eps)
        qp = Quantizer("quantized", 2 * eps * (1 - 1e-9), float(np.round(np.median(z))), eps)
        binned = check_pyramid(z, v, 4, qb, codec_error=eps)
        pointwise = check_pyramid(z, v, 4, qp, codec_error=eps)
        assert qb.bins == FLOAT_BINS and qp.bins == 1
        assert sum(map(len, binned.values())) < 0.5 * sum(map(len, pointwise.values()))


@pytest.mark.fast
def test_a_quantizer_without_bins_reads_as_before():
    """Metadata without ``bins`` (stores from before them) gives bins = 1, and bins = 1
    is not written (such stores stay readable by older code); a wrong width is refused."""
    q = Quantizer.from_json({"mode": "quantized", "step": 0.9, "offset": 0.0,
                             "codec_error": 0.5, "float_bits": 64})
    assert q.bins == 1 and "bins" not in q.to_json()
    assert Quantizer("quantized", 0.1, 0.0, 0.35, bins=7).to_json()["bins"] == 7
    for bad in (0, 2, MAX_BINS + 2, 7.0):
        with pytest.raises(ValueError, match="bins"):
            Quantizer("quantized", 0.1, 0.0, 0.35, bins=bad)
    with pytest.raises(ValueError, match="bins"):
        Quantizer("int", 1.0, 0.0, 0.0, bins=3)

"""The residual pyramid codec on a grid of several root tiles (issue 45): each root is a
top tile of its own, and the roots decode the same codes on the edges they share."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoterrain.codec.predict import fill_edges_first, fill_outward
from geoterrain.codec.pyramid import (
    decode_tile,
    decoded_codes,
    encode_decoded,
    encode_pyramid,
    roots_shape,
)
from geoterrain.codec.quantize import Quantizer, codes_to_heights, heights_to_codes

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

QUANTIZERS = {
    "int": Quantizer("int"),
    "binned": Quantizer("quantized", step=0.1, offset=0.0, codec_error=0.16, bins=3),
}


def decode_roots(blobs, shape, t, roots, qz):
    """Every stored tile decoded top-down from its own parent's decoding (each root from
    its blob alone); {level: (codes, covered)}, checking that neighbouring tiles, roots
    included, agree on the samples they share."""
    n, te = roots_shape(shape, t, roots)
    span, out, cache = 1 << te, {}, {}
    for lev in range(n - te + 1):
        s = 1 << lev
        m = ((shape[0] - 1) // s + 1, (shape[1] - 1) // s + 1)
        out[lev] = (np.zeros(m, np.int64), np.zeros(m, bool))
    for key in sorted(blobs, key=lambda k: -k[0]):  # parents first
        lev, x, y = key
        parent = cache.get((lev + 1, x // 2, y // 2))  # None for a root
        codes = cache[key] = decode_tile(blobs[key], parent, qz, (x % 2, y % 2))
        g, cov = out[lev]
        sl = (slice(y * span, y * span + span + 1), slice(x * span, x * span + span + 1))
        assert np.array_equal(g[sl][cov[sl]], codes[cov[sl]]), f"tile {key} disagrees"
        g[sl] = codes
        cov[sl] = True
    return out


def stored_keys(valid, te, lmax):
    """Tiles whose closed footprint holds a valid sample, by brute force."""
    keys = set()
    for lev in range(lmax + 1):
        span = 1 << (te + lev)
        for y in range((valid.shape[0] - 1) // span):
            for x in range((valid.shape[1] - 1) // span):
                if valid[y * span:(y + 1) * span + 1, x * span:(x + 1) * span + 1].any():
                    keys.add((lev, x, y))
    return keys


@st.composite
def root_grids(draw):
    te, lmax = draw(st.integers(1, 2)), draw(st.integers(1, 2))
    roots = draw(st.sampled_from([(2, 1), (1, 2), (2, 2), (3, 1)]))
    side = 1 << (te + lmax)
    shape = (roots[1] * side + 1, roots[0] * side + 1)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    z = np.cumsum(rng.normal(0, 3, shape), axis=1).round(1)
    valid = rng.random(shape) < draw(st.sampled_from([1.0, 0.9, 0.5]))
    # a lattice short of the extent, as a root grid's raster is: padding invalid
    valid[draw(st.integers(2, shape[0])):] = False
    valid[:, draw(st.integers(2, shape[1])):] = False
    return z, valid, te, roots


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(root_grids(), st.sampled_from(sorted(QUANTIZERS)), st.sampled_from(["linear", "cubic"]))
def test_roots_decode_as_encoded_and_agree_on_shared_edges(grid, qname, predictor):
    z, valid, t, roots = grid
    qz = QUANTIZERS[qname]
    if qname == "int":
        z = z.round()  # its heights are whole codes
    blobs, d = encode_decoded(z, valid, t, qz, predictor=predictor, roots=roots)
    n, te = roots_shape(z.shape, t, roots)
    assert set(blobs) == stored_keys(valid, te, n - te)
    assert np.array_equal(d, decoded_codes(z, valid, t, qz, predictor, roots))
    if not blobs:
        return
    levels = decode_roots(blobs, z.shape, t, roots, qz)
    for lev, (g, cov) in levels.items():  # closed loop: what the encoder predicted from
        s = 1 << lev
        assert np.array_equal(g[cov], d[::s, ::s][cov])
    g0, cov0 = levels[0]
    assert cov0[valid].all()
    h = codes_to_heights(g0, qz)
    if qname == "int":
        assert np.array_equal(g0[valid], heights_to_codes(z, qz)[valid])
    assert np.abs(h[valid] - z[valid]).max(initial=0) <= qz.codec_error + 1e-9


@pytest.mark.parametrize("predictor", ["linear", "cubic"])
def test_a_root_without_a_valid_sample_of_its_own_level_decodes_as_encoded(predictor):
    # root 1 holds (1, 5) but none of its level-1 samples: its blob has no mask and no
    # fill, while its corners come from root 0's data
    qz = QUANTIZERS["int"]
    z = np.zeros((5, 9))
    v = np.zeros((5, 9), bool)
    for (i, j), h in {(0, 0): 40, (1, 5): 7, (2, 2): -13}.items():
        z[i, j], v[i, j] = h, True
    blobs, d = encode_decoded(z, v, 1, qz, predictor=predictor, roots=(2, 1))
    assert (1, 1, 0) in blobs and (0, 2, 0) in blobs
    levels = decode_roots(blobs, z.shape, 1, (2, 1), qz)
    assert np.array_equal(levels[1][0], d[::2, ::2])
    assert levels[0][0][1, 5] == 7


@pytest.mark.parametrize("predictor", ["linear", "cubic"])
def test_one_root_is_the_square(predictor):
    rng = np.random.default_rng(3)
    z = np.cumsum(rng.normal(0, 3, (33, 33)), axis=0)
    valid = rng.random((33, 33)) < 0.8
    qz = QUANTIZERS["binned"]
    assert encode_pyramid(z, valid, 3, qz, predictor=predictor, roots=(1, 1)) == \
        encode_pyramid(z, valid, 3, qz, predictor=predictor)


def test_edges_first_fill_reads_each_edge_alone():
    rng = np.random.default_rng(5)
    f = rng.integers(-50, 50, (9, 9))
    known = rng.random((9, 9)) < 0.3
    known[::8, ::8] = True
    a = f.copy()
    fill_edges_first(a, known)
    g = f.copy()
    g[1:-1, 1:-1] = rng.integers(-50, 50, (7, 7))  # other interior data
    kg = known.copy()
    kg[1:-1, 1:-1] = rng.random((7, 7)) < 0.5
    b = g.copy()
    fill_edges_first(b, kg)
    for edge in (np.s_[0, :], np.s_[-1, :], np.s_[:, 0], np.s_[:, -1]):
        assert np.array_equal(a[edge], b[edge])
    c = f.copy()  # the plain fill reads the interior: the reason for this one
    fill_outward(c, known)
    assert np.array_equal(a[known], f[known]) and np.array_equal(c[known], f[known])


def test_roots_shape_refuses_a_grid_that_is_not_its_roots():
    with pytest.raises(ValueError, match="not 2 × 1 square roots"):
        roots_shape((17, 17), 2, (2, 1))

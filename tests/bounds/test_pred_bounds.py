"""Schema 14's PRED bounds payloads (log8codes.pred_residuals): codes as differences from
their parents' codes, decoded exactly, and small where the bounds are saturated or nested."""

from __future__ import annotations

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.log8codes import (
    _pred_centres,
    _pred_index,
    log8_codes,
    log8_exponent,
    log8_table,
    new_mask,
    pred_codes,
    pred_residuals,
)
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.vertexdata import CENTRES, PRED, decode_bounds, pack_bounds_v2
from geoterrain.core.grid import level_tiles
from geoterrain.ingest.synth import generate

pytestmark = pytest.mark.fast


@settings(max_examples=60, deadline=None)
@given(t=st.integers(1, 5), seed=st.integers(0, 2**31), k=st.integers(1, 4))
def test_pred_payloads_invert_whatever_the_codes(t, seed, k):
    """The map is a bijection on any codes, predictions right or wrong (mod 256)."""
    T = (1 << t) + 1
    W = np.random.default_rng(seed).integers(0, 256, (k, T, T)).astype(np.uint8)
    R = pred_residuals(W)
    assert R.shape == (k, int(new_mask(T).sum())) and R.dtype == np.uint8
    for n in range(k):
        np.testing.assert_array_equal(pred_codes(W[n, ::2, ::2], R[n]), W[n])


@settings(max_examples=60, deadline=None)
@given(t=st.integers(1, 5), seed=st.integers(0, 2**31), px=st.integers(0, 1),
       py=st.integers(0, 1), e=st.integers(-20, 20))
def test_pred_blobs_decode_to_their_codes(t, seed, px, py, e):
    """A tile's blob (no CENTRES shape: PRED) decodes to its codes when its parent's
    values at the shared vertices are those codes' (as in every store)."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    h = (T - 1) // 2
    codes = rng.integers(1, 256, (T, T)).astype(np.uint8)
    table = log8_table(e)
    parent = table[rng.integers(0, 256, (T, T))]
    parent[py * h: py * h + h + 1, px * h: px * h + h + 1] = table[codes[::2, ::2]]
    blob = pack_bounds_v2(codes, e, True, True, zstandard.ZstdCompressor(level=3))
    assert blob[1] & PRED and not blob[1] & CENTRES
    out = decode_bounds(blob, (T, T), parent, (px, py))
    np.testing.assert_array_equal(out[new_mask(T)], table[codes[new_mask(T)]])
    np.testing.assert_array_equal(out[::2, ::2],
                                  parent[py * h: py * h + h + 1, px * h: px * h + h + 1])
    # the same blob under a parent whose shared codes differ decodes to other codes:
    # the payload depends on them (what a δ_edge read must not use, terrain._bounds)
    other = parent.copy()
    other[py * h, px * h] = table[(int(codes[0, 0]) + 7) % 255]
    assert not np.array_equal(decode_bounds(blob, (T, T), other, (px, py)), out)


def _tile_windows(codes: np.ndarray, t: int, L: int) -> np.ndarray:
    w = level_tiles(codes, t, L)
    return w.reshape(-1, *w.shape[2:])


@settings(max_examples=25, deadline=None)
@given(n=st.integers(3, 6), t=st.integers(2, 3), seed=st.integers(0, 2**31),
       relief=st.sampled_from([0.1, 10.0, 1000.0]), holes=st.booleans())
def test_parents_bound_their_children_so_the_payload_is_a_gap(n, t, seed, relief, holes):
    """Seed 002 §2.4: a saturated δ and a nested r never exceed a parent's, and the coded
    values keep it (one monotone code map). So each prediction (the smaller code of a
    centre's two apex corners, of a midpoint's one or two neighbouring centres) is ≥ the
    code, and the payload holds (prediction − code) without wrapping. The other diagonal
    (the corners the split joins) fails it. (t ≥ 2: a tile's first cell then has the
    grid's union-jack parity; with t = 1 every other tile's cells are swapped, which
    costs bytes, not exactness.)"""
    t = min(t, n - 1)
    N = (1 << n) + 1
    z = generate("fbm", N, seed=seed % 10_000) * relief
    ok = np.ones((N, N), bool)
    if holes:
        ok[N // 3: N // 3 + 3, : N // 2] = False
    z = np.where(ok, z, np.nan)
    d = vertex_errors(np.where(ok, z, 0.0), ok)
    ii, jj = np.indices((N, N)).astype(np.float64)
    rc, _ = radius_codes(jj, -ii, np.where(ok, z, 0.0), ok)
    dc = log8_codes(d, log8_exponent(d))
    swapped = 0
    for codes in (dc, rc):
        for L in range(n - t):  # tiles below the top: their even samples are the parent's
            W = _tile_windows(codes, t, L).astype(np.int16)
            T = W.shape[1]
            other, n1, n2, main = _pred_index(T)
            assert (_pred_centres(W, main) >= W[:, 1::2, 1::2]).all()
            ext = np.concatenate([W.reshape(len(W), -1), np.full((len(W), 1), 255)], axis=1)
            assert (np.minimum(ext[:, n1], ext[:, n2]) >= ext[:, other]).all()
            # the diagonal's ends instead of the apexes
            h = (W.shape[1] - 1) // 2
            main = (np.add.outer(np.arange(h), np.arange(h)) % 2 == 0)[None]
            a, b = W[:, 0:-2:2, 0:-2:2], W[:, 0:-2:2, 2::2]
            c, dd = W[:, 2::2, 0:-2:2], W[:, 2::2, 2::2]
            ends = np.where(main, np.minimum(a, dd), np.minimum(b, c))
            swapped += int((ends < W[:, 1::2, 1::2]).sum())
    if relief >= 10 and not holes and n >= 5:
        assert swapped > 0


def test_pred_payloads_are_smaller_on_a_real_delta():
    """On a DEM's saturated δ, the PRED payloads compress to less than the raw codes."""
    N, t = 129, 4
    z = generate("fbm", N, seed=3) * 300
    ok = np.ones((N, N), bool)
    d = vertex_errors(z, ok)
    dc = log8_codes(d, log8_exponent(d))
    W = _tile_windows(dc, t, 1)
    raw = W[:, new_mask(W.shape[1])]
    c = zstandard.ZstdCompressor(level=3)
    assert len(c.compress(pred_residuals(W).tobytes())) < 0.95 * len(c.compress(raw.tobytes()))


@pytest.mark.parametrize("flag", [4, 8, 16, 32, 64])
def test_a_pred_blob_with_another_shape_flag_is_refused(flag):
    codes = np.random.default_rng(0).integers(1, 256, (9, 9)).astype(np.uint8)
    blob = bytearray(pack_bounds_v2(codes, 0, True, True, zstandard.ZstdCompressor()))
    assert blob[1] & PRED
    blob[1] |= flag
    with pytest.raises(ValueError, match="bounds blob"):
        decode_bounds(bytes(blob), (9, 9), np.zeros((9, 9), np.float32), (0, 0),
                      derive=lambda *a: np.zeros((9, 9), np.float32),
                      base=np.zeros((9, 9), np.float32))


@pytest.mark.parametrize("case", ["no parent", "top tile", "float16", "even side",
                                  "parent shape"])
def test_a_damaged_or_misplaced_pred_blob_is_refused(case):
    codes = np.random.default_rng(1).integers(1, 256, (9, 9)).astype(np.uint8)
    blob = bytearray(pack_bounds_v2(codes, 0, True, True, zstandard.ZstdCompressor()))
    shape, parent = (9, 9), np.zeros((9, 9), np.float32)
    if case == "no parent":
        parent = None
    elif case == "top tile":
        blob[1] &= ~1  # NEW_ONLY off
    elif case == "float16":
        blob[1] &= ~2  # LOG8 off
    elif case == "even side":
        shape, parent = (8, 8), np.zeros((8, 8), np.float32)
    else:
        parent = np.zeros((5, 5), np.float32)
    with pytest.raises(ValueError, match="predicted bounds blob"):
        decode_bounds(bytes(blob), shape, parent, (0, 0))


def test_a_store_decodes_every_level_to_the_whole_grid_codes(tmp_path):
    """A store's δ above level 0 (PRED blobs) decodes to the log8 codes of the whole
    grid's exact saturated δ (vertex_errors), coded independently here."""
    import geoterrain
    from tests.conftest import write_tif

    z = np.random.default_rng(5).normal(0, 5, (65, 65)).cumsum(0).cumsum(1)
    src = write_tif(tmp_path / "d.tif", z)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "d.geoterrain", tile_size=16,
                                              root_grid=False))
    h, v = t.level_heights(0)
    d = vertex_errors(np.where(v, t.frame.z(h), 0.0), v)
    e = int(np.int8(np.uint8(t._blob((1, 0, 0), "delta")[2])))
    want = log8_table(e)[log8_codes(d, e)]
    flags = set()
    for (L, x, y) in t.tile_info:
        if L == 0:
            continue
        flags.add(t._blob((L, x, y), "delta")[1] & PRED)
        s, span = 1 << L, 16 << L
        np.testing.assert_array_equal(t.tile_delta(L, x, y),
                                      want[y * span: y * span + span + 1: s,
                                           x * span: x * span + span + 1: s])
    assert PRED in flags


def test_a_damaged_or_misplaced_pred_blob_in_a_store_is_refused_in_one_line(tmp_path):
    """A stranger's store: PRED on a top tile without SLACK (schema 23's top δ is PRED
    with SLACK), beside RING, without log8 codes, or a payload one byte long: each read
    is a one-line StoreCorruptError."""
    import geoterrain
    from geoterrain.bounds.vertexdata import LOG8, NEW_ONLY, RING, SLACK, VERSION_2
    from geoterrain.exceptions import StoreCorruptError
    from tests.conftest import write_tif

    z = np.random.default_rng(6).normal(0, 5, (65, 65)).cumsum(1)
    src = write_tif(tmp_path / "d.tif", z)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "d.geoterrain", tile_size=16,
                                              root_grid=False))
    blob = t._blob
    top = t.grid.top_level
    d110 = blob((1, 1, 0), "delta")
    assert d110[1] & PRED

    def flagged(b, add=0, drop=0):
        return b[:1] + bytes([(b[1] | add) & ~drop]) + b[2:]

    short = bytes([VERSION_2, NEW_ONLY | LOG8 | PRED, 0]) + zstandard.ZstdCompressor().compress(
        b"\0")
    assert blob((top, 0, 0), "delta")[1] & (PRED | SLACK | NEW_ONLY) == PRED | SLACK
    cases = [((top, 0, 0), "delta", flagged(blob((top, 0, 0), "delta"), 0, SLACK)),
             ((1, 1, 0), "delta", flagged(d110, RING)),
             ((1, 1, 0), "delta", flagged(d110, 0, LOG8)),
             ((1, 1, 0), "delta", short),
             ((1, 1, 0), "radius", flagged(blob((1, 1, 0), "radius"), PRED))]
    for key, kind, bad in cases:
        t._blob = lambda k, kd, key=key, kind=kind, bad=bad: (bad if (k, kd) == (key, kind)
                                                             else blob(k, kd))
        t.clear_cache()
        with pytest.raises(StoreCorruptError, match=f"{kind} cannot be decoded") as ex:
            getattr(t, f"tile_{kind}")(*key)
        assert "\n" not in str(ex.value)

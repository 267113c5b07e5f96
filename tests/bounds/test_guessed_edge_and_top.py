"""Schema 23's payloads guessed from a tile's heights (geoterrain/bounds/ownguess.py):
the top tile's δ level by level inside it (``top_payload_own``), a δ_edge below the top
against its guess from the heights with the padding replicated (``edge_own_codes``,
``edge_payload_own``), the top tile's δ_edge level by level (``top_edge_payload_own``).
Each decodes exactly whatever the guess; one coded against other heights, or bytes the
encoder would not write, is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.log8codes import log8_table, new_mask
from geoterrain.bounds.ownguess import (
    edge_codes_own,
    edge_own_codes,
    edge_payload_own,
    own_codes,
    top_codes_own,
    top_edge_codes_own,
    top_edge_payload_own,
    top_payload_own,
    top_steps,
)
from geoterrain.bounds.vertexdata import DIFF, LOG8, NEW_ONLY, PRED, SLACK, VERSION_2, decode_bounds


def _codes(rng, shape, spread):
    # log8 codes near a smooth field (as δ's are), a few +inf (255)
    base = rng.integers(40, 60)
    c = np.clip(base + rng.integers(-spread, spread + 1, shape), 0, 254).astype(np.uint8)
    c[rng.random(shape) < 0.05] = 255
    return c


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), t=st.integers(1, 5), spread=st.integers(0, 40),
       good=st.booleans())
def test_the_top_tile_by_levels_decodes_exactly_whatever_the_guess(seed, t, spread, good):
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    c = _codes(rng, (T, T), spread)
    # a good guess: the codes themselves lowered a little; a bad one: noise
    lo = {s: (np.maximum(c[::s, ::s].astype(int) - rng.integers(0, 3), 0).astype(np.uint8)
              if good else rng.integers(0, 256, ((T - 1) // s + 1,) * 2).astype(np.uint8))
          for s in top_steps(T)}
    p = top_payload_own(c, lo.get)
    assert (top_codes_own(p, T, lo.get) == c).all()
    other = {s: g ^ 1 for s, g in lo.items()}  # another tile's heights
    if top_payload_own(c, other.get)[0] != p[0]:  # a one-byte check: it can collide
        with pytest.raises(ValueError, match="other heights"):
            top_codes_own(p, T, other.get)
    with pytest.raises(ValueError, match="other heights"):  # no corners
        top_codes_own(p[:3], T, lo.get)


def test_top_steps_are_the_levels_inside_a_tile():
    assert top_steps(3) == [1] and top_steps(65) == [32, 16, 8, 4, 2, 1]
    for bad in (2, 4, 64):
        with pytest.raises(ValueError):
            top_steps(bad)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), t=st.integers(1, 5), pred=st.booleans())
def test_an_edge_payload_decodes_exactly_and_keeps_delta_where_finite(seed, t, pred):
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    b = _codes(rng, (T, T), 5)
    b[rng.random((T, T)) < 0.4] = 255
    c = b.copy()
    inf = b == 255
    c[inf] = rng.integers(0, 256, int(inf.sum()))
    c[::2, ::2] = rng.integers(0, 256, c[::2, ::2].shape)  # the parent's codes
    g = rng.integers(0, 256, (T, T)).astype(np.uint8)
    p = edge_payload_own(c, b, g, pred)
    got = edge_codes_own(p, b, g, c[::2, ::2] if pred else None)
    new = new_mask(T)
    assert (got[new] == c[new]).all()
    if edge_payload_own(c, b, g ^ 1, pred)[0] != p[0]:  # a one-byte check: can collide
        with pytest.raises(ValueError, match="other heights"):
            edge_codes_own(p, b, g ^ 1, c[::2, ::2] if pred else None)
    # δ_edge below a finite δ: not this layout (the writer keeps the plain DIFF blob)
    fin = np.flatnonzero(new.ravel() & (b.ravel() != 255))
    if len(fin):
        c2 = c.copy()
        c2.ravel()[fin[0]] ^= 1
        assert edge_payload_own(c2, b, g, pred) is None


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), t=st.integers(1, 4))
def test_the_top_tile_s_delta_edge_by_levels_decodes_exactly(seed, t):
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    b = _codes(rng, (T, T), 5)
    b[rng.random((T, T)) < 0.3] = 255
    c = b.copy()
    c[b == 255] = rng.integers(0, 256, int((b == 255).sum()))
    c[::T - 1, ::T - 1] = rng.integers(0, 256, (2, 2))  # the corners as they are
    g = {s: rng.integers(0, 256, ((T - 1) // s + 1,) * 2).astype(np.uint8)
         for s in top_steps(T)}
    p = top_edge_payload_own(c, b, g.get)
    assert (top_edge_codes_own(p, b, g.get) == c).all()
    other = {s: v ^ 1 for s, v in g.items()}  # another tile's heights
    if top_edge_payload_own(c, b, other.get)[0] != p[0]:  # one byte: it can collide
        with pytest.raises(ValueError, match="other heights"):
            top_edge_codes_own(p, b, other.get)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), H=st.integers(3, 40), W=st.integers(3, 40),
       holes=st.booleans())
def test_the_edge_guess_is_own_codes_of_the_edge_replicated_grid(seed, H, W, holes):
    """A level-0 tile's edge_own_codes, from its own heights, is own_codes of the whole
    padded grid with edgepad.edge_support's replication (0 where the vertex's diamond
    misses the data): the guess the writer and the reader share needs no other tile."""
    from geoterrain.bounds.edgepad import edge_support
    from geoterrain.core.grid import Grid

    rng = np.random.default_rng(seed)
    g = Grid.for_shape(H, W, 8)
    N = g.extent[0] if hasattr(g, "extent") else g.size
    z = rng.normal(0, 5, (H, W)).cumsum(0)
    ok = np.ones((H, W), bool)
    if holes:
        ok &= rng.random((H, W)) > 0.2
    Z = np.full((N, N), np.nan)
    V = np.zeros((N, N), bool)
    Z[:H, :W], V[:H, :W] = np.where(ok, z, np.nan), ok
    Zr, okr = edge_support(Z, V, g)
    stand, e, T = 0.5, -4, g.tile_samples
    for y in range(-(-H // (T - 1))):
        for x in range(-(-W // (T - 1))):
            r0, c0 = y * (T - 1), x * (T - 1)
            if r0 + T > N or c0 + T > N:
                continue
            tile = np.s_[r0:r0 + T, c0:c0 + T]
            got = edge_own_codes(Z[tile], V[tile], stand, e, H - r0, W - c0)
            want = own_codes(Zr, okr, stand, e, np.array([[r0, c0]]), T, 1)[0]
            ii, jj = np.indices((T, T))
            want[(r0 + ii - 1 > H - 1) | (c0 + jj - 1 > W - 1)] = 0
            assert (got == want).all(), (y, x)


@pytest.mark.parametrize("case", ["no base", "no heights", "ring", "float16", "no parent"])
def test_a_stranger_s_guessed_edge_blob_is_refused(case):
    T = 5
    b = np.full((T, T), 255, np.uint8)
    c = np.full((T, T), 9, np.uint8)
    g = np.full((T, T), 9, np.uint8)
    blob = bytearray(bytes([VERSION_2, NEW_ONLY | LOG8 | DIFF | PRED, 0])
                     + edge_payload_own(c, b, g))
    base = np.full((T, T), np.inf, np.float32)
    parent, own = np.zeros((T, T), np.float32), (lambda e, s=1: g)
    if case == "no base":
        base = None
    elif case == "no heights":
        own = None
    elif case == "ring":
        blob[1] |= 4
    elif case == "float16":
        blob[1] &= ~LOG8
    else:
        parent = None
    with pytest.raises(ValueError, match="guessed difference bounds blob"):
        decode_bounds(bytes(blob), (T, T), parent, (0, 0), None, base, None, own)
    if case == "no base":  # the same blob, whole: decodes
        out = decode_bounds(bytes(blob), (T, T), np.zeros((T, T), np.float32), (0, 0), None,
                            np.full((T, T), np.inf, np.float32), None, own)
        assert (out[new_mask(T)] == log8_table(0)[9]).all()


def test_a_whole_tile_s_guessed_blobs_need_the_tile_s_heights():
    T = 5
    c = np.full((T, T), 9, np.uint8)
    lo = {s: np.zeros(((T - 1) // s + 1,) * 2, np.uint8) for s in top_steps(T)}
    blob = bytes([VERSION_2, LOG8 | PRED | SLACK, 0]) + top_payload_own(c, lo.get)
    out = decode_bounds(blob, (T, T), None, (0, 0), None, None, None,
                        lambda e, s=1: lo[s])
    assert (out == log8_table(0)[9]).all()
    for own, parent in ((None, None), (lambda e, s=1: lo[s], np.zeros((T, T), np.float32))):
        with pytest.raises(ValueError, match="heights|whole tile"):
            decode_bounds(blob, (T, T), parent, (0, 0), None, None, None, own)
    eb = bytes([VERSION_2, LOG8 | DIFF | PRED | SLACK, 0]) + top_edge_payload_own(
        c, np.full((T, T), 255, np.uint8), lo.get)
    with pytest.raises(ValueError, match="whole tile's guessed difference"):
        decode_bounds(eb, (T, T), None, (0, 0), None, None, None, lambda e, s=1: lo[s])


def test_an_r_blob_whose_centre_guesses_are_exact_is_its_header_alone():
    """Schema 23: a level-0 CENTRES-with-PRED r whose every centre equals its guess holds
    no payload: it decodes to the guesses; an empty payload in any zstd layout is
    refused."""
    import zstandard

    from geoterrain.bounds.vertexdata import CENTRES

    T = 5
    g = np.array([[3, 4], [5, 6]], np.uint8)
    head = bytes([VERSION_2, NEW_ONLY | LOG8 | CENTRES | PRED, 0])
    out = decode_bounds(head, (T, T), np.zeros((T, T), np.float32), (0, 0), None, None,
                        lambda e: g)
    assert (out[1::2, 1::2] == log8_table(0)[g]).all()
    for flags in (NEW_ONLY | LOG8 | CENTRES, NEW_ONLY | LOG8 | PRED):
        with pytest.raises((ValueError, zstandard.ZstdError)):
            decode_bounds(bytes([VERSION_2, flags, 0]), (T, T), np.zeros((T, T), np.float32),
                          (0, 0), None, None, lambda e: g)

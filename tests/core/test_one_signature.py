"""Helpers that their compiled callers call with a literal argument would compile once per
literal (issue 51, a quick first run): the callers pass those arguments as plain int64 or
bool values instead, so each helper compiles one specialisation, and a reader loads what a
writer compiled. Each test compiles the caller's Python function afresh (no cache) and
checks every signature its helper was typed with."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from numba import types


def _fresh_compile(kernel, *args) -> None:
    """Compile ``kernel``'s Python function afresh (no cache) for ``args``: its callees
    are typed, so compiled or loaded, with the argument types the caller passes them."""
    numba.njit(cache=False)(kernel.py_func).compile(tuple(numba.typeof(a) for a in args))


def test_the_normal_helpers_take_the_axis_as_an_int64():
    from geoterrain.bounds.normals import codes, maps

    n = 6
    j, i = np.meshgrid(np.arange(float(n)), np.arange(float(n)))
    z = np.arange(n * n, dtype=np.float64).reshape(n, n)
    v = np.ones((n, n), bool)
    out = np.empty((n, n, 3), np.float32)
    _fresh_compile(maps._normals_nb, j, -i, z, v, True, out)
    rr = np.array([0, 0], np.int64)
    X, Y = j[None], -i[None]
    _fresh_compile(codes._ring_guess_nb, z, v, X, Y, rr[:1], rr[:1], rr, rr, 255.0,
                   np.empty((1, 2, 2), np.uint8))
    for helper in (maps._tangent_nb, maps._horn_nb):
        assert helper.signatures
        assert all(sig[6] == types.int64 for sig in helper.signatures), helper.signatures
    assert maps._unit_cross.signatures
    assert all(sig[7] == sig[8] == types.int64 for sig in maps._unit_cross.signatures)


def test_the_gap_coder_compiles_once_for_each_direction():
    """The encoder codes with a run-time flag (one specialisation for every caller); the
    decoder, :func:`gapcoder._gap_decode`, through the coder's decoding twin with a
    literal False: its own specialisation, the encoder's branches folded away (4-5
    times faster a value)."""
    from geoterrain.bounds import gapcoder

    r = np.array([0, 3, 200], np.int64)
    gap = np.array([0, 5, 255], np.int64)
    _fresh_compile(gapcoder._encode_gaps_rows, r[None], gap[None], np.zeros((1, 64), np.uint8),
                   np.zeros(1, np.int64))
    d = gapcoder.GapDecoder(gapcoder.encode_gaps(r, gap))
    _fresh_compile(gapcoder._gap_decode, d.S, d.buf, d.m, np.zeros(3, np.int64), gap)
    assert d.take(gap).tolist() == r.tolist()
    sigs = gapcoder._gap_values.signatures
    assert len(sigs) == 1 and sigs[0][0] == types.boolean, sigs
    sigs = gapcoder._gap_values_dec.signatures
    assert len(sigs) == 1 and sigs[0][0] == types.literal(False), sigs
    assert len(gapcoder._gap_decode.signatures) == 1, gapcoder._gap_decode.signatures


@pytest.mark.fast
def test_the_cast_call_sites_keep_their_arithmetic():
    """The normals' helpers with a run-time axis give what the straight-line branch and
    the numpy oracle give (their bits are checked against main in the store's bytes)."""
    from geoterrain.bounds.normals import normal_map
    from geoterrain.testing.reference import normal_map_reference

    rng = np.random.default_rng(3)
    j, i = np.meshgrid(np.arange(17.0), np.arange(13.0))
    z = rng.normal(size=i.shape)
    v = rng.random(i.shape) > 0.2
    for kernel in ("central", "horn"):
        got = normal_map(j, -i, z, v, kernel)
        want = normal_map_reference(j, -i, z, v, kernel)
        assert np.abs(got - want).max() < 1e-6


def test_mid16_takes_its_steps_as_int64_from_both_callers():
    from geoterrain.codec import entropy, predict

    t = 5
    parent = np.arange(t * t, dtype=np.int64).reshape(t, t) * 4
    ok = np.ones((t, t), bool)
    _fresh_compile(entropy._encode_tile, np.zeros(256, np.uint8), parent, 0, 1, 2, True,
                   parent.copy(), ok, entropy.MASK_ALL_VALID, 1)
    _fresh_compile(predict.cubic_child, parent, 0, 0, 2, np.zeros(16, np.int64),
                   np.empty((t, t), np.int64))
    sigs = predict._mid16.signatures
    assert len(sigs) == 1 and all(a == types.int64 for a in sigs[0][1:]), sigs



def test_the_normal_helpers_take_one_layout_of_z():
    """``_normals_nb`` passes its helpers an 'A' view of z, as ``_ring_guess_nb``'s tile
    views are: one ``_tangent_nb`` for both (two on main, a C and an A z)."""
    from geoterrain.bounds.normals import codes, maps

    n = 6
    j, i = np.meshgrid(np.arange(float(n)), np.arange(float(n)))
    z = np.arange(n * n, dtype=np.float64).reshape(n, n)
    v = np.ones((n, n), bool)
    for horn in (False, True):
        _fresh_compile(maps._normals_nb, j, -i, z, v, horn, np.empty((n, n, 3), np.float32))
    rr = np.array([0, 0], np.int64)
    _fresh_compile(codes._ring_guess_nb, z, v, j[None], -i[None], rr[:1], rr[:1], rr, rr,
                   255.0, np.empty((1, 2, 2), np.uint8))
    for helper in (maps._tangent_nb, maps._horn_nb):
        assert helper.signatures
        assert all(sig[2].layout == "A" for sig in helper.signatures), helper.signatures


def test_the_ring_guess_gets_a_c_lattice_at_every_level(monkeypatch, tmp_path):
    """The in-memory writer copies a level above 0 C-contiguous for the ring guesses, as
    level 0 and the streaming windows are: ``_ring_guess_nb`` compiles one layout."""
    from geoterrain.bounds.normals import codes
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.pipeline import preprocess

    seen = []
    real = codes._ring_guess_nb

    def spy(z, valid, *rest):
        seen.append((z.flags.c_contiguous, valid.flags.c_contiguous, z.shape))
        return real(z, valid, *rest)

    monkeypatch.setattr(codes, "_ring_guess_nb", spy)
    src = tmp_path / "dem.tif"
    write_geotiff(src, generate("fbm", 129, seed=2))
    preprocess(src, tmp_path / "s.geoterrain", tile_size=32)
    assert len({s[2] for s in seen}) > 1, seen  # level 0 and a level above it
    assert all(c and cv for c, cv, _ in seen), seen


def test_the_decoders_run_their_own_twin_of_the_coder():
    """The decoders call a twin of the coder's chain (the same code objects, their own
    cache entries) whose per-decision helpers are calls: decoding compiles none of the
    encoder's chain, and its round trips hold."""
    from geoterrain.codec import entropy

    for name in entropy._DEC_CALLS + entropy._DEC_CHAIN:
        twin, f = entropy._DEC_GLOBALS[name], getattr(entropy, name)
        assert twin.py_func.__code__ is f.py_func.__code__
        assert twin.py_func.__qualname__ == f.py_func.__qualname__ + "_dec"
        want = "never" if name in entropy._DEC_CALLS else f.targetoptions.get("inline", "never")
        assert twin.targetoptions.get("inline", "never") == want
    assert entropy._bit.targetoptions["inline"] == "always"  # the encoder's, inlined
    assert entropy._tile.targetoptions["inline"] == entropy._top.targetoptions["inline"] \
        == "always"  # into their entry points: one LLVM optimisation of the chain less
    parent = np.arange(25, dtype=np.int64).reshape(5, 5) * 4
    child = np.arange(25, dtype=np.int64).reshape(5, 5) * 2 + 3
    ok = np.ones((5, 5), bool)
    ok[1, 2] = False
    data = np.frombuffer(entropy.encode_tile(child, ok, parent, (1, 0), True,
                                             entropy.MASK_STORED), np.uint8)
    numba.njit(cache=False)(entropy.decode_tile.py_func).compile(
        (numba.typeof(data), numba.typeof(parent), types.int64, types.int64, types.boolean,
         types.int64, types.int64))
    out, got_ok, exact = entropy.decode_tile(data, parent, 1, 0, True, entropy.MASK_STORED)
    assert exact and got_ok.tolist() == ok.tolist()
    new = ok.copy()
    new[::2, ::2] = False  # the even samples are the parent's
    assert out[new].tolist() == child[new].tolist()
    assert entropy.decode_mask(data, 5, entropy.MASK_STORED).tolist() == ok.tolist()
    for name in ("_child", "_tile", "_value", "_length", "_mask"):  # never typed to decode
        sigs = getattr(entropy, name).signatures
        assert not any(s[0] == types.literal(False) for s in sigs), (name, sigs)
    assert entropy._DEC_GLOBALS["_child"].signatures


def test_the_stream_check_and_the_field_error_compile_once():
    """``_canonical`` sees a writeable buffer from the tile decoder and the gap decoder
    alike; ``_field_lines`` passes ``_field_err`` an int64 index, never a literal 0."""
    from geoterrain.bounds import delta, gapcoder
    from geoterrain.codec import entropy

    top = np.arange(25, dtype=np.int64).reshape(5, 5) ** 2
    data = np.frombuffer(entropy.encode_top(top, np.ones((5, 5), bool), 2, True,
                                            entropy.MASK_ALL_VALID), np.uint8)
    assert data.flags.writeable is False
    back, _, exact = entropy.decode_top(data, 2, True, entropy.MASK_ALL_VALID)
    assert exact and back.tolist() == top.tolist()
    r = np.array([0, 3, 200], np.int64)
    d = gapcoder.GapDecoder(gapcoder.encode_gaps(r, np.array([0, 5, 255], np.int64)))
    d.take(np.array([0, 5, 255], np.int64))
    d.check()
    sigs = entropy._canonical.signatures
    assert len(sigs) == 1 and sigs[0][0].mutable, sigs
    row = np.linspace(0.0, 1.0, 5)
    H = np.zeros((2, 2, 8))
    V = np.zeros((2, 2, 8))
    _fresh_compile(delta._field_lines, row, 0, 0, 4, 1, True, 0.0, 0.1, 0.0, 0.1,
                   (H, V, 4, 0))
    sigs = delta._field_err.signatures
    assert sigs and all(s[5] == types.int64 for s in sigs), sigs

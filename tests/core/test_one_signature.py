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


def test_the_gap_coder_compiles_once_for_both_directions():
    from geoterrain.bounds import gapcoder

    r = np.array([0, 3, 200], np.int64)
    gap = np.array([0, 5, 255], np.int64)
    _fresh_compile(gapcoder._encode_gaps_rows, r[None], gap[None], np.zeros((1, 64), np.uint8),
                   np.zeros(1, np.int64))
    d = gapcoder.GapDecoder(gapcoder.encode_gaps(r, gap))
    assert d.take(gap).tolist() == r.tolist()
    sigs = gapcoder._gap_values.signatures
    assert len(sigs) == 1 and sigs[0][0] == types.boolean, sigs


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


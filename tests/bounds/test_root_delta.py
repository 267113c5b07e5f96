"""δ on a rectangular root grid (issue 45): the compiled kernel against the numpy
reference, and both against a brute force over the triangles of the roots' bintree
(bisected here by hand), with padding beyond the raster as the root grid has it."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import _raw_delta, vertex_errors
from geoterrain.core.bintree import root_triangles, vertex_children, vertex_depth
from geoterrain.core.rounding import round_up
from geoterrain.testing.reference import saturate, vertex_errors_reference

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

ROOTS = st.sampled_from([(1, 1), (2, 1), (1, 2), (3, 2)])


@st.composite
def root_dem(draw, max_n=4):
    n = draw(st.integers(1, max_n))
    rx, ry = draw(ROOTS)
    S = 1 << n
    R, C = ry * S + 1, rx * S + 1
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["noise", "smooth", "int"]))
    if kind == "noise":
        z = rng.normal(0, 10, (R, C))
    elif kind == "smooth":
        z = np.cumsum(np.cumsum(rng.normal(0, 1, (R, C)), 0), 1)
    else:
        z = rng.integers(-50, 50, (R, C)).astype(np.float64)
    valid = rng.random((R, C)) < draw(st.sampled_from([1.0, 1.0, 0.95, 0.7]))
    # the raster in the top-left corner, padding beyond (as a root grid pads it)
    rows, cols = draw(st.integers(2, R)), draw(st.integers(2, C))
    valid[rows:] = False
    valid[:, cols:] = False
    z[~valid] = rng.normal(0, 1e6, (~valid).sum())  # never read
    return z, valid, n, (rx, ry)


def _brute_raw(z, valid, n, roots):
    """Raw δ of every split vertex from the triangles whose hypotenuse it splits: the
    max |z − plane| over the valid samples they hold, +inf if they also hold an invalid
    one, 0 if none is valid. Each depth's triangles against every sample at once."""
    err, nv, ni = (np.zeros(z.shape) for _ in range(3))
    a, b, c = root_triangles(n, roots)
    II, JJ = (v.ravel()[None, :] for v in np.indices(z.shape))
    zs, vs = z.ravel()[None, :], valid.ravel()[None, :]
    for _ in range(2 * n):
        ai, aj, bi, bj, ci, cj = (p[:, k, None] for p in (a, b, c) for k in (0, 1))
        det = (bi - ai) * (cj - aj) - (ci - ai) * (bj - aj)
        wb = ((II - ai) * (cj - aj) - (ci - ai) * (JJ - aj)) / det
        wc = ((bi - ai) * (JJ - aj) - (II - ai) * (bj - aj)) / det
        wa = 1 - wb - wc
        inside = (wa >= -1e-12) & (wb >= -1e-12) & (wc >= -1e-12)
        plane = wa * z[ai, aj] + wb * z[bi, bj] + wc * z[ci, cj]
        m = tuple(((a + b) // 2).T)  # each triangle's split vertex
        np.maximum.at(err, m, np.where(inside & vs, np.abs(zs - plane), 0.0).max(axis=1))
        np.add.at(nv, m, (inside & vs).sum(axis=1))
        np.add.at(ni, m, (inside & ~vs).sum(axis=1))
        mid = (a + b) // 2  # bisect: (c, a, m), (b, c, m)
        a, b, c = np.concatenate([c, b]), np.concatenate([a, c]), np.concatenate([mid, mid])
    return np.where((nv > 0) & (ni > 0), np.inf, np.where(nv > 0, err, 0.0))


@settings(max_examples=25)  # a brute force: a few hundred triangles a depth
@given(root_dem(max_n=3))
def test_raw_delta_equals_the_brute_force_over_the_root_triangles(dem):
    z, valid, n, roots = dem
    brute = round_up(_brute_raw(np.where(valid, z, 0.0), valid, n, roots))
    ref = round_up(vertex_errors_reference(z, valid, 1 << n))
    ker = _raw_delta(np.where(valid, z, 0.0), valid.copy(), 1 << n)
    for got in (ref, ker):
        np.testing.assert_array_equal(np.isinf(got), np.isinf(brute))
        fin = np.isfinite(brute)
        np.testing.assert_allclose(got[fin], brute[fin], rtol=1e-6, atol=1e-9)


@given(root_dem())
def test_saturated_delta_on_roots_against_the_reference_and_the_dag(dem):
    z, valid, n, roots = dem
    S = 1 << n
    d = vertex_errors(z, valid, span=S)
    assert d.dtype == np.float32 and d.shape == z.shape
    ref = saturate(round_up(vertex_errors_reference(z, valid, S)), S)
    np.testing.assert_array_equal(np.isinf(d), np.isinf(ref))
    fin = np.isfinite(ref)
    np.testing.assert_allclose(d[fin], ref[fin], rtol=1e-6, atol=1e-9)
    # δ(parent) ≥ δ(child) on every edge of the roots' DAG (core.bintree's, not delta's)
    II, JJ = (v.ravel() for v in np.indices(z.shape))
    dep = vertex_depth(II, JJ, n, roots)
    assert (d[II[dep < 0], JJ[dep < 0]] == 0).all()  # every root's corners
    keep = dep >= 0
    ch = vertex_children(II[keep], JJ[keep], n, roots)
    par = np.repeat(d[II[keep], JJ[keep]], 4)
    c = ch.reshape(-1, 2)
    ok = c[:, 0] >= 0
    assert (par[ok] >= d[c[ok, 0], c[ok, 1]]).all()


@given(root_dem())
def test_one_root_is_the_square(dem):
    z, valid, n, roots = dem
    z, valid = z[: (1 << n) + 1, : (1 << n) + 1], valid[: (1 << n) + 1, : (1 << n) + 1]
    np.testing.assert_array_equal(vertex_errors(z, valid, span=1 << n), vertex_errors(z, valid))


def test_the_edge_two_roots_share_sees_both():
    z = np.zeros((5, 9))
    z[2, 5] = 3.0  # in the second root, in the shared edge midpoint's diamond (h = 2)
    d = _raw_delta(z, np.ones(z.shape, bool), 4)
    assert d[2, 4] == 3.0  # the midpoint of the edge (0, 4)–(4, 4)
    assert d[2, 2] == 0.0 and d[2, 6] == 3.0  # root 0's centre does not see it; root 1's
    with pytest.raises(ValueError, match="shape"):
        vertex_errors(np.zeros((5, 8)), np.ones((5, 8), bool), span=4)


@given(root_dem(), st.booleans())
def test_radii_on_roots_nest_on_the_roots_dag_and_equal_the_recursion(dem, curvy):
    from geoterrain.bounds.radii import vertex_radii
    from geoterrain.bounds.tileblobs import log8_table, radius_codes

    z, valid, n, roots = dem
    S = 1 << n
    ii, jj = np.indices(z.shape).astype(float)
    x, y = 30.0 * jj, -30.0 * ii
    if curvy:  # curvilinear scene x, y (a geographic frame's)
        x, y = x + 0.01 * ii * ii, y + 0.02 * jj * np.sqrt(ii + 1)
    p = np.stack([x, y, np.zeros(z.shape)], -1)
    zz = np.where(valid, z, np.nan)
    r = vertex_radii(x, y, zz, valid, span=S)
    # the recursion written out on core.bintree's DAG, fine to coarse, the proxies' z
    zp = np.where(valid, zz, 0.5 * (np.nanmin(zz[valid]) + np.nanmax(zz[valid]))
                  if valid.any() else 0.0)
    II, JJ = (v.ravel() for v in np.indices(z.shape))
    dep = vertex_depth(II, JJ, n, roots)
    p[..., 2] = zp
    want = np.zeros(z.shape, np.float32)
    for d in range(2 * n - 1, -1, -1):
        sel = dep == d
        ch = vertex_children(II[sel], JJ[sel], n, roots)
        for (i, j), cs in zip(zip(II[sel], JJ[sel], strict=True), ch, strict=True):
            best = 0.0
            for ci, cj in cs:
                if ci >= 0:
                    dist = float(np.sqrt(((p[i, j] - p[ci, cj]) ** 2).sum()))
                    best = max(best, dist + float(want[ci, cj]))
            want[i, j] = round_up(np.array([best]))[0]
    np.testing.assert_array_equal(r, want)
    codes, e = radius_codes(x, y, zz, valid, r, span=S)
    v = log8_table(e)[codes]
    assert (v >= r).all()

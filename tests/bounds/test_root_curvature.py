"""Bounds in the scene's metric x/y on a geographic root grid (issue 45): the square's
tests of :mod:`geoterrain.bounds.curvature` (tests/bounds/test_curvature.py) on a grid of
2 × 1 (or 1 × 2) root tiles, whose arrays are the roots' extent.

Every mesh is measured by :mod:`geoterrain.testing.metricmeasure` (each valid sample
located by its own scene x, y in the triangles drawn between the vertices' scene x, y;
it never reads δ, r or the bintree); the per-triangle oracle takes its triangles from
:func:`geoterrain.core.bintree.uniform_triangles` of the roots, not from the kernels.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.curvature import BORDER_FRACTION
from geoterrain.core.view import View
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.terrain import Terrain
from geoterrain.testing.metricmeasure import metric_errors, metric_screen_error
from tests.bounds.test_curvature import _case, _geo_tif, _measure, _rough, _smooth, _z_slack

pytestmark = pytest.mark.fast

ES = (1.0, 5.0, 20.0)
REL = 1e-6


def _voids(z):
    z = np.array(z, np.float32)
    z[20:27, 40:52] = np.nan  # a void in the west root
    z[:6, -10:] = np.nan  # one on the data's north-east corner
    return z


DEMS = {
    # 2° × 1° at 60° N on 2 × 1 roots of 64 samples: the square's lat60 cases, cut
    "roots_rough_voids": (lambda: _voids(_rough(129)[:65]), 10.0, 61.0, 2.0, 16),
    "roots_smooth": (lambda: _smooth(129)[:65], 10.0, 61.0, 2.0, 16),
    # 1 × 2 roots, a lattice short of the extent both ways (δ_edge, the clipped
    # static mesh's window), at 75° N
    "roots_tall_uneven": (lambda: _rough(129, 3)[:121, :50], 20.0, 76.0, 0.8, 8),
    # 2 × 1 roots of 64 over a lattice of 41 × 121 rows (its padding's positions past the
    # lattice are the frame's proxies, Frame.xy), with voids, at 61° N
    "roots_wide_past_lattice": (lambda: _voids(_rough(129, 5)[:40, :117]), 10.0, 61.0, 2.0,
                                16),
}


@pytest.fixture(scope="module", params=sorted(DEMS))
def geo(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    make, lon, lat, deg, ts = DEMS[request.param]
    src = _geo_tif(d / "g.tif", make(), lon, lat, deg)
    case = _case(preprocess(src, d / "s.geoterrain", tile_size=ts, root_grid=True))
    g = case[0].grid
    assert g.layout == "roots" and case[0].frame.kind == "geographic"
    # the frame takes proxy positions past level 0's lattice where the extent passes it
    assert case[0].frame.lattice == (g.shape if g.extent != g.shape else None)
    assert case[0].frame.lattice is not None or request.param.startswith("roots_smooth") \
        or request.param.startswith("roots_rough")
    assert g.roots == ((1, 2) if "tall" in request.param else (2, 1))
    return case


@pytest.mark.parametrize("e", ES)
def test_static_metric_error_and_cover(geo, e):
    t, X, Y, Z, valid, tol = geo
    ij, f, vz, vx, vy = _measure(geo, t.static_selection(e))
    err, outside = metric_errors(f, vx, vy, vz, X, Y, Z, valid, tol)
    assert int(outside.sum()) == 0, f"{int(outside.sum())} valid samples outside the mesh"
    assert np.nanmax(err) <= e * (1 + REL) + _z_slack(Z), np.nanmax(err)


@settings(max_examples=6, deadline=None)
@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.1, 1.4), dist=st.floats(0.05, 1.5),
       tx=st.floats(-0.5, 0.5), ty=st.floats(-0.5, 0.5), tau=st.sampled_from([0.5, 1.0, 4.0]))
def test_rtin_metric_screen_error(geo, az, el, dist, tx, ty, tau):
    t, X, Y, Z, valid, tol = geo
    span = max(np.ptp(X), np.ptp(Y))
    target = np.array([tx * np.ptp(X), ty * np.ptp(Y), float(Z[valid].mean())])
    eye = target + dist * span * np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el),
                                           np.sin(el)])
    view = View(tuple(eye), tuple(target), size=(640, 360))
    sel = t.select(view, tau, "rtin", occlusion=False)  # ρ at every sample in the frustum
    ij, f, vz, vx, vy = _measure(geo, sel)
    e = metric_screen_error(f, vx, vy, vz, X, Y, Z, valid, view.eye, view.planes, view.lam,
                            tol)
    d = np.sqrt((X - view.eye[0]) ** 2 + (Y - view.eye[1]) ** 2 + (Z - view.eye[2]) ** 2)
    assert e.max <= tau * (1 + REL) + view.lam * _z_slack(Z) / d.min(), (e, tau)


def test_border_chords_are_refined(geo):
    """The smooth case needs border refinement on the roots as on the square: its
    southern border (the extent's last row, bulging out of its chords) is refined to
    short chords, its northern one (bowing into the mesh) is not."""
    t, X, Y, Z, valid, tol = geo
    if "roots_smooth" not in str(t.path):
        pytest.skip("the smooth case only")
    sel = t.static_selection(20.0)
    F = sel.ij.astype(np.int64)[sel.surface_faces()]

    def border_spans(row):
        on = (F[:, :, 0] == row).sum(1) == 2  # triangles with an edge on this row
        cols = np.sort(F[on][:, :, 1][F[on][:, :, 0] == row].reshape(-1, 2), axis=1)
        spans = cols[:, 1] - cols[:, 0]
        assert spans.sum() == X.shape[1] - 1  # the row is drawn, end to end
        return spans

    assert border_spans(Z.shape[0] - 1).max() <= 8
    assert border_spans(0).max() >= 32


def _root_triangles_by_vertex(n, roots):
    """(v, a, b, c) of every triangle of the roots' bintree above the leaves, by its split
    vertex v = (a + b) / 2: :func:`geoterrain.core.bintree.uniform_triangles` per depth."""
    from geoterrain.core.bintree import uniform_triangles

    out = []
    for depth in range(2 * n):
        a, b, c = uniform_triangles(n, depth, roots)
        v = (a + b) // 2
        out += [tuple(map(tuple, q)) for q in zip(v, a, b, c, strict=True)]
    return out


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**16), lat=st.floats(-80, 80), rough=st.floats(0, 400),
       roots=st.sampled_from([(2, 1), (1, 2)]), short=st.booleans(), lattice=st.booleans())
def test_each_triangle_is_within_its_vertex_bounds(seed, lat, rough, roots, short, lattice):
    """Oracle per triangle T of the roots' bintree, split vertex v: every valid sample
    whose scene x/y lies in T is within δ(v) of T and within r(v) of p_v; δ saturated
    and r nested on every DAG edge of the roots (core.bintree's parents). ``lattice``:
    the positions past a lattice short of the extent are the frame's proxies."""
    from pyproj import CRS

    from geoterrain.bounds.curvature import metric_bounds
    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.bounds.radii import _proxy_positions, vertex_radii
    from geoterrain.core.bintree import vertex_parents
    from geoterrain.core.frame import Frame

    n = 4
    S = 1 << n
    R, C = roots[1] * S + 1, roots[0] * S + 1
    fr = Frame.from_raster((0.6, 0, 10.0, 0, -0.3, lat + 2.4), CRS.from_epsg(4326).to_wkt(),
                           *((R - 8, C - 9) if lattice else (R, C)))
    if lattice:  # a raster of R − 8 rows: proxies from row R − 6 and column C − 7 on
        fr = fr.with_lattice((R - 6, C - 7))
    X, Y = fr.grid_xy((R, C))
    rng = np.random.default_rng(seed)
    Z = rough * rng.random((R, C)) + 30.0 * np.indices((R, C))[1]
    valid = rng.random((R, C)) > 0.05
    if short or lattice:  # the raster a few samples short of the extent (invalid padding)
        valid[R - (8 if lattice else 3):] = False
        valid[:, C - (9 if lattice else 5):] = False
    d, r = metric_bounds(vertex_errors(Z, valid, span=S), vertex_radii(X, Y, Z, valid, span=S),
                         X, Y, Z, valid, span=S)
    assert d.shape == r.shape == (R, C)
    proxy = _proxy_positions(X, Y, np.where(valid, Z, np.nan), valid)
    tol = BORDER_FRACTION * min(np.hypot(np.diff(X, axis=a), np.diff(Y, axis=a)).min()
                                for a in (0, 1))
    checked = 0
    for v, a, b, c in _root_triangles_by_vertex(n, roots):
        if not (valid[a] and valid[b] and valid[c]):
            continue
        corners = np.array([a, b, c])
        keep = valid.copy()
        keep[tuple(corners.T)] = False  # corners are mesh vertices
        err, _ = metric_errors(np.array([[0, 1, 2]]), X[tuple(corners.T)],
                               Y[tuple(corners.T)], Z[tuple(corners.T)], X, Y, Z, keep, tol)
        held = np.isfinite(err)
        if not held.any():
            continue
        checked += 1
        # (the measure's own round-off: a flat grid's errors are float64 noise)
        assert err[held].max() <= d[v] + _z_slack(Z), (v, a, b, c, err[held].max(), d[v])
        cx, cy, cz = (P[v] for P in proxy)
        dist = np.sqrt((X - cx) ** 2 + (Y - cy) ** 2 + (Z - cz) ** 2)
        assert dist[held].max() <= r[v], (v, dist[held].max(), r[v])
    assert checked > 0
    # saturation and nesting over the roots' DAG (every root's corners are 0)
    i, j = (a.ravel() for a in np.indices((R, C)))
    corner = (i % S == 0) & (j % S == 0)
    i, j = i[~corner], j[~corner]
    par = vertex_parents(i, j, n, roots)
    xp, yp, zp = proxy
    for k in range(2):
        pi, pj = par[:, k, 0], par[:, k, 1]
        ok = (pi >= 0) & ((pi % S != 0) | (pj % S != 0))  # a root's corners are 0
        assert (d[pi[ok], pj[ok]] >= d[i[ok], j[ok]]).all()
        gap = np.sqrt((xp[pi[ok], pj[ok]] - xp[i[ok], j[ok]]) ** 2
                      + (yp[pi[ok], pj[ok]] - yp[i[ok], j[ok]]) ** 2
                      + (zp[pi[ok], pj[ok]] - zp[i[ok], j[ok]]) ** 2)
        assert (r[pi[ok], pj[ok]] >= (gap + r[i[ok], j[ok]]) * (1 - 1e-6)).all()
    assert (d[::S, ::S] == 0).all()


def test_edge_terms_reuse_the_original_grid(tmp_path):
    """δ_edge's metric terms on a root grid's extent (edgepad.py) computed only where a
    padding sample is read equal the terms computed everywhere."""
    from geoterrain.bounds.curvature import metric_terms
    from geoterrain.bounds.edgepad import edge_support, zero_beyond_data

    store = preprocess(_geo_tif(tmp_path / "g.tif", _rough(129)[:50, :117], 10.0, 61.0, 2.0),
                       tmp_path / "g.geoterrain", tile_size=16, root_grid=True)
    t = Terrain(store)
    g = t.grid
    assert g.roots == (2, 1) and g.extent == (65, 129)
    X, Y = t.frame.grid_xy(g.extent)
    Z = g.pad(t.scene_xyz()[2], np.nan, whole=True)
    valid = np.isfinite(Z)
    Zr, ok = edge_support(Z, valid, g)
    win = (g.rows, g.cols)
    base = metric_terms(X, Y, Z, valid, span=g.span)
    full = metric_terms(X, Y, Zr, ok, window=win, span=g.span)
    fast = metric_terms(X, Y, Zr, ok, window=win, base=base, span=g.span)
    for k in (0, 2):  # δ_m and the bulge flags (r_m is not used for δ_edge)
        a, b = full[k].copy(), fast[k].copy()
        zero_beyond_data(a, *win)
        zero_beyond_data(b, *win)
        np.testing.assert_array_equal(a, b)
    assert full[0][:g.rows, :g.cols].max() > 0  # the metric term is there to compare

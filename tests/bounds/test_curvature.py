"""Bounds in the scene's metric x/y on geographic (curvilinear) grids.

Every mesh is measured by :mod:`geoterrain.testing.metricmeasure`, which locates each valid sample
by its own scene (X, Y) in the triangles drawn between the vertices' scene (X, Y) and never
reads δ, r or the bintree: the vertical error must be ≤ e (static) or ρ ≤ τ (views), and
no valid sample may lie outside the drawn mesh (beyond a band of 1 % of a sample spacing,
the fraction the border refinement guarantees).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from geoterrain.bounds.curvature import BORDER_FRACTION
from geoterrain.core.view import View
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.terrain import Terrain
from geoterrain.testing.measure import mesh_heights_on_grid
from geoterrain.testing.metricmeasure import metric_errors, metric_screen_error
from tests.conftest import real_dem, write_tif

ES = (1.0, 5.0, 20.0)
REL = 1e-6


def _z_slack(Z) -> float:
    # float32 mesh heights: half an ulp of the largest |z|, as the stress suite allows
    return float(np.nanmax(np.abs(Z))) * 2.0 ** -23 + 1e-9


def _geo_tif(path, z, lon0, lat0, deg):
    return write_tif(path, np.asarray(z, np.float32), crs="EPSG:4326", origin=(lon0, lat0),
                     spacing=deg / (z.shape[1] - 1))


def _rough(n, seed=5):
    from geoterrain.ingest.synth import generate

    z = generate("fbm", n, seed=seed).astype(np.float64)
    return (z - z.min()) / np.ptp(z) * 1200.0


def _smooth(n):
    # a gentle swell: coarse triangles (long, curved border chords) already meet e = 20
    i, j = np.indices((n, n)) / (n - 1)
    return 300.0 + 150.0 * np.sin(2.2 * i + 0.7) * np.cos(1.7 * j) + 40.0 * i * j


DEMS = {
    # a 2° × 2° grid at 60° N: parallels bow by ~400 m over its width
    "lat60_rough": lambda d: _geo_tif(d / "a.tif", _rough(129), 10.0, 61.0, 2.0),
    "lat60_smooth": lambda d: _geo_tif(d / "b.tif", _smooth(129), 10.0, 61.0, 2.0),
    # the same, 100 × 117 samples: padded, so the static mesh is clipped to the data and
    # its cut southern and eastern borders are chords of curved ones (curvature.py window)
    "lat60_uneven": lambda d: _geo_tif(d / "e.tif", _rough(129)[:100, :117], 10.0, 61.0,
                                       2.0),
    "lat60_smooth_uneven": lambda d: _geo_tif(d / "f.tif", _smooth(129)[:100, :117], 10.0,
                                              61.0, 2.0),
    # 1° × 1° tiles across the antimeridian, written east and west of it
    "antimeridian_east": lambda d: _geo_tif(d / "c.tif", _rough(129, 8), 179.5, 40.5, 1.0),
    "antimeridian_west": lambda d: _geo_tif(d / "d.tif", _smooth(129), -180.5, -39.5, 1.0),
}


@pytest.fixture(scope="module", params=sorted(DEMS))
def geo(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    return _case(preprocess(DEMS[request.param](d), d / "s.geoterrain"))


def _case(store):
    t = Terrain(store)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    sp = min(np.median(np.hypot(np.diff(X, axis=a), np.diff(Y, axis=a))) for a in (0, 1))
    return t, X, Y, np.where(valid, Z, 0.0), valid, BORDER_FRACTION * sp


def _measure(case, sel):
    t, X, Y, Z, valid, tol = case
    ij = sel.ij.astype(np.int64)
    f = sel.surface_faces()
    p = np.asarray(sel.mesh.points, np.float64)
    at = np.all(sel.ij == ij, axis=1)  # vertices at samples (a clipped static mesh also
    # has points cut on the data's border, which are where the mesh puts them)
    vx = np.where(at, X[ij[:, 0].clip(0, X.shape[0] - 1), ij[:, 1].clip(0, X.shape[1] - 1)],
                  p[:, 0])
    vy = np.where(at, Y[ij[:, 0].clip(0, X.shape[0] - 1), ij[:, 1].clip(0, X.shape[1] - 1)],
                  p[:, 1])
    return ij, f, p[:, 2], vx, vy


def test_antimeridian_frame_is_continuous(geo):
    t, X, Y, *_ = geo
    dx = np.diff(X, axis=1)
    assert (dx > 0).all() and dx.max() < 1.1 * dx.min()  # no wrap, no jump (spacing follows cos φ)
    assert (np.diff(Y, axis=0) < 0).all()


@pytest.mark.parametrize("e", ES)
def test_static_metric_error_and_cover(geo, e):
    t, X, Y, Z, valid, tol = geo
    sel = t.static_selection(e)
    ij, f, vz, vx, vy = _measure(geo, sel)
    err, outside = metric_errors(f, vx, vy, vz, X, Y, Z, valid, tol)
    assert int(outside.sum()) == 0, f"{int(outside.sum())} valid samples outside the mesh"
    assert np.nanmax(err) <= e * (1 + REL) + _z_slack(Z), np.nanmax(err)


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
    slack = view.lam * _z_slack(Z) / d.min()
    assert e.max <= tau * (1 + REL) + slack, (e, tau)
    # samples the grid-space mesh covers, away from frustum-culled triangles (all their
    # in-grid neighbours covered too), must be covered in metres as well
    _, cov = mesh_heights_on_grid(ij, f, vz, Z.shape)
    pad = np.pad(cov, 1, constant_values=True)
    inner = cov.copy()
    for di in range(3):
        for dj in range(3):
            inner &= pad[di:di + Z.shape[0], dj:dj + Z.shape[1]]
    _, outside = metric_errors(f, vx, vy, vz, X, Y, Z, valid & inner, tol)
    assert int(outside.sum()) == 0


def test_border_chords_are_refined(geo):
    """The smooth 2° DEM needs border refinement: a coarse mesh on it would leave samples
    outside (the measure sees them), and the refined border edges are short."""
    t, X, Y, Z, valid, tol = geo
    if t.meta["source"] not in ("b.tif",) and "b.tif" not in t.meta["source"]:
        pytest.skip("the smooth 60° N case only")
    sel = t.static_selection(20.0)
    ij = sel.ij.astype(np.int64)
    F = ij[sel.surface_faces()]

    def border_spans(row):
        on = (F[:, :, 0] == row).sum(1) == 2  # triangles with an edge on this row
        cols = np.sort(F[on][:, :, 1][F[on][:, :, 0] == row].reshape(-1, 2), axis=1)
        spans = cols[:, 1] - cols[:, 0]
        assert spans.sum() == X.shape[1] - 1  # the row is drawn, end to end
        return spans

    # Parallels bow away from the pole: the southern border bulges out of its chords (a 2°
    # chord by ~400 m, half a spacing), the northern one into the mesh. Chords of 16
    # samples would bow out by ~9 m > 0.5 % of the 870 m spacing: the south is refined,
    # the north is not.
    assert border_spans(Z.shape[0] - 1).max() <= 8
    assert border_spans(0).max() >= 32


def test_real_geographic_dems(tmp_path):
    for name in ("srtm3_pysheds.tif", "srtm1_japan.tif"):
        case = _case(preprocess(real_dem(name), tmp_path / f"{name}.geoterrain"))
        t, X, Y, Z, valid, tol = case
        for e in (1.0, 20.0):
            ij, f, vz, vx, vy = _measure(case, t.static_selection(e))
            err, outside = metric_errors(f, vx, vy, vz, X, Y, Z, valid, tol)
            assert int(outside.sum()) == 0, (name, e)
            assert np.nanmax(err) <= e * (1 + REL) + _z_slack(Z), (name, e, np.nanmax(err))


@pytest.mark.fast
def test_projected_and_pixel_paths_never_call_it(tmp_path, monkeypatch):
    """δ and r of affine grids stay bit-identical: the metric term is not computed."""
    from geoterrain.preprocessing import levelblobs, surface

    def boom(*a, **k):
        raise AssertionError("metric_bounds called on an affine grid")

    # its callers: δ and r (surface.vertex_bounds), δ_edge (levelblobs.tile_blobs)
    monkeypatch.setattr(surface, "metric_bounds", boom)
    monkeypatch.setattr(levelblobs, "metric_bounds", boom)
    z = _rough(33)
    preprocess(write_tif(tmp_path / "utm.tif", z), tmp_path / "a.geoterrain")
    preprocess(write_tif(tmp_path / "px.tif", z, crs=None), tmp_path / "b.geoterrain",
               pixel_size=2.0)
    with pytest.raises(AssertionError, match="affine"):
        preprocess(_geo_tif(tmp_path / "g.tif", z, 10.0, 61.0, 2.0), tmp_path / "c.geoterrain")


def _vertex_triangles(N):
    """(v, a, b, c) of every bintree triangle, by its split vertex v, written out here."""
    out = []
    h = 1
    while h < N - 1:
        s = 2 * h
        for i0 in range(0, N - 1, s):
            for j0 in range(0, N - 1, s):
                v = (i0 + h, j0 + h)
                if ((i0 // s) + (j0 // s)) % 2 == 0:  # union jack: main diagonal
                    a, b, apex = (i0, j0), (i0 + s, j0 + s), [(i0, j0 + s), (i0 + s, j0)]
                else:
                    a, b, apex = (i0, j0 + s), (i0 + s, j0), [(i0, j0), (i0 + s, j0 + s)]
                out += [(v, a, b, c) for c in apex]
        for i in range(0, N, h):
            for j in range(0, N, h):
                if (i // h) % 2 + (j // h) % 2 != 1:
                    continue
                if (i // h) % 2:  # hypotenuse along the rows
                    ends, apex = [(i - h, j), (i + h, j)], [(i, j - h), (i, j + h)]
                else:
                    ends, apex = [(i, j - h), (i, j + h)], [(i - h, j), (i + h, j)]
                out += [((i, j), *ends, c) for c in apex
                        if 0 <= c[0] < N and 0 <= c[1] < N]
        h *= 2
    return out


@settings(max_examples=8)
@given(seed=st.integers(0, 2**16), lat=st.floats(-80, 80), rough=st.floats(0, 400))
@example(seed=17927, lat=0.0, rough=273.0)  # an invalid split vertex (see below)
def test_each_triangle_is_within_its_vertex_bounds(seed, lat, rough):
    """Oracle per bintree triangle T of split vertex v: every valid sample whose scene x/y
    lies in T (measured by metricmeasure) is within δ(v) of T and within r(v) of p_v."""
    from pyproj import CRS

    from geoterrain.bounds.curvature import metric_bounds
    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.bounds.radii import _proxy_positions, vertex_radii
    from geoterrain.core.frame import Frame

    N = 17
    fr = Frame.from_raster((0.6, 0, 10.0, 0, -0.3, lat + 2.4), CRS.from_epsg(4326).to_wkt(), N, N)
    X, Y = fr.grid_xy(N)
    rng = np.random.default_rng(seed)
    Z = rough * rng.random((N, N)) + 30.0 * np.indices((N, N))[1]
    valid = rng.random((N, N)) > 0.05
    d, r = metric_bounds(vertex_errors(Z, valid), vertex_radii(X, Y, Z, valid), X, Y, Z, valid)
    proxy = _proxy_positions(X, Y, np.where(valid, Z, np.nan), valid)
    tol = BORDER_FRACTION * min(np.hypot(np.diff(X, axis=a), np.diff(Y, axis=a)).min()
                                for a in (0, 1))
    for v, a, b, c in _vertex_triangles(N):
        if not (valid[a] and valid[b] and valid[c]):
            continue
        corners = np.array([a, b, c])
        vx, vy, vz = (X[tuple(corners.T)], Y[tuple(corners.T)],
                      Z[tuple(corners.T)])
        keep = valid.copy()
        keep[tuple(corners.T)] = False  # corners are mesh vertices
        err, _ = metric_errors(np.array([[0, 1, 2]]), vx, vy, vz, X, Y, Z, keep, tol)
        held = np.isfinite(err)
        if not held.any():
            continue
        assert err[held].max() <= d[v], (v, a, b, c, err[held].max(), d[v])
        # r(v) is about v's position in the nested spheres: its own when valid, else the
        # finite proxy that stands in for it (radii.vertex_radii); a 5 % nodata grid has
        # invalid split vertices, whose raw Z is noise (found by hypothesis: seed 17927,
        # lat 0, rough 273, v = (11, 5) invalid, 1.5 mm beyond r measured from raw Z)
        cx, cy, cz = (P[v] for P in proxy)
        dist = np.sqrt((X - cx) ** 2 + (Y - cy) ** 2 + (Z - cz) ** 2)
        assert dist[held].max() <= r[v], (v, dist[held].max(), r[v])


@pytest.mark.parametrize("shape", [(100, 117), (129, 70), (65, 128)])
def test_edge_terms_reuse_the_original_grid(tmp_path, shape):
    """δ_edge's metric terms (edgepad.py) computed only where a padding sample is read,
    the rest taken from the original grid's run, equal the terms computed everywhere."""
    from geoterrain.bounds.curvature import metric_terms
    from geoterrain.bounds.edgepad import edge_support, zero_beyond_data

    store = preprocess(_geo_tif(tmp_path / "g.tif", _rough(129)[:shape[0], :shape[1]], 10.0,
                                61.0, 2.0), tmp_path / "g.geoterrain",
                       root_grid=False)  # δ_edge's terms on the square (roots: test_root_curvature)
    t = Terrain(store)
    g = t.grid
    X, Y = t.frame.grid_xy(g.size)
    Z = g.pad(t.scene_xyz()[2], np.nan)
    valid = np.isfinite(Z)
    Zr, ok = edge_support(Z, valid, g)
    win = (g.rows, g.cols)
    base = metric_terms(X, Y, Z, valid)
    full = metric_terms(X, Y, Zr, ok, window=win)
    fast = metric_terms(X, Y, Zr, ok, window=win, base=base)
    for k in (0, 2):  # δ_m and the bulge flags (r_m is not used for δ_edge)
        a, b = full[k].copy(), fast[k].copy()
        zero_beyond_data(a, *win)
        zero_beyond_data(b, *win)
        np.testing.assert_array_equal(a, b)

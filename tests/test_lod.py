"""LOD engine: crack-freedom, measured error ≤ τ, monotonicity, culling, laziness.

Errors are measured with geoterrain.measure (grid rasterisation), which shares
no code with the selection.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import geoterrain
from geoterrain.measure import screen_space_error, vertical_error
from geoterrain.synth import generate
from geoterrain.view import View
from tests.conftest import real_dem, write_tif

SLACK = 1 + 1e-9


def bound(e, Z):
    """e with 1e-9 relative slack, plus float64 round-off of interpolating heights Z."""
    return e * SLACK + 1e-12 * float(np.nanmax(np.abs(Z)))


def _store(tmp_path_factory, name, z, nodata=None, tile_size=16, **kw):
    d = tmp_path_factory.mktemp(name)
    src = write_tif(d / f"{name}.tif", z, nodata=nodata, **kw)
    return geoterrain.open(geoterrain.preprocess(src, d / f"{name}.geoterrain",
                                                 tile_size=tile_size))


@pytest.fixture(scope="module")
def holey(tmp_path_factory):
    """A 150×130 fBm with a nodata lake: non-square, padded, with holes."""
    z = generate("fbm", (150, 130), seed=5).astype(np.float32)
    yy, xx = np.mgrid[:150, :130]
    z[(yy - 60) ** 2 + (xx - 40) ** 2 < 150] = -9999
    return _store(tmp_path_factory, "holey", z, nodata=-9999)


@pytest.fixture(scope="module")
def truth_cache():
    return {}


def truth(t, cache):
    key = id(t)
    if key not in cache:
        X, Y, Z = t.scene_xyz()
        cache[key] = (X, Y, Z, np.isfinite(Z))
    return cache[key]


def surface(sel):
    f = sel.surface_faces()
    return sel.ij, f, np.asarray(sel.mesh.points)[:, 2]


def valid_domain_area(valid: np.ndarray) -> float:
    """Area (in cells) of the full-resolution triangles with three valid corners.

    Written independently of the library: in each unit cell the diagonal joins
    the corner whose row and column are both odd to the opposite corner.
    """
    H, W = valid.shape
    a, b = np.mgrid[: H - 1, : W - 1]
    main = (a % 2) == (b % 2)  # the odd/odd corner is (a, b) or (a+1, b+1)
    v00, v01, v10, v11 = valid[:-1, :-1], valid[:-1, 1:], valid[1:, :-1], valid[1:, 1:]
    t1 = np.where(main, v00 & v11 & v01, v01 & v10 & v00)
    t2 = np.where(main, v00 & v10 & v11, v01 & v11 & v10)
    return 0.5 * float(t1.sum() + t2.sum())


def check_conforming(sel, valid):
    ij, f, _ = surface(sel)
    if not len(f):
        return 0.0
    p = ij[f]
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    # edges: every edge is used by one or two triangles, never more
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() <= 2
    # no T-junction: no vertex lies strictly inside any edge
    verts = {tuple(v) for v in ij.astype(np.int64).tolist()}
    for u, w in np.unique(e, axis=0).tolist():
        a, b = ij[u].astype(np.int64), ij[w].astype(np.int64)
        d = b - a
        k = int(np.abs(d).max())
        step = d // k
        for s in range(1, k):
            assert tuple((a + s * step).tolist()) not in verts, "T-junction"
    return float(area.sum())


def random_view(t, az, el, dist_frac, tx, ty, fov=30.0):
    X, Y, Z, v = t._truth
    ext = float(np.nanmax(np.abs(np.stack([X, Y]))))
    zc = float(np.nanmean(Z))
    target = np.array([tx * ext, ty * ext, zc])
    d = ext * dist_frac
    eye = target + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return View(tuple(eye), tuple(target), fov_y_deg=fov, size=(640, 360))


@pytest.fixture(scope="module")
def terrains(holey, tmp_path_factory):
    out = [holey]
    p = real_dem("srtm3_pysheds.tif") if (tmp_path_factory and True) else None
    d = tmp_path_factory.mktemp("real")
    out.append(geoterrain.open(geoterrain.preprocess(p, d / "s.geoterrain", tile_size=32)))
    for t in out:
        X, Y, Z = t.scene_xyz()
        t._truth = (X, Y, Z, np.isfinite(Z))
    return out


# ------------------------------------------------------------------ static mesh
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0, 5.0, 20.0])
def test_static_mesh_vertical_error_is_bounded(holey, truth_cache, e):
    X, Y, Z, valid = truth(holey, truth_cache)
    sel = holey.static_selection(e)
    ij, f, z = surface(sel)
    err = vertical_error(ij, f, z, Z, valid)
    assert err.max <= bound(e, Z)
    full = vertical_error(*surface(holey.static_selection(0.0)), Z, valid)
    assert err.n_uncovered_valid == full.n_uncovered_valid  # covers the whole valid domain
    area = check_conforming(sel, valid)
    assert area == pytest.approx(valid_domain_area(valid))


@pytest.mark.parametrize("name", ["fuji_terrain_rgb.png", "srtm1_japan.tif", "roi_epsg3089.tif"])
def test_static_mesh_on_real_dems(tmp_path, name):
    t = geoterrain.open(geoterrain.preprocess(real_dem(name), tmp_path / "s.geoterrain"))
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    prev = None
    for e in (0.5, 1.0, 5.0, 20.0):
        sel = t.static_selection(e)
        err = vertical_error(*surface(sel), Z, valid)
        assert err.max <= bound(e, Z)
        assert prev is None or sel.stats["triangles"] <= prev
        prev = sel.stats["triangles"]


def test_flat_terrain_gives_two_triangles(tmp_path_factory):
    t = _store(tmp_path_factory, "flat", np.full((33, 33), 7.0, np.float32))
    assert t.static_selection(0.0).stats["triangles"] == 2
    sel = t.select(View((0, -500, 300), (0, 0, 7)), 1.0)
    assert sel.stats["triangles"] == 2


def test_affine_terrain_gives_two_triangles(tmp_path_factory):
    yy, xx = np.mgrid[:65, :65]
    t = _store(tmp_path_factory, "affine", (3.0 * xx - 2.0 * yy + 100).astype(np.float64))
    assert t.static_selection(0.0).stats["triangles"] == 2


@pytest.mark.parametrize("shape", [(2, 2), (3, 3), (2, 9), (17, 5)])
def test_tiny_grids(tmp_path_factory, shape):
    z = np.random.default_rng(1).random(shape) * 50
    t = _store(tmp_path_factory, f"tiny{shape[0]}x{shape[1]}", z, tile_size=4)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    for e in (0.0, 1.0):
        sel = t.static_selection(e)
        assert vertical_error(*surface(sel), Z, valid).max <= bound(e, Z)
    sel = t.select(View((0, -100, 50), (0, 0, 0)), 1.0)
    for s in ("rtin", "chunked", "bruteforce"):
        sel = t.select(View((0, -100, 50), (0, 0, 0)), 1.0, s)
        assert np.isfinite(np.asarray(sel.mesh.points)).all()


# --------------------------------------------------------- view-dependent LOD
@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5), dist=st.floats(0.05, 3.0),
       tx=st.floats(-1, 1), ty=st.floats(-1, 1), tau=st.sampled_from([0.5, 1.0, 4.0]),
       which=st.integers(0, 1), strategy=st.sampled_from(["rtin", "chunked"]))
def test_screen_space_error_is_at_most_tau(terrains, az, el, dist, tx, ty, tau, which,
                                           strategy):
    t = terrains[which]
    X, Y, Z, valid = t._truth
    view = random_view(t, az, el, dist, tx, ty)
    sel = t.select(view, tau, strategy)
    ij, f, z = surface(sel)
    err = screen_space_error(ij, f, z, X, Y, Z, valid, view.eye, view.planes, view.lam)
    assert err.max <= tau * SLACK, (err, sel.stats)
    assert np.isfinite(np.asarray(sel.mesh.points)).all()
    if strategy == "rtin":
        area = check_conforming(sel, valid)
        assert area <= valid_domain_area(valid) + 1e-9


def test_rtin_full_view_covers_exact_valid_domain(terrains):
    for t in terrains:
        X, Y, Z, valid = t._truth
        view = random_view(t, 0.3, 1.2, 2.5, 0, 0, fov=60)
        sel = t.select(view, 1.0, "rtin")
        if not view.points_inside(np.stack([X[valid], Y[valid], Z[valid]], 1)).all():
            continue
        assert check_conforming(sel, valid) == pytest.approx(valid_domain_area(valid))


@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5), dist=st.floats(0.1, 2.0))
def test_smaller_tau_never_removes_a_vertex(terrains, az, el, dist):
    t = terrains[0]
    view = random_view(t, az, el, dist, 0.1, -0.2)
    sets = []
    for tau in (8.0, 4.0, 1.0, 0.5):
        sel = t.select(view, tau, "rtin")
        inside = view.points_inside(np.asarray(sel.mesh.points))
        ij = sel.ij.astype(np.int64)
        sets.append((set(map(tuple, ij[inside].tolist())), set(map(tuple, ij.tolist()))))
    # every in-view vertex of a coarser selection is kept by every finer one
    for (coarse_in, _), (_, fine_all) in zip(sets, sets[1:], strict=False):
        assert coarse_in <= fine_all

@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5), dist=st.floats(0.05, 1.0),
       strategy=st.sampled_from(["rtin", "chunked", "bruteforce"]))
def test_culling_keeps_triangles_near_the_frustum(terrains, az, el, dist, strategy):
    t = terrains[0]
    view = random_view(t, az, el, dist, 0.5, 0.5, fov=20)
    sel = t.select(view, 1.0, strategy)
    pts = np.asarray(sel.mesh.points)
    f = sel.faces
    if not len(f):
        return
    P = view.planes
    d = pts @ P[:, :3].T + P[:, 3]  # (V, 6) signed distances
    out_by = -d[f].max(axis=1)  # (F, 6): > 0 means the whole triangle is outside that plane
    X, Y, Z, _ = t._truth
    spacing = float(np.nanmax(np.hypot(np.diff(X, axis=1), np.diff(Y, axis=1))))
    zr = float(np.nanmax(Z) - np.nanmin(Z))
    lvl = np.asarray(sel.mesh.cell_data["level"])
    tile_diag = np.hypot(2.0 ** (t.grid.t + lvl) * spacing * np.sqrt(2), zr)
    assert (out_by.max(axis=1) <= tile_diag + 1e-6).all()


def test_view_looking_away_is_empty_and_decodes_nothing(tmp_path_factory):
    z = generate("fbm", 129, seed=2)
    t = _store(tmp_path_factory, "away", z)
    for s in ("rtin", "chunked", "bruteforce"):
        t.decoded_tiles = 0
        sel = t.select(View((0, 0, 5000), (0, 0, 10000)), 1.0, s)
        assert sel.stats["triangles"] == 0 and sel.stats["tiles_decoded"] == 0


def test_eye_below_terrain_and_inside_spheres(terrains):
    t = terrains[0]
    X, Y, Z, v = t._truth
    for eye_z in (float(np.nanmin(Z)) - 100, float(np.nanmean(Z))):
        for s in ("rtin", "chunked", "bruteforce"):
            sel = t.select(View((1.0, 2.0, eye_z), (50.0, 60.0, eye_z + 1)), 1.0, s)
            assert np.isfinite(np.asarray(sel.mesh.points)).all()


def test_unchanged_camera_reuses_selection(terrains):
    t = terrains[0]
    v = random_view(t, 1.0, 0.5, 1.0, 0, 0)
    a = t.select(v, 1.0)
    b = t.select(v, 1.0)
    assert b.stats["reused"] and b.stats["triangles"] == a.stats["triangles"]


def test_corner_view_decodes_few_tiles_independent_of_store_size(tmp_path_factory):
    big = generate("fbm", 1025, seed=9).astype(np.float32)
    counts = []
    for size in (257, 1025):
        t = _store(tmp_path_factory, f"corner{size}", big[:size, :size], tile_size=32,
                   origin=(500000.0, 5000000.0))
        # a steep view of the north-west corner, identical in CRS coordinates
        x0, y0 = t.frame.crs_to_scene(np.array(500000.0 + 600), np.array(5000000.0 - 600))
        x1, y1 = t.frame.crs_to_scene(np.array(500000.0 + 700), np.array(5000000.0 - 700))
        zc = float(np.mean(big[:100, :100]))
        sel = t.select(View((float(x0), float(y0), zc + 1500), (float(x1), float(y1), zc),
                            fov_y_deg=30), 1.0, "rtin")
        counts.append(sel.stats["tiles_decoded"])
        assert sel.stats["triangles"] > 0
    # two more levels in the large store add at most a few ancestor tiles
    assert counts[1] <= counts[0] + 4 * 2
    assert counts[1] < 0.1 * (1024 // 32) ** 2


@given(n=st.integers(1, 6), seed=st.integers(0, 10_000), frac=st.floats(0.01, 0.5))
def test_upward_closure_is_closed_and_box_limited_scan_agrees(n, seed, frac):
    from geoterrain.bintree import vertex_depth, vertex_parents
    from geoterrain.lod.kernels import close_upward, close_upward_boxes

    N = 2**n + 1
    rng = np.random.default_rng(seed)
    i0, j0 = (int(v) for v in rng.integers(0, N, 2))
    i1, j1 = min(N - 1, i0 + int(rng.integers(0, N))), min(N - 1, j0 + int(rng.integers(0, N)))
    a = np.zeros((N, N), bool)
    a[i0:i1 + 1, j0:j1 + 1] = rng.random((i1 - i0 + 1, j1 - j0 + 1)) < frac
    full, boxed = a.copy(), a.copy()
    close_upward(full)
    # all activity entered at the finest level inside one box; coarser levels empty
    boxes = np.tile(np.array([N, -1, N, -1], np.int64), (n + 1, 1))
    boxes[0] = (i0, i1, j0, j1)
    close_upward_boxes(boxed, boxes)
    assert (full == boxed).all() and (full >= a).all()
    i, j = np.nonzero(full)
    keep = vertex_depth(i, j, n) >= 0
    par = vertex_parents(i[keep], j[keep], n).reshape(-1, 2)
    par = par[par[:, 0] >= 0]
    assert full[par[:, 0], par[:, 1]].all()  # every active vertex has both parents active

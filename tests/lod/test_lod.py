"""LOD engine: crack-freedom, measured error ≤ τ, monotonicity, culling, laziness.

Errors are measured with geoterrain.testing.measure (grid rasterisation), which shares
no code with the selection.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate
from geoterrain.lod import STRATEGIES, strategy_info
from geoterrain.testing.measure import screen_space_error, vertical_error
from tests.conftest import has_real_dem, real_dem, write_tif

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


def _valid_triangles(valid: np.ndarray):
    """Full-resolution triangles with three valid corners, written independently of the
    library: in each unit cell the diagonal joins the corner whose row and column are both
    odd to the opposite corner. Returns (main, t1, t2), (H-1, W-1) masks: where ``main``,
    t1 = (00, 01, 11) and t2 = (00, 10, 11); elsewhere t1 = (00, 01, 10), t2 = (01, 10, 11).
    """
    H, W = valid.shape
    a, b = np.mgrid[: H - 1, : W - 1]
    main = (a % 2) == (b % 2)  # the odd/odd corner is (a, b) or (a+1, b+1)
    v00, v01, v10, v11 = valid[:-1, :-1], valid[:-1, 1:], valid[1:, :-1], valid[1:, 1:]
    t1 = np.where(main, v00 & v11 & v01, v01 & v10 & v00)
    t2 = np.where(main, v00 & v10 & v11, v01 & v11 & v10)
    return main, t1, t2


def valid_domain_area(valid: np.ndarray) -> float:
    """Area (in cells) of the full-resolution triangles with three valid corners."""
    _, t1, t2 = _valid_triangles(valid)
    return 0.5 * float(t1.sum() + t2.sum())


def coverable(valid: np.ndarray) -> np.ndarray:
    """Valid samples that are a corner of a full-resolution triangle with three valid
    corners: the samples a mesh of exactly the valid domain covers."""
    main, t1, t2 = _valid_triangles(valid)
    out = np.zeros(valid.shape, bool)
    out[:-1, :-1] |= t1 | (t2 & main)
    out[:-1, 1:] |= t1 | (t2 & ~main)
    out[1:, :-1] |= t2 | (t1 & ~main)
    out[1:, 1:] |= t2 | (t1 & main)
    return out


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
        k = int(np.gcd(abs(int(d[0])), abs(int(d[1]))))  # lattice points on the edge
        step = d // k
        for s in range(1, k):
            assert tuple((a + s * step).tolist()) not in verts, "T-junction"
    return float(area.sum())


class Case:
    """A terrain and its full-resolution truth: scene X, Y, Z and the valid mask."""

    def __init__(self, name: str, t):
        self.name, self.t = name, t
        self.X, self.Y, self.Z = t.scene_xyz()
        self.valid = np.isfinite(self.Z)
        v = self.valid
        self.lo = np.array([self.X[v].min(), self.Y[v].min(), self.Z[v].min()])
        self.hi = np.array([self.X[v].max(), self.Y[v].max(), self.Z[v].max()])

    def points(self) -> np.ndarray:
        """(n, 3) scene positions of the valid samples."""
        v = self.valid
        return np.stack([self.X[v], self.Y[v], self.Z[v]], 1)

    def corners(self) -> np.ndarray:
        """The eight corners of the valid data's bounding box."""
        return np.array([[x, y, z] for x in (self.lo[0], self.hi[0])
                         for y in (self.lo[1], self.hi[1]) for z in (self.lo[2], self.hi[2])])

    def xyz(self, i: int, j: int) -> np.ndarray:
        return np.array([self.X[i, j], self.Y[i, j], self.Z[i, j]])

    def nearest_valid(self, i: int, j: int) -> tuple[int, int]:
        vi, vj = np.nonzero(self.valid)
        k = int(np.argmin((vi - i) ** 2 + (vj - j) ** 2))
        return int(vi[k]), int(vj[k])

    def __repr__(self) -> str:  # hypothesis prints drawn cases
        return f"Case({self.name!r})"


def random_view(c: Case, az, el, dist_frac, tx, ty, fov=30.0):
    X, Y, Z = c.X, c.Y, c.Z
    ext = float(np.nanmax(np.abs(np.stack([X, Y]))))
    zc = float(np.nanmean(Z))
    target = np.array([tx * ext, ty * ext, zc])
    d = ext * dist_frac
    eye = target + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return View(tuple(eye), tuple(target), fov_y_deg=fov, size=(640, 360))


def view_of_all_data(c: Case, fov=60.0) -> View:
    """A view from above whose frustum holds the whole valid data.

    The frustum is convex, so it holds every valid sample once it holds the eight corners
    of their bounding box; the eye backs off until it does.
    """
    ctr = 0.5 * (c.lo + c.hi)
    D = float(np.linalg.norm(c.hi - c.lo))
    corners = c.corners()
    for _ in range(40):
        view = View(tuple(ctr + np.array([0.0, -1e-3 * D, D])), tuple(ctr), fov_y_deg=fov,
                    size=(640, 360))
        if view.points_inside(corners).all():
            return view
        D *= 1.5
    raise AssertionError(f"no view from above holds all of {c}")


def n_in_view(c: Case, view: View) -> int:
    return int(view.points_inside(c.points()).sum())


@pytest.fixture(scope="module")
def terrains(holey, tmp_path_factory):
    """Synthetic terrains, always; real DEMs add cases when ../shared/dems is present."""
    yy, xx = np.mgrid[:97, :161]
    ridged = generate("ridged", (97, 161), seed=11).astype(np.float32)
    ridged[(yy < 20) & (xx > 140)] = np.nan  # a nodata corner
    out = [Case("holey", holey),
           Case("ridged", _store(tmp_path_factory, "ridged", ridged, tile_size=32))]
    if has_real_dem("srtm3_pysheds.tif"):
        d = tmp_path_factory.mktemp("real")
        p = real_dem("srtm3_pysheds.tif")
        out.append(Case("srtm3", geoterrain.open(geoterrain.preprocess(
            p, d / "s.geoterrain", tile_size=32))))
    return out


@pytest.mark.fast
def test_synthetic_terrains_do_not_need_real_dems(terrains):
    assert [c.name for c in terrains[:2]] == ["holey", "ridged"]
    assert all(c.valid.any() and not c.valid.all() for c in terrains[:2])


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


@pytest.mark.fast
def test_flat_terrain_gives_two_triangles(tmp_path_factory):
    t = _store(tmp_path_factory, "flat", np.full((33, 33), 7.0, np.float32))
    assert t.static_selection(0.0).stats["triangles"] == 2
    sel = t.select(View((0, -500, 300), (0, 0, 7)), 1.0)
    assert sel.stats["triangles"] == 2


@pytest.mark.fast
def test_affine_terrain_gives_two_triangles(tmp_path_factory):
    yy, xx = np.mgrid[:65, :65]
    t = _store(tmp_path_factory, "affine", (3.0 * xx - 2.0 * yy + 100).astype(np.float64))
    assert t.static_selection(0.0).stats["triangles"] == 2


@pytest.mark.parametrize("shape", [(2, 2), (3, 3), (2, 9), (17, 5), (9, 6)])
def test_tiny_grids(tmp_path_factory, shape):
    z = np.random.default_rng(1).random(shape) * 50
    if shape == (9, 6):
        z[4, 2:] = np.nan  # a nodata band: a valid domain in two pieces
    t = _store(tmp_path_factory, f"tiny{shape[0]}x{shape[1]}", z, tile_size=4)
    c = Case(f"tiny{shape}", t)
    Z, valid = c.Z, c.valid
    assert Z.shape == shape
    area, cover = valid_domain_area(valid), int(coverable(valid).sum())
    assert area > 0
    for e in (0.0, 1.0, 5.0):
        sel = t.static_selection(e)
        err = vertical_error(*surface(sel), Z, valid)
        assert err.max <= bound(e, Z), (e, err)
        assert err.n_samples == cover and err.n_uncovered_valid == valid.sum() - cover
        assert check_conforming(sel, valid) == pytest.approx(area)
    view = view_of_all_data(c)
    for tau in (0.5, 8.0):
        for s in STRATEGIES:
            sel = t.select(view, tau, s)
            err = screen_error(c, sel, view)
            assert not strategy_info(s).bounded or err.max <= tau * SLACK, (s, tau, err)
            assert err.n_samples == cover, (s, tau, err)  # all the data is in view
            if strategy_info(s).conforming:
                assert check_conforming(sel, valid) == pytest.approx(area)


# --------------------------------------------------------- view-dependent LOD
def screen_error(c: Case, sel, view: View):
    ij, f, z = surface(sel)
    return screen_space_error(ij, f, z, c.X, c.Y, c.Z, c.valid, view.eye, view.planes,
                              view.lam)


@given(data=st.data(), az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5),
       dist=st.floats(0.05, 3.0), tx=st.floats(-1, 1), ty=st.floats(-1, 1),
       tau=st.sampled_from([0.5, 1.0, 4.0]), strategy=st.sampled_from(STRATEGIES),
       morph=st.booleans())
def test_screen_space_error_is_at_most_tau(terrains, data, az, el, dist, tx, ty, tau,
                                           strategy, morph):
    c = data.draw(st.sampled_from(terrains), label="terrain")
    view = random_view(c, az, el, dist, tx, ty)
    # the strategy's own bound, at every sample in the frustum: no horizon culling
    # (tests/lod/test_occlusion.py checks ρ ≤ τ at the visible samples with it); morphing on
    # and off for the strategies that morph (the others ignore it)
    sel = c.t.select(view, tau, strategy, occlusion=False, morph=morph)
    err = screen_error(c, sel, view)
    info = strategy_info(strategy)
    assert not info.bounded or err.max <= tau * SLACK, (err, sel.stats)
    assert np.isfinite(np.asarray(sel.mesh.points)).all()
    if info.conforming:
        area = check_conforming(sel, c.valid)
        assert area <= valid_domain_area(c.valid) + 1e-9
    if strategy != "rtin":  # whole tiles whose boxes meet the frustum: all in view is drawn
        assert err.n_uncovered == 0, (err, sel.stats)


@pytest.mark.fast
def test_rtin_full_view_covers_exact_valid_domain(terrains):
    checked = []
    for c in terrains:
        view = view_of_all_data(c)
        assert view.points_inside(c.points()).all()  # the whole valid data is in view
        sel = c.t.select(view, 1.0, "rtin")
        assert check_conforming(sel, c.valid) == pytest.approx(valid_domain_area(c.valid)), c
        err = screen_error(c, sel, view)
        assert err.max <= SLACK, (c, err)
        assert err.n_samples == int(coverable(c.valid).sum()), (c, err)
        checked.append(c.name)
    assert checked[:2] == ["holey", "ridged"] and len(checked) == len(terrains)


@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5), dist=st.floats(0.1, 2.0))
def test_smaller_tau_never_removes_a_vertex(terrains, az, el, dist):
    c = terrains[0]
    view = random_view(c, az, el, dist, 0.1, -0.2)
    sets = []
    for tau in (8.0, 4.0, 1.0, 0.5):
        sel = c.t.select(view, tau, "rtin")
        inside = view.points_inside(np.asarray(sel.mesh.points))
        ij = sel.ij.astype(np.int64)
        sets.append((set(map(tuple, ij[inside].tolist())), set(map(tuple, ij.tolist()))))
    if n_in_view(c, view):
        assert sets[-1][1], "terrain in view but the finest selection is empty"
    # every in-view vertex of a coarser selection is kept by every finer one
    for (coarse_in, _), (_, fine_all) in zip(sets, sets[1:], strict=False):
        assert coarse_in <= fine_all


@pytest.mark.fast
@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.5), dist=st.floats(0.05, 1.0),
       strategy=st.sampled_from([s for s in STRATEGIES if strategy_info(s).culls]))
def test_culling_keeps_triangles_near_the_frustum(terrains, az, el, dist, strategy):
    """Every triangle drawn lies within a tile's diagonal of the frustum (the strategies
    that cull: ``clipmap`` draws its whole rings, tests/lod/test_clipmap.py)."""
    c = terrains[0]
    t = c.t
    view = random_view(c, az, el, dist, 0.5, 0.5, fov=20)
    sel = t.select(view, 1.0, strategy)
    pts = np.asarray(sel.mesh.points)
    f = sel.faces
    if not len(f):
        assert n_in_view(c, view) == 0, "terrain in view but nothing selected"
        return
    P = view.planes
    d = pts @ P[:, :3].T + P[:, 3]  # (V, 6) signed distances
    out_by = -d[f].max(axis=1)  # (F, 6): > 0 means the whole triangle is outside that plane
    X, Y, Z = c.X, c.Y, c.Z
    spacing = float(np.nanmax(np.hypot(np.diff(X, axis=1), np.diff(Y, axis=1))))
    zr = float(np.nanmax(Z) - np.nanmin(Z))
    lvl = np.asarray(sel.mesh.cell_data["level"])
    tile_diag = np.hypot(2.0 ** (t.grid.t + lvl) * spacing * np.sqrt(2), zr)
    assert (out_by.max(axis=1) <= tile_diag + 1e-6).all()


@pytest.mark.fast
def test_view_looking_away_is_empty_and_decodes_nothing(tmp_path_factory):
    z = generate("fbm", 129, seed=2)
    t = _store(tmp_path_factory, "away", z)
    for s in STRATEGIES:
        sel = t.select(View((0, 0, 5000), (0, 0, 10000)), 1.0, s)
        assert sel.stats["triangles"] == 0 and sel.stats["tiles_decoded"] == 0


def eye_cases(c: Case):
    """(label, eye, target): eyes below all the terrain, inside the data's box (so inside
    every bounding sphere that holds all the data) and a hair above and below the surface,
    all looking at a sample a quarter of the way across the grid."""
    H, W = c.Z.shape
    i, j = c.nearest_valid(H // 2, W // 2)
    j2 = j + 1 if j + 1 < W and c.valid[i, j + 1] else j - 1
    mid = 0.5 * (c.xyz(i, j) + c.xyz(i, j2))  # on the segment between two samples
    target = c.xyz(*c.nearest_valid(H // 4, W // 4))
    yield "below", np.array([mid[0], mid[1], c.lo[2] - 100.0]), target
    yield "inside", np.array([mid[0], mid[1], 0.5 * (c.lo[2] + c.hi[2])]), target
    for dz in (0.5, 1e-3, -1e-3, -0.5):
        yield f"surface{dz:+g}", mid + np.array([0.0, 0.0, dz]), target + [0.0, 0.0, dz]


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_eye_below_terrain_and_inside_spheres(terrains, strategy):
    tau = 1.0
    for c in terrains:
        for label, eye, target in eye_cases(c):
            view = View(tuple(eye), tuple(target), fov_y_deg=45, size=(640, 360))
            if label == "inside":
                assert ((c.lo < eye) & (eye < c.hi)).all()
            seen = n_in_view(c, view)
            assert seen > 100, (c, label, seen)  # the view does look at terrain
            sel = c.t.select(view, tau, strategy, occlusion=False)  # ρ at every sample
            err = screen_error(c, sel, view)
            what = (c, label, err, sel.stats)
            assert np.isfinite(np.asarray(sel.mesh.points)).all(), what
            assert sel.stats["triangles"] > 0 and err.n_samples > 0, what
            assert not strategy_info(strategy).bounded or err.max <= tau * SLACK, what
            # the terrain in view is drawn: tiles whole, rtin all but what its error bound
            # lets slip out of the frustum at the frustum's sides
            assert err.n_uncovered <= (0.01 * seen if strategy == "rtin" else 0), what


@pytest.mark.fast
def test_unchanged_camera_reuses_selection(terrains):
    t = terrains[0].t
    v = random_view(terrains[0], 1.0, 0.5, 1.0, 0, 0)
    a = t.select(v, 1.0)
    b = t.select(v, 1.0)
    assert b.stats["reused"] and b.stats["triangles"] == a.stats["triangles"]


@pytest.mark.fast
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


@pytest.mark.fast
@given(n=st.integers(1, 6), seed=st.integers(0, 10_000), frac=st.floats(0.01, 0.5))
def test_upward_closure_is_closed_and_box_limited_scan_agrees(n, seed, frac):
    from geoterrain.core.bintree import vertex_depth, vertex_parents
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

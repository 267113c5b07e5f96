"""The refinement bound holds in the picture: depth along the view, not distance.

LP's eq. 2 (seed 002) divides a vertex's error δ by its sphere's distance d − r to the eye;
a planar picture divides by the depth z along the view axis, and z = d·cos θ at θ off the
axis, so ρ ≤ τ let the picture move by up to τ/cos²θ (1.2 px on the low flight's corners,
docs/lab/rendering-frame.md). ``rtin`` now tests λkδ > τ(z − r − δ)
(:meth:`geoterrain.core.view.View.terms` with ``depth``). Checked here: the test keeps LP's
nesting (a child's sphere inside its parent's never refines when the parent does not), a
sphere crossing the eye plane refines, and, measured independently of the selection
(:func:`geoterrain.testing.measure.picture_displacement` projects every sample's true and
drawn height through the camera), the drawn surface moves no sample more than τ pixels,
where the distance metric moved it more.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.view import View, ViewTerms
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import kernels, rtin
from geoterrain.testing.measure import picture_displacement

SLACK = 1 + 1e-9
_T: dict = {}


def _terrain(tmp_path_factory):
    if "t" not in _T:
        d = tmp_path_factory.mktemp("picture")
        dem = write_geotiff(d / "d.tif", generate("fbm", 257, seed=3))
        _T["t"] = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain", tile_size=32))
        X, Y, Z = _T["t"].scene_xyz()
        _T["truth"] = (X, Y, Z, np.isfinite(Z))
    return _T["t"], _T["truth"]


def _low_view(t, s: float, fov: float = 45.0, pitch: float = 8.0,
              size: tuple[int, int] = (640, 360)) -> View:
    """The low flight of benchmarks/bench_render.py at ``s`` ∈ [0, 1], on a small store:
    a quarter of the relief above the top, pitched down, heading north-east."""
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    eye = np.array([c[0] + ext * (-0.4 + 0.2 * s), c[1] - 0.4 * ext,
                    hi[2] + 0.25 * (hi[2] - lo[2])])
    a, p = np.radians(45.0), np.radians(pitch)
    fwd = np.array([np.sin(a) * np.cos(p), np.cos(a) * np.cos(p), -np.sin(p)])
    return View(tuple(eye), tuple(eye + 0.2 * ext * fwd), fov_y_deg=fov, size=size)


def _displacement(t, truth, view: View, tau: float, depth: bool, morph: bool = False):
    keep = rtin.DEPTH
    rtin.DEPTH = depth
    try:
        sel = t.select(view, tau, "rtin", occlusion=False, morph=morph, reuse=False)
    finally:
        rtin.DEPTH = keep
    z = np.asarray(sel.mesh.points)[:, 2]
    return picture_displacement(sel.ij, sel.surface_faces(), z, *truth, view)


def _status(view: View, tau: float, c, r, delta, depth: bool) -> int:
    """lp_tiles' status of one sphere (a box of one point), frustum culling left out."""
    return _status_culled(view, tau, c, r, delta, depth, planes=False)


def _status_culled(view: View, tau: float, c, r, delta, depth: bool = True,
                   planes: bool = True) -> int:
    """lp_tiles' status of one sphere (a box of one point), with the view's planes."""
    vt = view.terms(tau, depth=depth)
    if not planes:
        vt = ViewTerms(vt.eye, np.zeros((0, 4)), vt.lam, vt.tau, vt.axis)
    p = np.asarray(c, np.float64).reshape(1, 3)
    d = np.array([float(delta)])
    return int(kernels.lp_tiles(p, p.copy(), d, np.array([float(r)]), d, vt,
                                np.empty(1))[0])


unit = st.floats(-1, 1)


@pytest.mark.fast
@settings(max_examples=200, deadline=None)
@given(eye=st.tuples(unit, unit, unit), look=st.tuples(unit, unit, unit),
       fov=st.floats(10, 120), aspect=st.floats(0.5, 2.5),
       cp=st.tuples(unit, unit, unit), rp=st.floats(1e-3, 1.0),
       off=st.tuples(unit, unit, unit), frac=st.floats(0, 0.99), shrink=st.floats(0, 1),
       dp=st.floats(1e-6, 1.0), dfrac=st.floats(0, 1), tau=st.floats(0.05, 8.0))
def test_nested_spheres_keep_the_depth_bound_monotone(eye, look, fov, aspect, cp, rp, off,
                                                      frac, shrink, dp, dfrac, tau):
    """Depth is linear, so a child's sphere inside its parent's has a nearest depth
    z_c − r_c ≥ z_p − r_p: with δ_c ≤ δ_p the parent's bound is at least the child's, and
    a child is never active where its parent is not (LP's monotone refinement, hence
    crack-freedom, seed 002 §3.1)."""
    e = 10 * np.asarray(eye)
    a = e + np.asarray(look) + 1e-3
    view = View(tuple(e), tuple(a), fov_y_deg=fov, size=(max(1, round(360 * aspect)), 360))
    cp = 10 * np.asarray(cp)
    o = np.asarray(off)
    n = np.linalg.norm(o)
    o = o / n if n > 0 else np.zeros(3)
    dist = frac * rp  # the child's centre inside the parent's sphere ...
    rc = shrink * (rp - dist) * (1 - 1e-9)  # ... and its sphere too
    cc = cp + dist * o
    dc = dfrac * dp
    child, parent = (_status(view, tau, cc, rc, dc, True), _status(view, tau, cp, rp, dp, True))
    assert not child or parent, (child, parent)
    f = view.forward
    zc, zp = float(f @ (cc - e)), float(f @ (cp - e))
    assert zc - rc >= zp - rp - 1e-12


@pytest.mark.fast
def test_a_sphere_crossing_the_eye_plane_refines():
    """A sphere far to the side whose depth interval holds 0 is active under the depth
    metric whatever its δ (it may come in front of the eye), not under LP's distance."""
    view = View((0, 0, 0), (0, 1, 0), fov_y_deg=45.0)
    c, r, delta = (1000.0, 0.5, 0.0), 1.0, 1e-6
    assert _status(view, 1.0, c, r, delta, True) == 2
    assert _status(view, 1.0, c, r, delta, False) == 0
    # in front of the eye plane by more than r: the usual test (δ small: inactive)
    assert _status(view, 1.0, (1000.0, 2.0, 0.0), r, delta, True) == 0


@pytest.mark.fast
def test_lift_is_the_largest_picture_move_of_a_vertical_step():
    """k (View.lift) bounds what a vertical move of δ at depth z does in the picture:
    λkδ/z, over the whole viewport; a level camera has k = 1."""
    rng = np.random.default_rng(4)
    for pitch in (0.0, 8.0, 30.0, 60.0, 89.0):
        p = np.radians(pitch)
        v = View((0, 0, 0), (0, np.cos(p), -np.sin(p)), fov_y_deg=45.0, size=(640, 360))
        r, u, f = v.basis()
        ty = np.tan(np.radians(22.5))
        tx = ty * 640 / 360
        a, b = rng.uniform(-tx, tx, 2000), rng.uniform(-ty, ty, 2000)
        pts = (a[:, None] * r + b[:, None] * u + f) * 100.0  # depth 100, in the picture
        h = 1e-6
        moved = pts + np.array([0, 0, h])
        d0 = pts @ f
        uv0 = np.c_[pts @ r, pts @ u] / d0[:, None]
        uv1 = np.c_[moved @ r, moved @ u] / (moved @ f)[:, None]
        rate = np.hypot(*(uv1 - uv0).T) * d0 / h  # picture move per unit height, × z
        assert rate.max() <= v.lift * (1 + 1e-6)
        assert v.lift >= 1.0
        if pitch == 0.0:
            assert v.lift == 1.0


@pytest.mark.fast
def test_the_picture_moves_more_than_tau_with_distance_and_not_with_depth(tmp_path_factory):
    """The low flight's geometry on a small fBm: LP's distance lets the picture move
    > 1.05 τ; the depth metric keeps every sample within τ."""
    t, truth = _terrain(tmp_path_factory)
    worst = {}
    for depth in (False, True):
        worst[depth] = max(_displacement(t, truth, _low_view(t, s), 1.0, depth).max
                           for s in (0.0, 0.5, 1.0))
    assert worst[False] > 1.05, worst
    assert worst[True] <= SLACK, worst


@settings(max_examples=25, deadline=None)
@given(s=st.floats(0, 1), fov=st.floats(20, 100), down=st.floats(3, 30),
       tau=st.sampled_from([0.5, 1.0, 2.0]), morph=st.booleans())
def test_picture_displacement_is_at_most_tau(tmp_path_factory, s, fov, down, tau, morph):
    """Any field of view, pitched so that the terrain fills the picture's lower part."""
    t, truth = _terrain(tmp_path_factory)
    view = _low_view(t, s, fov, fov / 2 + down)
    e = _displacement(t, truth, view, tau, True, morph)
    assert e.n_samples > 0
    assert e.max <= tau * SLACK, (e, view)


@pytest.mark.fast
@settings(max_examples=300, deadline=None)
@given(eye=st.tuples(unit, unit, unit), look=st.tuples(unit, unit, unit),
       fov=st.floats(10, 120), aspect=st.floats(0.5, 2.5),
       cp=st.tuples(unit, unit, unit), rp=st.floats(1e-3, 3.0),
       off=st.tuples(unit, unit, unit), frac=st.floats(0, 0.99), shrink=st.floats(0, 1),
       dp=st.floats(0, 3.0), dfrac=st.floats(0, 1), tau=st.floats(0.05, 8.0))
def test_culling_by_the_sphere_moved_by_delta_keeps_nesting(eye, look, fov, aspect, cp, rp,
                                                           off, frac, shrink, dp, dfrac,
                                                           tau):
    """A vertex is culled when its sphere, moved up or down by δ, is outside a plane
    (kernels._sphere_out): a child's sphere inside its parent's with δ_c ≤ δ_p is culled
    wherever its parent is, so a child is never refined where its parent is culled (the
    per-vertex test and the one-point tile test of lp_tiles alike)."""
    e = 10 * np.asarray(eye)
    view = View(tuple(e), tuple(e + np.asarray(look) + 1e-3), fov_y_deg=fov,
                size=(max(1, round(360 * aspect)), 360))
    cp = 10 * np.asarray(cp)
    o = np.asarray(off)
    n = np.linalg.norm(o)
    o = o / n if n > 0 else np.zeros(3)
    dist = frac * rp
    rc = shrink * (rp - dist) * (1 - 1e-9)
    cc = cp + dist * o
    dc = dfrac * dp
    planes = view.planes
    out_c = kernels._sphere_out(planes, 6, *cc, rc, dc)
    out_p = kernels._sphere_out(planes, 6, *cp, rp, dp)
    assert out_c or not out_p, (out_c, out_p)
    child = _status_culled(view, tau, cc, rc, dc)
    parent = _status_culled(view, tau, cp, rp, dp)
    assert not child or parent, (child, parent)


@pytest.mark.fast
def test_a_sphere_outside_by_less_than_its_delta_is_kept():
    """The moved sphere is what is tested: a vertex below the bottom plane by more than
    its radius but less than |c|·δ (its drawn samples may come inside) is kept, and one
    beyond that is culled."""
    view = View((0, -1000, 500), (0, 0, 0), fov_y_deg=30.0)
    a, b, c, w = view.planes[2]  # bottom
    assert abs(c) > 0.5
    n = np.array([a, b, c])
    r, delta = 1.0, 10.0
    _, u, f = view.basis()
    q = view.eye + 500.0 * (f - np.tan(np.radians(15.0)) * u)  # the picture's bottom edge
    assert abs(n @ q + w) < 1e-9
    for gap, culled in ((r + 0.5 * abs(c) * delta, False), (r + 1.5 * abs(c) * delta, True)):
        p = q - gap * n  # outside the bottom plane by gap, inside the others
        assert kernels._sphere_out(view.planes, 6, *p, r, 0.0)  # LP's sphere alone: culled
        assert kernels._sphere_out(view.planes, 6, *p, r, delta) == culled
        assert (_status_culled(view, 1e-9, p, r, delta) == 0) == culled


def _shown_from_outside(t, truth, view: View, tau: float):
    """The picture's displacement, and how many counted samples have their true point
    outside the frustum (drawn inside it from outside)."""
    sel = t.select(view, tau, "rtin", occlusion=False, reuse=False)
    z = np.asarray(sel.mesh.points)[:, 2]
    e = picture_displacement(sel.ij, sel.surface_faces(), z, *truth, view)
    X, Y, Z, valid = truth
    inside = np.ones(Z.shape, bool)
    for a, b, c, d in view.planes:
        with np.errstate(invalid="ignore"):
            inside &= a * X + b * Y + c * Z + d >= 0
    return e, e.n_samples - int(np.count_nonzero(inside & valid & np.isfinite(Z)))


@pytest.mark.fast
def test_samples_drawn_into_the_picture_from_outside_move_it_at_most_tau(tmp_path_factory):
    """The frustum's edges: every sample the picture shows, its true point inside the
    frustum or only its drawn point, moves at most τ pixels (a vertex culled by its
    sphere alone left its δ where its samples just outside the bottom plane were drawn
    inside: 5.17 px on these views, measured on the tree before)."""
    t, truth = _terrain(tmp_path_factory)
    worst, outside = 0.0, 0
    for s in (0.0, 0.5, 1.0):
        e, n_out = _shown_from_outside(t, truth, _low_view(t, s), 1.0)
        worst, outside = max(worst, e.max), outside + n_out
    assert outside > 0  # the edge is exercised: samples drawn in from outside counted
    assert worst <= SLACK, worst

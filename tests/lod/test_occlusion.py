"""Horizon culling (geoterrain.lod.occlusion) against an independent ray-march oracle.

The oracle (:func:`geoterrain.testing.reference.visible_samples`) marches from each valid
sample in the frustum to the eye over the drawn full-resolution surface. A culled
selection must cover every sample it finds visible, and the bounded strategies must
keep ρ ≤ τ there; hidden tiles must not be decoded.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import has_real_dem, real_dem, write_tif
from geoterrain import lod
from geoterrain.bench.harness import ground_views
from geoterrain.core.view import View
from geoterrain.lod import strategy_info
from geoterrain.lod.occlusion import (
    _surface_max_near,
    eye_above_surface,
    hidden_rows,
    occluder_rows,
)
from geoterrain.lod.tiles import tile_index
from geoterrain.testing.measure import mesh_heights_on_grid, screen_space_error
from geoterrain.testing.reference import _uj_height, visible_samples

CHECKED = ("rtin", "chunked", "geomipmap", "cdlod", "quadtree", "bruteforce", "tessellation")


def _fbm(n: int, seed: int, amp: float) -> np.ndarray:
    from geoterrain.ingest.synth import generate

    z = generate("fbm", (n, n), seed=seed)
    return amp * (z - z.min()) / max(float(np.ptp(z)), 1e-12)


def _store(tmp_path, z, name="dem", tile_size=16, **tif):
    src = write_tif(tmp_path / f"{name}.tif", z, **tif)
    return geoterrain.open(geoterrain.preprocess(src, tmp_path / f"{name}.geoterrain",
                                                 tile_size=tile_size))


def _low_view(t, rng) -> tuple[View, tuple[int, int]]:
    """A low view from just above a random valid sample, looking across the terrain."""
    return ground_views(*t.scene_xyz(), 1, seed=int(rng.integers(2**31)))[0]


def _eye_ij(t, view) -> tuple[float, float]:
    """The eye's fractional (row, column) on an affine frame."""
    f = t.frame
    cx, cy = f.scene_to_crs(np.array([view.eye[0]]), np.array([view.eye[1]]))
    a, b, c, d, e, g = f.transform
    det = a * e - b * d
    j = (e * (cx[0] - c) - b * (cy[0] - g)) / det - 0.5
    i = (a * (cy[0] - g) - d * (cx[0] - c)) / det - 0.5
    return float(i), float(j)


def _visible(t, view, eye_ij):
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    P = np.stack([X, Y, Zt], -1)
    inside = valid & ((P @ view.planes[:, :3].T + view.planes[:, 3]) >= 0).all(-1)
    return visible_samples(Zt, valid, eye_ij, float(view.eye[2]), inside), inside


def check_nothing_visible_lost(t, view, eye_ij, strategies=CHECKED, tau=1.0) -> tuple[int, int]:
    """Assert every oracle-visible sample is drawn (and ρ ≤ τ there for the bounded
    strategies); return (hidden level-0 tiles in the frustum, those culled)."""
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    vis, inside = _visible(t, view, eye_ij)
    for s in strategies:
        sel = lod.select(t, view, tau, s, reuse=False)
        ij, faces = sel.ij, sel.surface_faces()
        vz = np.asarray(sel.mesh.points)[:, 2] if len(faces) else np.zeros(0)
        _, cov = mesh_heights_on_grid(ij, faces, vz, Z.shape)
        lost = vis & ~cov
        assert not lost.any(), f"{s}: {int(lost.sum())} visible samples not drawn ({view})"
        if strategy_info(s).bounded:
            e = screen_space_error(ij, faces, vz, X, Y, Zt, vis, view.eye, view.planes,
                                   view.lam)
            assert e.max <= tau * (1 + 1e-9) + 1e-9, f"{s}: ρ {e.max} px at a visible sample"
    ix = tile_index(t)
    hidden = hidden_rows(t, view)
    S = 1 << t.grid.t
    n_hidden = n_culled = 0
    for r in np.flatnonzero(ix.keys[:, 0] == 0):
        _, x, y = ix.keys[r]
        win = (slice(y * S, y * S + S + 1), slice(x * S, x * S + S + 1))
        if inside[win].any() and not vis[win].any():
            n_hidden += 1
            n_culled += bool(hidden[r])
        assert not (hidden[r] and vis[win].any()), "a tile with a visible sample was culled"
    return n_hidden, n_culled


# ---------------------------------------------------------------- the rule itself
@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    """Rough ground 0–40 m high with a 300 m wall across the middle rows."""
    z = _fbm(129, 1, 40.0)
    z[60:68, :] = 300.0
    return _store(tmp_path_factory.mktemp("wall"), z, "wall", spacing=10.0)


def _behind_and_front(t):
    ix = tile_index(t)
    L0 = ix.keys[:, 0] == 0
    mid = 0.5 * (ix.lo[:, 1] + ix.hi[:, 1])
    # rows count down the raster: row 0 is the north edge (largest scene y)
    return np.flatnonzero(L0 & (ix.hi[:, 1] < -200.0)), np.flatnonzero(L0 & (mid > 100.0))


@pytest.mark.fast
def test_a_wall_hides_the_tiles_behind_it(wall):
    """Seen from 5 m above the highest ground north of the wall, looking south, the tiles beyond the
    wall are culled and those before it are not."""
    v = View((0.0, 400.0, 45.0), (0.0, -400.0, 0.0), size=(320, 180), fov_y_deg=60.0)
    behind, front = _behind_and_front(wall)
    hidden = hidden_rows(wall, v)
    assert hidden[behind].mean() > 0.5
    assert not hidden[front].any()
    assert not hidden_rows(wall, v, enabled=False).any()
    # the selections skip them: fewer triangles drawn (τ small enough that the ground
    # behind the wall would be refined)
    for s in ("rtin", "chunked"):
        on = lod.select(wall, v, 0.2, s, reuse=False)
        off = lod.select(wall, v, 0.2, s, reuse=False, occlusion=False)
        assert on.stats["triangles"] < off.stats["triangles"], s


@pytest.mark.fast
def test_a_wall_higher_than_the_eye_but_seen_over_from_above(wall):
    """From above the wall's top nothing behind it within the view is culled that the
    oracle sees, and some of it is seen."""
    v = View((0.0, 400.0, 400.0), (0.0, -600.0, 0.0), size=(320, 180), fov_y_deg=60.0)
    assert hidden_rows(wall, v).any()
    n_hidden, _ = check_nothing_visible_lost(wall, v, _eye_ij(wall, v))
    assert n_hidden > 0  # the wall does hide some ground behind it


@pytest.mark.fast
def test_no_culling_when_the_eye_is_inside_the_terrain(wall):
    v = View((0.0, 0.0, 100.0), (0.0, -400.0, 100.0), size=(320, 180))  # inside the wall
    assert not eye_above_surface(wall, v)
    assert not hidden_rows(wall, v).any()


@pytest.mark.fast
def test_no_culling_from_outside_the_grid(wall):
    v = View((0.0, 5000.0, 10.0), (0.0, 0.0, 0.0), size=(320, 180))
    assert not hidden_rows(wall, v).any()


@pytest.mark.fast
def test_no_culling_when_the_near_plane_cuts_the_ground(wall):
    """A near plane farther than the eye's height above the ground clips the ground
    before it, so what lies behind a clipped occluder can show: nothing is culled."""
    v = View((0.0, 400.0, 45.0), (0.0, -400.0, 0.0), size=(320, 180), fov_y_deg=60.0,
             near=50.0)
    assert not eye_above_surface(wall, v)
    assert not hidden_rows(wall, v).any()


@pytest.mark.fast
def test_a_gap_in_the_data_is_not_a_horizon(tmp_path):
    """Across a nodata trench a ray may pass under a plateau (no surface joins them) and
    see the ground beyond from below, as a depth render does: the plateau must not
    occlude for rays that crossed the gap."""
    z = np.full((129, 129), 40.0)
    z[45:53] = -9999.0  # the trench
    z[53:85] = 100.0  # the plateau
    z[85:] = 60.0  # the ground beyond
    t = _store(tmp_path, z, "gap", spacing=10.0, nodata=-9999.0)
    X, Y, Z = t.scene_xyz()
    eye = (float(X[20, 64]), float(Y[20, 64]), 50.0)
    v = View(eye, (eye[0], eye[1] - 900.0, 55.0), size=(320, 180), fov_y_deg=40.0)
    vis, _ = _visible(t, v, (20.0, 64.0))
    assert vis[90:].any()  # the ground beyond is seen, under the plateau
    check_nothing_visible_lost(t, v, (20.0, 64.0), strategies=("chunked", "rtin"))


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.floats(0.0, 0.3))
def test_surface_bound_near_the_eye(seed, rc):
    """The bound used for "the eye is above the surface" is ≥ the surface anywhere
    within rc cells of the point (checked on the oracle's own interpolation)."""
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 10, (6, 6))
    ii, jj = rng.uniform(2, 3, 2)
    bound = _surface_max_near(z[1:5, 1:5], 1, 1, ii, jj, rc)
    a = rng.uniform(0, 2 * np.pi, 400)
    r = rc * np.sqrt(rng.uniform(0, 1, 400))
    h = _uj_height(z, np.ones_like(z, bool), ii + r * np.sin(a), jj + r * np.cos(a))
    assert np.nanmax(h) <= bound + 1e-9


# ---------------------------------------------------------------- against the oracle
@pytest.fixture(scope="module")
def holey(tmp_path_factory):
    """A rough 129² fBm with a nodata lake and a nodata corner."""
    z = _fbm(129, 7, 300.0)
    z[40:56, 70:90] = -9999.0
    z[100:, :20] = -9999.0
    return _store(tmp_path_factory.mktemp("holey"), z, "holey", spacing=10.0, nodata=-9999.0)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6))
def test_random_low_views_lose_nothing_visible(holey, seed):
    view, ij = _low_view(holey, np.random.default_rng(seed))
    check_nothing_visible_lost(holey, view, ij)


@pytest.mark.parametrize("name", ["st_helens_terrain_rgb.png", "srtm3_pysheds.tif",
                                  "roi_epsg3089.tif"])
def test_real_dems_lose_nothing_visible(tmp_path, name):
    src = real_dem(name)
    kw = {"pixel_size": 10.0} if name.endswith(".png") else {}
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "r.geoterrain", tile_size=16,
                                              **kw))
    rng = np.random.default_rng(3)
    for _ in range(3):
        view, ij = _low_view(t, rng)
        check_nothing_visible_lost(t, view, ij, strategies=("rtin", "chunked", "cdlod"))


@pytest.mark.fast
def test_hidden_tiles_are_not_decoded(tmp_path):
    """Behind a ridge, culled level-0 tiles are neither decoded nor drawn (except the
    few nearest read as occluders, should one of them lie behind another)."""
    z = _fbm(257, 2, 100.0)
    z[120:130, :] += 400.0  # a ridge across the middle
    t = _store(tmp_path, z, "ridge", tile_size=16, spacing=10.0)
    X, Y, Z = t.scene_xyz()
    i, j = 40, 128
    eye = (float(X[i, j]), float(Y[i, j]), float(Z[i, j]) + 5.0)
    v = View(eye, (eye[0], eye[1] - 2000.0, eye[2] - 50.0), size=(320, 180), fov_y_deg=60.0)
    hidden = hidden_rows(t, v)
    ix = tile_index(t)
    culled = [tuple(k) for k in ix.keys[hidden & (ix.keys[:, 0] == 0)].tolist()]
    assert len(culled) > 10
    t2 = geoterrain.open(t.path)  # an empty cache
    sel = lod.select(t2, v, 1.0, "chunked", reuse=False)
    assert sel.stats["tiles_hidden"] > 0
    decoded = {k[1:] for k in t2.cache_keys() if k[0] == "h"}
    read = {tuple(k) for k in tile_index(t2).keys[occluder_rows(t2, v)].tolist()}
    assert len(read) <= 40
    assert not (decoded & set(culled)) - read, "a culled tile was decoded"
    assert len(set(culled) - decoded) > 10


@pytest.mark.slow
def test_a_hundred_low_views(tmp_path):
    """The issue's view set: ≥ 100 random low views over synthetic and real DEMs, 0 lost
    visible samples, ≥ 50 % of the hidden level-0 tiles culled."""
    stores = {"fbm513": (_fbm(513, 2, 600.0), dict(spacing=30.0)),
              "holey": (None, None)}
    terrains = []
    z, kw = stores["fbm513"]
    terrains.append(_store(tmp_path, z, "fbm513", **kw))
    zh = _fbm(257, 7, 300.0)
    zh[80:110, 140:180] = -9999.0
    terrains.append(_store(tmp_path, zh, "holes", spacing=10.0, nodata=-9999.0))
    for name in ("fuji_terrain_rgb.png", "st_helens_terrain_rgb.png", "terrarium.png",
                 "srtm3_pysheds.tif", "roi_epsg3089.tif"):
        if has_real_dem(name):
            kw = {"pixel_size": 10.0} if name.endswith(".png") else {}
            terrains.append(geoterrain.open(geoterrain.preprocess(
                real_dem(name), tmp_path / f"{name}.geoterrain", tile_size=16, **kw)))
    rng = np.random.default_rng(11)
    per = -(-100 // len(terrains))
    hidden = culled = 0
    for t in terrains:
        for _ in range(per):
            view, ij = _low_view(t, rng)
            h, c = check_nothing_visible_lost(t, view, ij, strategies=("rtin", "chunked"))
            hidden, culled = hidden + h, culled + c
    assert culled >= 0.5 * hidden, f"culled {culled} of {hidden} hidden level-0 tiles"


# ---------------------------------------------------------------- the kernel, alone
@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6))
def test_the_horizon_kernel_hides_only_what_an_occluder_covers(seed):
    """``_horizon_cull`` on random square footprints (some holes) and boxes: for every
    box it hides, each sampled ray to the box's top passes under an occluder's lowest
    height inside that occluder's footprint, nearer than the box, having crossed no hole
    on the way there (the geometric claim the culling rests on)."""
    from geoterrain.lod.horizon import FootprintSet, _horizon_cull
    from geoterrain.lod.occlusion import _centres

    rng = np.random.default_rng(seed)
    n = 8
    ty, tx = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x0, y0 = tx.ravel() * 100.0, ty.ravel() * 100.0
    corners = np.stack([np.stack([x0, y0], 1), np.stack([x0 + 100, y0], 1),
                        np.stack([x0 + 100, y0 + 100], 1), np.stack([x0, y0 + 100], 1)], 1)
    state = (rng.uniform(size=n * n) > 0.1).astype(np.int8)
    zmin = rng.uniform(0, 150, n * n)
    eye = np.array([rng.uniform(0, 800), rng.uniform(0, 800), 0.0])
    p_eye = int(eye[1] // 100) * n + int(eye[0] // 100)
    state[p_eye] = 1
    eye[2] = zmin[p_eye] + rng.uniform(1, 60)
    lo = np.stack([rng.uniform(0, 750, 40), rng.uniform(0, 750, 40), np.zeros(40)], 1)
    hi = lo + np.stack([rng.uniform(5, 50, 40), rng.uniform(5, 50, 40),
                        rng.uniform(0, 200, 40)], 1)
    out = np.zeros(40, bool)
    _horizon_cull(eye[0], eye[1], eye[2], FootprintSet(corners, _centres(corners), state, zmin,
                                                     0.0), 0.0, 4 * np.pi, lo, hi, out)
    s = np.linspace(0, 1, 4001)[1:-1]
    for r in np.flatnonzero(out):
        for _ in range(25):
            q = np.array([rng.uniform(lo[r, 0], hi[r, 0]), rng.uniform(lo[r, 1], hi[r, 1]),
                          hi[r, 2]])
            p = eye + s[:, None] * (q - eye)
            cell = (np.clip(p[:, 1] // 100, 0, n - 1) * n
                    + np.clip(p[:, 0] // 100, 0, n - 1)).astype(int)
            inside = (p[:, 0] >= 0) & (p[:, 0] < 800) & (p[:, 1] >= 0) & (p[:, 1] < 800)
            hole = ~inside | (state[cell] == 0)
            first_hole = np.argmax(hole) if hole.any() else len(s)
            under = (state[cell] == 1) & inside & (p[:, 2] < zmin[cell])
            assert under[:first_hole].any(), f"box {r} hidden, but a ray to {q} is not blocked"


@pytest.mark.fast
@settings(max_examples=200, deadline=None)
@given(st.integers(0, 10**6))
def test_the_kernel_geometry_matches_plain_trigonometry(seed):
    """``_poly_span`` (extremes by pseudo-angle, two atan2) and ``_in_sector`` (a wedge
    test without angles) against the same quantities taken with atan2 everywhere."""
    from geoterrain.lod.horizon import _in_sector, _poly_span, _wedge

    rng = np.random.default_rng(seed)
    ex, ey = rng.uniform(-50, 50, 2)
    c = rng.uniform(-40, 40, 2) + np.array([ex, ey]) * rng.choice([0.0, 1.0])
    w_, h_ = rng.uniform(0.5, 30, 2)
    quad = c + np.array([[0, 0], [w_, 0], [w_, h_], [0, h_]], float)
    if rng.uniform() < 0.5:  # the eye just outside an edge: corners behind it too
        side = rng.integers(4)
        t_ = rng.uniform(-0.2, 1.2)
        off = rng.uniform(1e-3, 3.0)
        ex, ey = {0: (c[0] + t_ * w_, c[1] - off), 1: (c[0] + w_ + off, c[1] + t_ * h_),
                  2: (c[0] + t_ * w_, c[1] + h_ + off), 3: (c[0] - off, c[1] + t_ * h_)}[side]
    s, w, dn, df = _poly_span(ex, ey, quad)
    d = quad - [ex, ey]
    inside = (quad[0, 0] < ex < quad[1, 0]) and (quad[0, 1] < ey < quad[2, 1])
    assert np.isclose(df, np.hypot(d[:, 0], d[:, 1]).max(), rtol=1e-12)
    if inside:
        assert w < 0
        return
    ref = np.arctan2(d[:, 1].mean(), d[:, 0].mean())
    a = (np.arctan2(d[:, 1], d[:, 0]) - ref + np.pi) % (2 * np.pi) - np.pi
    if a.max() - a.min() >= np.pi - 1e-9:
        return
    assert w >= 0
    assert np.isclose(w, a.max() - a.min(), atol=1e-12)
    assert np.isclose((s - (ref + a.min()) + np.pi) % (2 * np.pi) - np.pi, 0.0, atol=1e-12)
    near = np.hypot(max(quad[0, 0] - ex, 0, ex - quad[1, 0]),
                    max(quad[0, 1] - ey, 0, ey - quad[2, 1]))
    assert np.isclose(dn, near, rtol=1e-12, atol=1e-12)
    # the wedge test: may the footprint's circle meet the sector?
    sec0, secw = rng.uniform(-np.pi, np.pi), rng.uniform(0.01, np.pi - 0.01)
    cen = np.array([*quad.mean(0), np.hypot(w_, h_) / 2])
    dc = np.hypot(cen[0] - ex, cen[1] - ey)
    if dc <= cen[2] * (1 + 1e-6):
        return
    half = np.arcsin(cen[2] / dc)
    lo_ = (np.arctan2(cen[1] - ey, cen[0] - ex) - half - sec0) % (2 * np.pi)
    want = lo_ <= secw or lo_ + 2 * half >= 2 * np.pi
    if min(abs(lo_ - secw), abs(lo_ + 2 * half - 2 * np.pi)) < 1e-9:
        return  # on the sector's edge: either answer is within rounding
    assert _in_sector(ex, ey, cen, _wedge(sec0, secw)) == want


def _hidden_in_one_pass(t, view):
    """Culling without the upper-bound pass: the near tiles refined into blocks always,
    every row tested against that horizon."""
    from geoterrain.lod import occlusion as oc

    index = tile_index(t)
    out = np.zeros(len(index.keys), bool)
    if index.outside(view) or not eye_above_surface(t, view):
        return out
    fp = oc._footprints(t)
    rows, replaced = oc._near_tiles(t, index, view)
    state, corners, cen, zmin = fp.state.copy(), fp.corners, fp.centres, fp.zmin
    if len(rows):
        bc, bcen, bs, bz = oc._near_blocks(t, index, rows)
        state[replaced] = -1
        corners, cen = np.concatenate([corners, bc]), np.concatenate([cen, bcen])
        state, zmin = np.concatenate([state, bs]), np.concatenate([zmin, bz])
    e = view.eye
    oc._horizon_cull(float(e[0]), float(e[1]), float(e[2]),
                     oc.FootprintSet(corners, cen, state, zmin, fp.margin), *oc._sector(view),
                     index.lo, index.hi, out)
    return out


@pytest.fixture(scope="module")
def rough_store(tmp_path_factory):
    d = tmp_path_factory.mktemp("rough")
    return _store(d, _fbm(129, 5, 60.0), tile_size=16)


@pytest.mark.fast
@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.integers(0, 10**6), st.booleans())
def test_the_upper_bound_pass_changes_nothing(rough_store, seed, low):
    """``hidden_rows`` first bounds the near tiles' blocks by their highest sample and
    refines only when that bound hides something: it must give exactly what one pass
    with the blocks always refined gives."""
    t = rough_store
    rng = np.random.default_rng(seed)
    if low:
        view = _low_view(t, rng)[0]
    else:
        X, Y, Z = t.scene_xyz()
        ext = float(np.nanmax(np.abs(X)))
        az, el = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(3, 40))
        dist = ext * rng.uniform(0.3, 2.0)
        target = np.array([*rng.uniform(-0.5 * ext, 0.5 * ext, 2), float(np.nanmedian(Z))])
        eye = target + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                        np.sin(el)])
        eye[2] = max(eye[2], float(np.nanmax(Z)) + rng.uniform(-30, 30))
        view = View(tuple(eye), tuple(target), size=(320, 180))
    got = hidden_rows(t, view)
    want = _hidden_in_one_pass(t, dataclasses.replace(view, memos={}))
    assert np.array_equal(got, want)
    # asked about some rows only (what a strategy's walk reaches): the same answer for
    # those, not hidden for the others
    some = np.flatnonzero(rng.random(len(want)) < rng.uniform(0.05, 0.6))
    part = hidden_rows(t, dataclasses.replace(view, memos={}), rows=some)
    assert np.array_equal(part[some], want[some])
    assert not np.delete(part, some).any()


@pytest.mark.fast
@settings(max_examples=80, deadline=None)
@given(st.integers(0, 10**6))
def test_a_standing_in_footprint_bounds_its_blocks(seed):
    """The kernel's state 2: a footprint standing in for its 4 × 4 blocks at their
    highest sample hides at least every box those blocks hide (the upper-bound pass of
    :func:`hidden_rows` relies on it)."""
    from geoterrain.lod.horizon import FootprintSet, _horizon_cull
    from geoterrain.lod.occlusion import _centres

    rng = np.random.default_rng(seed)
    n, k = 8, 4
    ty, tx = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x0, y0 = tx.ravel() * 100.0, ty.ravel() * 100.0

    def squares(x, y, w):
        return np.stack([np.stack([x, y], 1), np.stack([x + w, y], 1),
                         np.stack([x + w, y + w], 1), np.stack([x, y + w], 1)], 1)

    corners = squares(x0, y0, 100.0)
    state = (rng.uniform(size=n * n) > 0.1).astype(np.int8)
    zmin = rng.uniform(0, 100, n * n)
    eye = np.array([rng.uniform(0, 800), rng.uniform(0, 800), 0.0])
    p_eye = int(eye[1] // 100) * n + int(eye[0] // 100)
    state[p_eye] = 1
    eye[2] = zmin[p_eye] + rng.uniform(1, 60)
    # some valid footprints (not the eye's) split into blocks of random heights
    split = [p for p in np.flatnonzero(state == 1) if p != p_eye and rng.uniform() < 0.4]
    by, bx = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    bc = np.concatenate([squares(x0[p] + bx.ravel() * 25.0, y0[p] + by.ravel() * 25.0, 25.0)
                         for p in split]) if split else np.zeros((0, 4, 2))
    bz = rng.uniform(0, 200, len(bc))
    top = np.array([bz[i * k * k:(i + 1) * k * k].max() for i in range(len(split))])
    lo = np.stack([rng.uniform(0, 750, 60), rng.uniform(0, 750, 60), np.zeros(60)], 1)
    hi = lo + np.stack([rng.uniform(5, 50, 60), rng.uniform(5, 50, 60),
                        rng.uniform(0, 150, 60)], 1)
    fine_state = state.copy()
    fine_state[split] = -1
    fine = np.zeros(60, bool)
    every = np.concatenate([corners, bc])
    _horizon_cull(eye[0], eye[1], eye[2],
                  FootprintSet(every, _centres(every),
                               np.concatenate([fine_state, np.ones(len(bc), np.int8)]),
                               np.concatenate([zmin, bz]), 0.0), 0.0, 4 * np.pi, lo, hi, fine)
    up_state, up_z = state.copy(), zmin.copy()
    up_state[split], up_z[split] = 2, top
    upper = np.zeros(60, bool)
    if _horizon_cull(eye[0], eye[1], eye[2], FootprintSet(corners, _centres(corners), up_state,
                                                        up_z, 0.0), 0.0, 4 * np.pi, lo, hi,
                     upper) == 0:
        assert not (fine & ~upper).any(), "a box the blocks hide is not hidden by the bound"

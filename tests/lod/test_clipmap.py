"""Geometry clipmaps (``clipmap``, ``clipmap_bounded``, ``clipmap_gpu``): toroidal updates
that read only the newly exposed samples, a constant amount of geometry along a flight
and, for ``clipmap`` (whole rings, no culling unless ``cull=True``), a constant count
drawn, conforming meshes that cover every valid sample (no-data and padding included),
and the bounded variant's ρ ≤ τ with the transitions on.

Small regions (n = 15 or 31) give several levels on small terrains; the registered
strategies (n = 255) are also run by tests/lod/test_lod.py and tests/test_stress.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.bench.harness import extent, glide
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import Selection, clipmap, clipmaps
from geoterrain.testing.measure import mesh_height_range_on_grid, screen_space_error


@pytest.fixture(scope="module")
def holey(tmp_path_factory):
    """A 300 × 260 fBm with a no-data lake, padded to 513²."""
    d = tmp_path_factory.mktemp("clip")
    z = generate("fbm", (300, 260), seed=8).astype(np.float32) * 2
    yy, xx = np.mgrid[:300, :260]
    z[(yy - 200) ** 2 + (xx - 70) ** 2 < 400] = np.nan
    dem = write_geotiff(d / "h.tif", z, nodata=np.nan)
    return geoterrain.open(geoterrain.preprocess(dem, d / "h.geoterrain", tile_size=16,
                                                 root_grid=False))


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    """A 513² fBm: no padding, no no-data."""
    d = tmp_path_factory.mktemp("clipsq")
    dem = write_geotiff(d / "s.tif", generate("fbm", 513, seed=2))
    return geoterrain.open(geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=32))


def _views(t, k, seed, size=(480, 270)):
    X, Y, Z = t.scene_xyz()
    lo, hi = extent(X, Y, Z)
    c, r = 0.5 * (lo + hi), float(np.linalg.norm(hi[:2] - lo[:2]))
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(0.03, 1.2)
        d = r * rng.uniform(0.05, 0.9)
        base = c + rng.normal(0, 0.25 * r, 3) * [1, 1, 0]
        eye = base + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                   np.sin(el)])
        out.append(View(tuple(eye), tuple(base), size=size, fov_y_deg=45))
    return out


def _check_conforming(t, sel):
    """Every edge used at most twice, one height per grid point (no crack, no T-junction)."""
    f = sel.surface_faces()
    if not len(f):
        return
    N = t.grid.size
    ij = np.asarray(sel.ij, np.int64)
    key = (ij[:, 0] * N + ij[:, 1])[f]
    e = np.sort(np.concatenate([key[:, [0, 1]], key[:, [1, 2]], key[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e[:, 0] * N * N + e[:, 1], return_counts=True)
    assert counts.max() <= 2
    z = np.asarray(sel.mesh.points)[:, 2]
    lo, hi = mesh_height_range_on_grid(sel.ij, f, z, (t.grid.rows, t.grid.cols))
    assert np.nan_to_num(hi - lo).max() <= 1e-9 * max(1.0, float(np.nanmax(np.abs(z))))


def _uncovered_far_from_nodata(t, sel, view) -> int:
    """Valid samples in the frustum, not next to no-data, that no triangle covers."""
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    f = sel.surface_faces()
    z = np.asarray(sel.mesh.points)[:, 2] if len(f) else np.zeros(0)
    lo, _ = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
    P = np.stack([X, Y, np.where(valid, Z, 0.0)], -1)
    inside = (P @ view.planes[:, :3].T + view.planes[:, 3] >= 0).all(-1)
    pad = np.pad(~valid, 1, constant_values=True)
    near = np.zeros_like(valid)
    H, W = Z.shape
    for a in range(3):
        for b in range(3):
            near |= pad[a:a + H, b:b + W]
    return int((valid & inside & ~near & ~np.isfinite(lo)).sum())


@pytest.mark.fast
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10**6), kind=st.sampled_from(["clipmap", "bounded", "gpu"]),
       n=st.sampled_from([15, 31]), morph=st.booleans(), tau=st.sampled_from([1.0, 4.0]),
       cull=st.sampled_from([None, True, False]))
def test_conforming_covering_and_bounded(holey, seed, kind, n, morph, tau, cull):
    X, Y, Z = holey.scene_xyz()
    valid = np.isfinite(Z)
    for view in _views(holey, 2, seed):
        mesh, stats = clipmaps.select(holey, view, tau, kind=kind, occlusion=False,
                                      morph=morph, n=n, cull=cull)
        sel = Selection(mesh, stats)
        _check_conforming(holey, sel)
        # the culled rectangles lie outside the frustum: nothing inside goes uncovered
        assert _uncovered_far_from_nodata(holey, sel, view) == 0
        f = sel.surface_faces()
        if kind == "bounded" and len(f):
            e = screen_space_error(sel.ij, f, np.asarray(mesh.points)[:, 2], X, Y,
                                   np.where(valid, Z, 0.0), valid, view.eye, view.planes,
                                   view.lam)
            assert e.max <= tau * (1 + 1e-9), (e.max, stats)


@pytest.mark.fast
def test_toroidal_updates_read_only_the_exposed_samples(square):
    """Moving the viewer reads exactly the samples the new regions add (an L-shaped ring
    per level), and every buffer then holds the store's heights."""
    X, Y, Z = square.scene_xyz()
    views = [v for _, v in glide(*extent(X, Y, Z), n_frames=30, step=0.2, size=(480, 270))]
    square.forget(f"{clipmaps.__name__}.state.clipmap.31")
    regions = None
    for k, v in enumerate(views):
        _, stats = clipmaps.select(square, v, 4.0, n=31)
        state = square.derived(f"{clipmaps.__name__}.state.clipmap.31", dict)
        now = {lv: (st_.r0, st_.r1, st_.c0, st_.c1) for lv, st_ in state["levels"].items()}
        if regions is not None:
            want = 0
            for lv, (r0, r1, c0, c1) in now.items():
                cur = np.zeros((square.grid.size,) * 2, bool)
                s = 1 << lv
                cur[r0 * s:(r1 + 1) * s:s, c0 * s:(c1 + 1) * s:s] = True
                if lv in regions:
                    q0, q1, p0, p1 = regions[lv]
                    cur[q0 * s:(q1 + 1) * s:s, p0 * s:(p1 + 1) * s:s] = False
                want += int(cur.sum())
            assert stats["samples_updated"] == want, (k, stats, now, regions)
        regions = now
        for lv, st_ in state["levels"].items():  # the buffers hold the level's samples
            s = 1 << lv
            r = np.arange(st_.r0, st_.r1 + 1)
            c = np.arange(st_.c0, st_.c1 + 1)
            got = clipmaps.buffer_heights(st_, r[:, None], c[None, :])
            np.testing.assert_array_equal(got, Z[np.ix_(r * s, c * s)])


@pytest.mark.fast
def test_the_geometry_is_constant_along_a_flight(square):
    """§2.9's steady rendering rate: the same number of triangles every frame (before
    culling) while the viewer's height keeps the same levels."""
    X, Y, Z = square.scene_xyz()
    views = [v for _, v in glide(*extent(X, Y, Z), n_frames=25, step=0.05, size=(480, 270))]
    counts = {}
    for v in views:
        _, stats = clipmaps.select(square, v, 4.0, n=63)
        counts.setdefault(stats["levels"], set()).add(stats["clipmap_triangles"])
    assert all(len(c) == 1 for c in counts.values()), counts


@pytest.mark.fast
def test_regions_nest_and_keep_even_perimeters(holey):
    for view in _views(holey, 5, 3):
        clipmaps.select(holey, view, 2.0, n=31)
        levels = holey.derived(f"{clipmaps.__name__}.state.clipmap.31", dict)["levels"]
        for lv, st_ in levels.items():
            assert st_.r0 % 2 == 0 and st_.c0 % 2 == 0 and st_.r1 % 2 == 0
            assert st_.c1 % 2 == 0
            if lv + 1 in levels:
                P = levels[lv + 1]
                assert 2 * P.r0 <= st_.r0 and st_.r1 <= 2 * P.r1
                assert 2 * P.c0 <= st_.c0 and st_.c1 <= 2 * P.c1


class _NoCulling(View):
    """A view that culls nothing (no frustum planes): the clipmap's whole geometry."""

    @property
    def planes(self) -> np.ndarray:
        return np.zeros((0, 4))


def _flights(t, frames):
    from geoterrain.bench.experiments import minute_flight

    X, Y, Z = t.scene_xyz()
    lo, hi = extent(X, Y, Z)
    return {"glide": [v for _, v in glide(lo, hi, n_frames=frames, step=0.2,
                                          size=(480, 270))],
            "minute loop": [v for _, v in minute_flight(lo, hi, frames, size=(480, 270),
                                                        warmup=False)]}


@pytest.mark.fast
@pytest.mark.parametrize("kind", ["clipmap", "gpu"])
def test_the_count_is_constant_along_level_flights(square, kind):
    """§2.9's steady rendering rate on the glide and the one-minute loop (both level
    flights): the clipmap's triangles before culling, and the mesh drawn without culling,
    stay constant within 5 % (the geometry exactly; the mesh varies by the stitched
    perimeter sides that lie on the DEM's edge); culling (``clipmap_gpu``'s footprints,
    ``clipmap``'s 4 strips with ``cull=True``) is a separate step that only removes
    triangles (its count follows the heading: reported, not held constant)."""
    for name, views in _flights(square, 12).items():
        geometry, uncull, culled = [], [], []
        for v in views:
            mesh, stats = clipmaps.select(square, v, 4.0, kind=kind, occlusion=False, n=31,
                                          cull=True)
            nc = _NoCulling(v.look_from, v.look_at, v.up, v.fov_y_deg, v.size, v.near, v.far)
            whole, s2 = clipmaps.select(square, nc, 4.0, kind=kind, occlusion=False, n=31,
                                        cull=True)
            assert s2["cells_culled"] == 0 and s2["levels"] == stats["levels"]
            geometry.append(stats["clipmap_triangles"])
            uncull.append(whole.n_cells)
            culled.append(mesh.n_cells)
        for counts in (geometry, uncull):
            c = np.array(counts)
            assert (c.max() - c.min()) <= 0.05 * np.median(c), (name, counts)
        assert all(a <= b for a, b in zip(culled, uncull, strict=True)), (name, culled)


def _turning_flights(t, k, frames, seed, size=(480, 270)):
    """``k`` seeded random flights of ``frames`` views at a constant height above the
    highest terrain (so §2.9's level rule keeps the same levels): the heading turns at a
    rate that changes, the pitch drifts between 5° and 60° down, the eye moves ahead and
    turns back at the DEM's edges."""
    X, Y, Z = t.scene_xyz()
    lo, hi = extent(X, Y, Z)
    width = float(min(hi[:2] - lo[:2]))
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        pos = lo[:2] + (hi[:2] - lo[:2]) * rng.uniform(0.25, 0.75, 2)
        z = float(hi[2]) + width * rng.uniform(0.02, 0.15)
        yaw, pitch = rng.uniform(0, 2 * np.pi), rng.uniform(5.0, 60.0)
        rate = rng.uniform(-0.6, 0.6)
        views = []
        for _ in range(frames):
            p = np.radians(pitch)
            ahead = np.array([np.cos(yaw) * np.cos(p), np.sin(yaw) * np.cos(p), -np.sin(p)])
            eye = np.array([pos[0], pos[1], z])
            views.append(View(tuple(eye), tuple(eye + 100.0 * ahead), fov_y_deg=45,
                              size=size))
            rate = float(np.clip(rate + rng.normal(0, 0.3), -0.8, 0.8))
            yaw += rate
            pitch = float(np.clip(pitch + rng.normal(0, 12.0), 5.0, 60.0))
            step = pos + 0.04 * width * np.array([np.cos(yaw), np.sin(yaw)])
            if ((step < lo[:2] + 0.1 * width) | (step > hi[:2] - 0.1 * width)).any():
                yaw += np.pi  # turn back at the edge
            else:
                pos = step
        out.append(views)
    return out


def _spread(counts) -> float:
    c = np.asarray(counts, float)
    return float((c.max() - c.min()) / np.median(c))


def _drawn(mesh) -> int:
    """The triangles a mesh draws, counted from its own cells (not the strategy's stats)."""
    return int(mesh.n_cells)


@pytest.mark.fast
def test_clipmap_draws_a_constant_count_whatever_the_heading(square):
    """``clipmap`` culls nothing by default: along the glide, the one-minute loop and
    seeded random flights whose heading turns and pitch changes (at a constant height
    above the highest terrain), the triangles it draws stay within 5 % (max − min over
    the median), horizon culling asked for or not. The same flights with the paper's
    culling (``cull=True``) spread far beyond 5 % (so these flights tell the two apart)."""
    flights = {**_flights(square, 10),
               **{f"random {k}": v for k, v in enumerate(_turning_flights(square, 3, 10, 46))}}
    culled_spread = {}
    for name, views in flights.items():
        drawn, culled = [], []
        for k, v in enumerate(views):
            mesh, stats = clipmaps.select(square, v, 4.0, n=63, occlusion=k % 2 == 0)
            assert stats["cells_culled"] == 0 and not stats["culled"]
            drawn.append(_drawn(mesh))
            culled.append(_drawn(clipmaps.select(square, v, 4.0, n=63, cull=True)[0]))
        assert len(drawn) == 10 and min(drawn) > 0
        assert _spread(drawn) <= 0.05, (name, drawn)
        assert all(a <= b for a, b in zip(culled, drawn, strict=True)), (name, culled)
        culled_spread[name] = _spread(culled)
    assert culled_spread["minute loop"] > 0.2, culled_spread
    assert sum(v > 0.05 for k, v in culled_spread.items() if k.startswith("random")) >= 2, \
        culled_spread


@pytest.mark.fast
def test_the_registered_clipmap_draws_its_whole_rings(square):
    """Through the seam, with the seam's defaults (horizon culling on): the registered
    ``clipmap`` (n = 255) draws as many triangles looking into a corner as with no
    frustum at all, where ``cull=True`` leaves many of them out."""
    X, Y, Z = square.scene_xyz()
    lo, hi = extent(X, Y, Z)
    eye = (float(lo[0]) + 50.0, float(lo[1]) + 50.0, float(hi[2]) + 100.0)
    v = View(eye, (float(lo[0]) - 500.0, float(lo[1]) - 500.0, float(lo[2])), fov_y_deg=30,
             size=(480, 270))
    sel = square.select(v, 4.0, "clipmap", reuse=False)
    nc = _NoCulling(v.look_from, v.look_at, v.up, v.fov_y_deg, v.size, v.near, v.far)
    whole, _ = clipmap.select(square, nc, 4.0, occlusion=False)
    few, _ = clipmap.select(square, v, 4.0, cull=True)
    assert sel.mesh.n_cells == whole.n_cells > 0
    assert few.n_cells < 0.8 * whole.n_cells, (few.n_cells, whole.n_cells)


@pytest.mark.slow
def test_the_registered_clipmap_count_is_constant_along_flights(square):
    """The registered ``clipmap`` (n = 255, through the seam, horizon culling on as by
    default) on the glide, the one-minute loop and three seeded random flights: the
    triangles drawn stay within 5 %."""
    flights = {**_flights(square, 12),
               **{f"random {k}": v for k, v in enumerate(_turning_flights(square, 3, 12, 7))}}
    for name, views in flights.items():
        drawn = [_drawn(square.select(v, 8.0, "clipmap", reuse=False).mesh) for v in views]
        assert min(drawn) > 0 and _spread(drawn) <= 0.05, (name, drawn)


@pytest.mark.fast
def test_updates_touch_only_the_newly_exposed_l_shapes(square):
    """When the view moves, each level's toroidal height buffer is written exactly at the
    samples the new region adds to the old one (an L-shaped band: whole rows on the side
    it moved to, whole columns on the other), and its normal map (the clipmap's texture)
    only there and one sample beside them; nothing else in either buffer is touched.

    Found by filling the buffers with sentinels before each frame (restored after)."""
    key = clipmaps.state_key("clipmap", 31)
    sz, sn = -1.0e300, 9.0  # no height, no unit normal's component
    for name, views in _flights(square, 40).items():
        square.forget(key)
        moved = 0
        for k, v in enumerate(views):
            state = square.derived(key, dict)
            before = {lv: (s_, (s_.r0, s_.r1, s_.c0, s_.c1), s_.z.copy(), s_.normal.copy())
                      for lv, s_ in state.get("levels", {}).items()}
            for s_, _, _, _ in before.values():
                s_.z[:] = sz
                s_.normal[:] = sn
            clipmaps.select(square, v, 4.0, n=31)
            for lv, s_ in state["levels"].items():
                if lv not in before or before[lv][0] is not s_:
                    continue  # a level that joined (or a buffer that grew) is read whole
                _, (q0, q1, p0, p1), z0, n0 = before[lv]
                size = s_.size
                rows, cols = np.arange(s_.r0, s_.r1 + 1), np.arange(s_.c0, s_.c1 + 1)
                kept_r = (rows >= q0) & (rows <= q1)
                kept_c = (cols >= p0) & (cols <= p1)
                new = ~(kept_r[:, None] & kept_c[None, :])
                want = np.zeros((size, size), bool)
                want[np.ix_(rows % size, cols % size)] = new
                # an L: the new rows whole, then the new columns of the kept rows
                dr, dc = int((~kept_r).sum()), int((~kept_c).sum())
                assert want.sum() == dr * len(cols) + dc * (len(rows) - dr), (name, k, lv)
                wrote = s_.z != sz
                np.testing.assert_array_equal(wrote, want, err_msg=f"{name} {k} level {lv}")
                near = want.copy()  # the exposed samples and their 4-neighbours, toroidally
                for ax in (0, 1):
                    near |= np.roll(want, 1, ax) | np.roll(want, -1, ax)
                wn = (s_.normal != sn).any(-1)
                assert not (wn & ~near).any() and not (want & ~wn).any(), (name, k, lv)
                moved += int(new.any())
                s_.z[~wrote] = z0[~wrote]  # restore what was not rewritten
                s_.normal[~wn] = n0[~wn]
        assert moved >= 5, (name, moved)  # the flights do move the regions

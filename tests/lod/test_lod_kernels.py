"""The one-pass mesh kernels give exactly what the earlier passes gave.

``rtin.active_mesh`` emits a mesh in one walk (vertex numbers in a hash table or the
dense scratch, positions read as each vertex is first met, culling in place), skips
vertices whose δ is below a per-tile floor before reading their sphere, and computes
x, y on affine frames instead of storing them. Each shortcut is checked here against
the plain path it replaces: walk, gather, cull in three passes; the LP test on every
sample; the stored per-tile x, y.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import emit, kernels, leaves, rtin
from geoterrain.lod.pool import tile_pool
from geoterrain.lod.tiles import TileTree, tile_index

_T: dict = {}


def _terrain(tmp_path_factory, holes: bool):
    if holes not in _T:
        z = generate("fbm", 257, seed=5)
        if holes:
            z[40:90, 100:170] = np.nan  # nodata: triangles with an invalid corner are dropped
        d = tmp_path_factory.mktemp("k")
        dem = write_geotiff(d / "d.tif", z)
        _T[holes] = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain",
                                                          tile_size=16))
    return _T[holes]


def _view(t, az: float, el: float, dist: float) -> geoterrain.View:
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    r = float(np.linalg.norm(hi[:2] - lo[:2])) * dist
    eye = c + r * np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
    return geoterrain.View(tuple(eye), tuple(c), size=(320, 180))


def _same(a, b) -> None:
    assert (a.n_points, a.n_cells) == (b.n_points, b.n_cells)
    if a.n_cells == 0:
        return
    np.testing.assert_array_equal(np.asarray(a.points), np.asarray(b.points))
    np.testing.assert_array_equal(np.asarray(a.regular_faces, np.int64),
                                  np.asarray(b.regular_faces, np.int64))
    np.testing.assert_array_equal(np.asarray(a.point_data["grid_ij"]),
                                  np.asarray(b.point_data["grid_ij"]))
    np.testing.assert_array_equal(np.asarray(a.cell_data["level"]),
                                  np.asarray(b.cell_data["level"]))


@pytest.mark.fast
@settings(max_examples=12, deadline=None)
@given(az=st.floats(0, 6.28), el=st.floats(0.1, 1.4), dist=st.floats(0.05, 1.5),
       holes=st.booleans(), hashed=st.booleans())
def test_one_pass_mesh_equals_three_passes(tmp_path_factory, az, el, dist, holes, hashed):
    t = _terrain(tmp_path_factory, holes)
    v = _view(t, az, el, dist)
    act = rtin.view_active(t, tile_index(t), v, 1.0)
    keep = rtin._HASHED_UP_TO
    rtin._HASHED_UP_TO = keep if hashed else 0
    try:
        one = rtin.active_mesh(t, act, v)
    finally:
        rtin._HASHED_UP_TO = keep
    three = rtin._mesh_in_passes(t, act, v.planes, np.asarray(v.eye, float), 0.0)
    _same(one, three)


@pytest.mark.fast
@settings(max_examples=12, deadline=None)
@given(az=st.floats(0, 6.28), el=st.floats(0.05, 1.4), dist=st.floats(0.02, 1.5),
       tau=st.sampled_from([0.5, 1.0, 4.0]), depth=st.booleans())
def test_the_lp_floor_changes_no_flag(tmp_path_factory, az, el, dist, tau, depth):
    """Skipping λδ ≤ τ(D_box − r_max) gives the same active set as testing every vertex,
    with the distance (LP) or the depth (the picture's bound, rtin.DEPTH) for D."""
    t = _terrain(tmp_path_factory, True)
    v = _view(t, az, el, dist)
    index = tile_index(t)
    real, keep = kernels.lp_tiles_walk, rtin.DEPTH
    rtin.DEPTH = depth
    try:
        with_floor = rtin.view_active(t, index, v, tau)
        a = with_floor.active == with_floor.gen
        m = with_floor.mixed == with_floor.gen

        def no_floor(*args):
            out = real(*args)
            args[-2][:] = -1.0  # floor −1: every vertex takes the full LP test
            return out

        rtin.lp_tiles_walk = no_floor
        plain = rtin.view_active(t, index, v, tau)
    finally:
        rtin.lp_tiles_walk, rtin.DEPTH = real, keep
    np.testing.assert_array_equal(a, plain.active == plain.gen)
    np.testing.assert_array_equal(m, plain.mixed == plain.gen)


@pytest.mark.fast
def test_affine_xy_equals_the_stored_tile_xy(tmp_path_factory):
    t = _terrain(tmp_path_factory, False)
    pool = tile_pool(t)
    assert pool.affine and len(pool.aff) == 10  # a projected frame: x, y are not pooled
    g = t.grid
    for L, x, y in [(0, 0, 0), (0, 15, 15), (1, 3, 5), (g.top_level, 0, 0)]:
        X, Y = t.tile_xy(L, x, y)
        rows, cols = g.tile_rows(L, y), g.tile_cols(L, x)
        for a in (0, 3, len(rows) - 1):
            for b in (0, 7, len(cols) - 1):
                got = kernels.sample_xy(pool.X, pool.Y, pool.aff, 0, a, b, int(rows[a]),
                                        int(cols[b]))
                assert got == (X[a, b], Y[a, b])  # bit for bit


@pytest.mark.fast
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), nplanes=st.integers(0, 4))
def test_cull_in_place_equals_cull_compact(seed, nplanes):
    rng = np.random.default_rng(seed)
    V, F = 60, 90
    xyz = rng.normal(size=(V, 3))
    xyz[rng.random(V) < 0.1, 2] = np.nan
    faces = rng.integers(0, V, (F, 3)).astype(np.int32)
    lvl = rng.integers(0, 5, V)
    planes = rng.normal(size=(nplanes, 4))
    eye, slack = rng.normal(size=3), float(rng.choice([0.0, 0.05]))
    ref_f, keep, ref_l = emit.cull_compact(faces.copy(), xyz.copy(), planes, lvl, eye,
                                           slack)
    ij = rng.random((V, 2))
    f2, x2, ij2 = faces.copy(), xyz.copy(), ij.copy()
    nf, nv, lev = emit.cull_in_place(f2, x2, ij2, planes, lvl, eye, slack)
    keep = np.arange(V) if keep is None else keep
    np.testing.assert_array_equal(f2[:nf], ref_f)
    np.testing.assert_array_equal(lev, ref_l)
    np.testing.assert_array_equal(x2[:nv], xyz[keep])
    np.testing.assert_array_equal(ij2[:nv], ij[keep])


@pytest.mark.fast
@settings(max_examples=15, deadline=None)
@given(az=st.floats(0, 6.28), el=st.floats(0.02, 1.5), dist=st.floats(0.01, 2.0),
       tau=st.sampled_from([0.5, 1.0, 4.0]), holes=st.booleans(), depth=st.booleans())
def test_the_tile_walk_equals_testing_every_tile(tmp_path_factory, az, el, dist, tau, holes,
                                                 depth):
    """Entering only subtrees whose box (grown by their largest radius) meets the frustum
    gives the status and floor lp_tiles gives every tile (either metric)."""
    t = _terrain(tmp_path_factory, holes)
    v = _view(t, az, el, dist)
    index = tile_index(t)
    n = len(index.keys)
    f1, f2 = np.empty(n), np.empty(n)
    table, base, rsub, grow, gsub = rtin._tile_tree(t, index)
    ref = kernels.lp_tiles(index.lo, index.hi, index.delta_max, index.radius_max, grow,
                           v.terms(tau, depth), f1)
    got = np.zeros(n, np.uint8)
    tree = TileTree(table, base, t.grid.top_level, index.lo, index.hi)
    visited = kernels.lp_tiles_walk(tree, index.delta_max, index.radius_max, rsub, grow,
                                    gsub, v.terms(tau, depth), f2, got)
    np.testing.assert_array_equal(got, ref)
    on = ref > 0
    np.testing.assert_array_equal(f2[on], f1[on])
    assert visited <= n


@pytest.mark.fast
@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), t=st.floats(1e-4, 0.05), u=st.floats(0.05, 0.99))
def test_culling_keeps_every_triangle_over_a_sample_in_the_frustum(seed, t, u):
    """A triangle outside a plane is dropped only if no sample within (τ/λ)·d of its
    surface, vertically (ρ ≤ τ), can be inside (`_corner_bits`, slack 2τ/λ); and one
    outside by more than that margin is dropped."""
    rng = np.random.default_rng(seed)
    eye = rng.normal(size=3) * 10
    tri = eye + rng.normal(size=(3, 3)) * 30
    n = rng.normal(size=3)
    d = np.linalg.norm(tri - eye, axis=1)
    faces = np.array([[0, 1, 2]], np.int32)
    lvl = np.zeros(3, np.int64)
    for margin, drawn in ((u, True), (2.5, False)):
        # the plane's offset puts the corners outside by at least margin·|c|·(τ/λ)·d, one
        # of them by exactly that: lifted or lowered by (τ/λ)·d it is inside when margin < 1
        w = -np.max(tri @ n + margin * abs(n[2]) * t * d)
        plane = np.append(n, w)[None]
        kept, _, _ = emit.cull_compact(faces, tri, plane, lvl, eye, 2 * t)
        assert len(kept) == (1 if drawn else 0)


def _oriented(mesh) -> dict:
    """Each triangle as its three grid samples, rotated to start at the smallest (the
    winding kept), mapped to its level."""
    if mesh.n_cells == 0:
        return {}
    ij = np.asarray(mesh.point_data["grid_ij"]).astype(np.int64)
    k = (ij[:, 0] << 32) + ij[:, 1]
    f = k[np.asarray(mesh.regular_faces, np.int64)]
    r = np.argmin(f, 1)
    f = np.stack([f[np.arange(len(f)), (r + q) % 3] for q in range(3)], 1)
    lvl = np.asarray(mesh.cell_data["level"]).tolist()
    return dict(zip(map(tuple, f.tolist()), lvl, strict=True))


def _uneven(tmp_path_factory):
    if "uneven" not in _T:  # 200 × 300 in a 513² grid: padding along two edges
        z = generate("fbm", 300, seed=9)[:200]
        z[120:150, 30:60] = np.nan
        d = tmp_path_factory.mktemp("u")
        dem = write_geotiff(d / "d.tif", z)
        _T["uneven"] = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain",
                                                             tile_size=32))
    return _T["uneven"]


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
@settings(max_examples=25, deadline=None)
@given(e=st.one_of(st.just(0.0), st.floats(0.0, 60.0), st.just(1e12)),
       which=st.sampled_from(["plain", "holes", "uneven"]), counted=st.booleans())
def test_static_leaves_equal_the_walk(tmp_path_factory, e, which, counted):
    """The static mesh made from its active vertices alone (``leaves.static_leaves``)
    has exactly the walk's triangles: the same samples, winding, levels and positions;
    whether the leaves are emitted with room to spare and gathered, or counted first
    (``counted``: what a mesh too large for the kept scratch does)."""
    t = _uneven(tmp_path_factory) if which == "uneven" else _terrain(tmp_path_factory,
                                                                     which == "holes")
    walk = rtin.active_mesh(t, rtin.static_active(t, tile_index(t), e))
    flat = _nodata_rule_leaves(t, e, counted)
    assert flat.n_cells == walk.n_cells and flat.n_points == walk.n_points
    assert _oriented(flat) == _oriented(walk)
    by_sample = [np.asarray(m.points)[np.lexsort(np.asarray(m.point_data["grid_ij"]).T[::-1])]
                 for m in (walk, flat)]  # each sample at one position
    np.testing.assert_array_equal(*by_sample)


def _nodata_rule_leaves(t, e: float, counted: bool):
    """The static mesh through the leaves with the walk's nodata padding (test_edgepad.py:
    the other), emitted with room to spare or (``counted``) counted first, as a mesh too
    large for the kept scratch is."""
    keep = leaves.KEEP_BYTES
    leaves.KEEP_BYTES = 0 if counted else keep
    rtin.EDGE_PADDING = False
    try:
        return geoterrain.lod.static(t, e).mesh
    finally:
        leaves.KEEP_BYTES = keep
        rtin.EDGE_PADDING = True


def _roots(tmp_path_factory, rows: int, cols: int, ts: int, voids: bool = True):
    key = ("roots", rows, cols, ts, voids)
    if key not in _T:  # a root grid with voids, one touching the data's last column
        z = generate("fbm", 129, seed=rows + cols)[:rows, :cols].copy()
        if voids:
            z[rows // 3:rows // 3 + 5, cols - 6:] = np.nan
            z[5:9, 10:14] = np.nan
        d = tmp_path_factory.mktemp("r")
        dem = write_geotiff(d / "d.tif", z)
        _T[key] = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain",
                                                        tile_size=ts))
    return _T[key]


@pytest.mark.fast
@pytest.mark.parametrize(("shape", "roots"), [
    ((50, 121, 8), (2, 1)), ((121, 50, 8), (1, 2)), ((49, 129, 16), (2, 1)),
    ((50, 60, 8), (1, 1)), ((65, 129, 16, False), (2, 1)), ((129, 65, 16, False), (1, 2))])
def test_static_leaves_equal_the_walk_on_root_grids(tmp_path_factory, shape, roots):
    """On 2 × 1, 1 × 2 and 1 × 1 roots (and a DEM ending on a tile border, whose vertices
    just past it lie in no tile: the active set misses those parents) the leaves are the
    walk's triangles, with the nodata rule (the walk's padding), emitted with room to
    spare or counted first; without padding or voids, at e = 10¹² every root is its two
    base triangles, each along the walk's diagonal for that root."""
    t = _roots(tmp_path_factory, *shape)
    assert not t.grid.square and t.grid.roots == roots
    for e in (0.0, 3.0, 1e12):
        walk = rtin.active_mesh(t, rtin.static_active(t, tile_index(t), e))
        for counted in (False, True):
            flat = _nodata_rule_leaves(t, e, counted)
            assert flat.n_cells == walk.n_cells and flat.n_points == walk.n_points
            assert _oriented(flat) == _oriented(walk)


@pytest.mark.fast
@settings(max_examples=15, deadline=None)
@given(az=st.floats(0, 6.28), el=st.floats(0.02, 1.4), dist=st.floats(0.02, 1.5),
       tau=st.sampled_from([0.5, 1.0, 4.0]), holes=st.booleans())
def test_skipping_blocks_by_their_bounds_changes_no_flag(tmp_path_factory, az, el, dist, tau,
                                                          holes):
    """Testing each block's bounds before its samples (``rtin.BLOCKS``) gives the same
    active and mixed flags as testing every sample of every candidate tile."""
    t = _terrain(tmp_path_factory, holes)
    v = _view(t, az, el, dist)
    index = tile_index(t)
    out = {}
    for blocks in (True, False):
        rtin.BLOCKS = blocks
        try:
            act = rtin.view_active(t, index, v, tau)
        finally:
            rtin.BLOCKS = True
        out[blocks] = (act.active == act.gen, act.mixed == act.gen)
    np.testing.assert_array_equal(out[True][0], out[False][0])
    np.testing.assert_array_equal(out[True][1], out[False][1])


@pytest.mark.fast
def test_the_static_elevation_is_the_seams_formula(tmp_path_factory):
    """The static mesh computes ``elevation`` with its positions; it equals what
    ``mesh.add_elevation`` computes from Z, bit for bit, with and without culled
    vertices (nodata) and with an exaggeration."""
    from geoterrain.exaggerate import exaggerated
    from geoterrain.lod.mesh import add_elevation

    for t in (_terrain(tmp_path_factory, False), _uneven(tmp_path_factory),
              exaggerated(_terrain(tmp_path_factory, True), 3.0)):
        for e in (0.0, 2.0, 30.0):
            m = geoterrain.lod.static(t, e).mesh
            got = np.asarray(m.point_data["elevation"]).copy()
            add_elevation(m, t.frame.z_scale)
            assert got.dtype == np.float32
            np.testing.assert_array_equal(got, np.asarray(m.point_data["elevation"]))


def test_a_forked_child_extracts_the_same_static_mesh(tmp_path_factory, parallel_always):
    """After the parent has run the parallel kernels, a child made by fork() (GNU
    OpenMP aborts such a child at its first parallel launch) extracts the same static
    mesh, with the serial twins."""
    from geoterrain.core.threads import forked
    from tests.conftest import in_fork

    t = _terrain(tmp_path_factory, True)
    want = _oriented(geoterrain.lod.static(t, 3.0).mesh)  # the parent uses the threads
    got, status = in_fork(lambda: _oriented(geoterrain.lod.static(t, 3.0).mesh) == want
                          and forked())
    assert got == b"same", (got, status)

"""Padding by edge replication for the static mesh (geoterrain/bounds/edgepad.py, lod/clip.py).

Every check measures the mesh with code that does not select it: the barycentric
rasteriser of geoterrain.testing.measure, edge counting, and areas.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import StoreCorruptError
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import rtin
from geoterrain.lod.clip import clip_in_place
from geoterrain.testing.measure import vertical_error
from geoterrain.testing.reference import static_mesh

_T: dict = {}


def _store(tmp_path_factory, rows: int, cols: int, holes: bool):
    key = (rows, cols, holes)
    if key not in _T:
        z = generate("fbm", 129, seed=rows * 131 + cols)[:rows, :cols].copy()
        if holes:
            z[rows // 3:rows // 3 + 6, cols - 5:] = np.nan  # nodata touching the edge
        d = tmp_path_factory.mktemp("e")
        dem = write_geotiff(d / "d.tif", z)
        _T[key] = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain",
                                                        tile_size=8))
    return _T[key]


def _truth(t):
    _, _, Z = t.scene_xyz()
    return Z, np.isfinite(Z)


def _area(ij: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (ij[faces[:, k]] for k in range(3))
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                  - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


@settings(max_examples=30, deadline=None)
@given(rows=st.sampled_from([40, 65, 97, 100, 128]), cols=st.sampled_from([33, 64, 90, 129]),
       holes=st.booleans(), e=st.one_of(st.just(0.0), st.floats(0.0, 400.0), st.just(1e9)))
# found by this test: a padding vertex whose tile holds no data, needed at (2, 64); and
# one lifted by saturation below a DEM ending on a tile boundary (row 40), with nodata
@example(rows=97, cols=64, holes=False, e=0.0)
@example(rows=40, cols=90, holes=True, e=0.0)
def test_the_clipped_mesh_keeps_the_bound_and_covers_every_sample(tmp_path_factory, rows,
                                                                    cols, holes, e):
    """On DEMs that leave padding, the static mesh (replicated padding, clipped) has
    measured vertical error ≤ e at every valid sample, leaves none uncovered, stays in
    the data's rectangle, and is a conforming surface: every edge inside it is shared
    by two faces of opposite winding, and the edges on its rim lie on the rectangle's
    sides (or next to nodata)."""
    _check_clipped(_store(tmp_path_factory, rows, cols, holes), rows, cols, holes, e)


def _check_clipped(t, rows: int, cols: int, holes: bool, e: float) -> None:
    """The clipped static mesh of bound ``e`` on ``t`` (a rows × cols DEM): measured error
    ≤ e at every valid sample, none uncovered, inside the data's rectangle, one
    winding, every inner edge shared by two faces of opposite winding (no crack, across
    a root grid's shared edges too), the rim on the rectangle's sides (or next to
    nodata), and without holes the rectangle's whole area."""
    Z, valid = _truth(t)
    sel = t.static_selection(e)
    ij = np.asarray(sel.ij, float)
    faces = sel.surface_faces().astype(np.int64)
    z = np.asarray(sel.mesh.points)[:, 2]
    err = vertical_error(ij, faces, z, Z, valid)
    assert err.n_uncovered_valid == 0
    assert err.max <= e * (1 + 1e-9) + 1e-9
    assert ij[:, 0].min() >= 0 and ij[:, 0].max() <= rows - 1
    assert ij[:, 1].min() >= 0 and ij[:, 1].max() <= cols - 1
    assert (_area(ij, faces) > 0).all() or (_area(ij, faces) < 0).all()  # one winding
    edges = Counter()
    for a, b in np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]):
        edges[(int(a), int(b))] += 1
    for (a, b), n in edges.items():
        assert n == 1, "an edge used twice in one direction"
        if (b, a) in edges:
            continue
        pa, pb = ij[a], ij[b]  # a rim edge: on a side of the rectangle
        on_side = any((pa[k] == v and pb[k] == v) for k, v in
                      ((0, 0), (0, rows - 1), (1, 0), (1, cols - 1)))
        assert on_side or holes, f"a crack at {pa}–{pb}"
    if not holes:  # the rim encloses the whole rectangle
        assert np.isclose(abs(_area(ij, faces).sum()), (rows - 1) * (cols - 1))


@settings(max_examples=15, deadline=None)
@given(rows=st.sampled_from([40, 97, 100]), cols=st.sampled_from([33, 90, 129]),
       e=st.floats(2.0, 400.0))
def test_replicated_padding_needs_fewer_triangles_than_nodata(tmp_path_factory, rows, cols,
                                                              e):
    """The nodata rule refines the DEM's edge to full resolution; replicated padding
    does not, so it never needs more triangles on a DEM without holes."""
    t = _store(tmp_path_factory, rows, cols, False)
    edge = t.static_selection(e).stats["triangles"]
    rtin.EDGE_PADDING = False
    try:
        nodata = t.static_selection(e).stats["triangles"]
    finally:
        rtin.EDGE_PADDING = True
    assert edge <= nodata


@pytest.mark.fast
def test_a_store_without_padding_is_unchanged(tmp_path):
    """A (2^n+1)² DEM has no padding: no second δ is stored, and the static mesh is the
    nodata rule's, triangle for triangle."""
    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 65, seed=2))
    t = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=16))
    assert t.edge_max is None
    a = t.static_selection(3.0).mesh
    rtin.EDGE_PADDING = False
    try:
        b = t.static_selection(3.0).mesh
    finally:
        rtin.EDGE_PADDING = True
    np.testing.assert_array_equal(np.asarray(a.faces), np.asarray(b.faces))


def _clip(f, ij, xyz, rows, cols, n):
    """clip_in_place on copies with the room the static mesh gives it; the face data it
    carries (``level`` there) is each face's source face here."""
    F, V = len(f), len(ij)
    rv, rf = rows + cols + 1, 2 * (rows + cols + 4)
    fb = np.zeros((F + rf, 3), np.int32)
    fb[:F] = f
    src = np.zeros(F + rf, np.int64)
    src[:F] = np.arange(F)
    ib, xb = np.zeros((V + rv, 2)), np.zeros((V + rv, 3))
    ib[:V], xb[:V] = ij, xyz
    nf, nv = clip_in_place(fb, src, F, ib, xb, V, float(rows - 1), float(cols - 1),
                           np.int64(n))
    return fb[:nf], src[:nf], ib[:nv], xb[:nv]


@settings(max_examples=120, deadline=None)
@given(n=st.sampled_from([5, 9, 17, 33]), e=st.floats(0.0, 3.0), seed=st.integers(0, 99),
       fr=st.floats(0.05, 1.0), fc=st.floats(0.05, 1.0))
@example(n=5, e=1.0, seed=1, fr=0.625, fc=0.5)  # a corner on the first cut line
def test_clipping_keeps_exactly_the_rectangle(n, e, seed, fr, fc):
    """A conforming bintree mesh of the whole grid, clipped to rows × cols: the pieces
    tile the rectangle exactly (their areas sum to it, none is empty), every cut point
    lies on the face it came from (its height is that face's plane there), and a cut
    edge's point is one vertex shared by both faces (no crack)."""
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, n))
    from geoterrain.bounds.delta import vertex_errors

    v, f = static_mesh(vertex_errors(z, np.ones((n, n), bool)), np.ones((n, n), bool), e)
    rows, cols = max(2, round(fr * n)), max(2, round(fc * n))
    ij = v.astype(float)
    xyz = np.c_[ij[:, 1], -ij[:, 0], z[v[:, 0], v[:, 1]]]
    f2, src, ij2, xyz2 = _clip(f, ij, xyz, rows, cols, n)
    area = _area(ij2, f2)
    assert (area > 0).all() == (_area(ij, f) > 0).all() and (np.abs(area) > 1e-12).all()
    assert np.isclose(np.abs(area).sum(), (rows - 1) * (cols - 1))
    # each new point on the plane of its source face
    for k in range(len(f2)):
        a, b, c = ij[f[src[k]]]
        d = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        for p, q in zip(ij2[f2[k]], xyz2[f2[k]], strict=True):
            wb = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / d
            wc = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / d
            want = (1 - wb - wc) * xyz[f[src[k]]][0] + wb * xyz[f[src[k]]][1] \
                + wc * xyz[f[src[k]]][2]
            np.testing.assert_allclose(q, want, atol=1e-9)
    # no two vertices at one place: shared cut points are shared vertices
    assert len(np.unique(np.round(ij2, 9), axis=0)) == len(ij2)


@pytest.mark.fast
def test_a_delta_edge_list_naming_a_missing_tile_is_refused(tmp_path):
    """The tiles with a second δ come from the metadata of a file that may come from a
    stranger: a list naming a tile the store does not hold fails to open, in one line."""
    import sqlite3

    from tests.store.storesql import read_meta, write_meta

    z = generate("fbm", 65, seed=4)[:50, :40]
    dem = write_geotiff(tmp_path / "d.tif", z)
    p = geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=16)
    con = sqlite3.connect(p)
    meta = read_meta(con)
    assert meta["delta_edge"], "a padded store lists its tiles with a second δ"
    meta["delta_edge"].append([0, 99, 99, 1.0])
    write_meta(con, meta)  # a consistent file: only the list is wrong
    con.commit()
    con.close()
    with pytest.raises(StoreCorruptError, match="delta_edge") as ex:
        geoterrain.open(p)
    assert "\n" not in str(ex.value)


#: Root grids (issue 45) by what they are: (rows, cols, tile size) → (across, down) roots.
#: "1x1 short": one root over fewer tiles than its extent (jacksboro's, srtm's case);
#: "2x1 border": the data's last row on a level-0 tile border, so the vertices just
#: below it lie in no tile (their δ_edge is not stored: a parent missing from the set).
_ROOTS = {"2x1": (50, 121, 8, (2, 1)), "1x2": (121, 50, 8, (1, 2)),
          "1x1 short": (50, 60, 8, (1, 1)), "2x1 border": (49, 129, 16, (2, 1))}


def _root_store(tmp_path_factory, layout: str, geographic: bool, holes: bool):
    """A root-grid store of an fBm named by ``layout`` (:data:`_ROOTS`), projected (UTM,
    10 m) or geographic (EPSG:4326, 3″ at 61° N), with a void touching the data's last
    column (``holes``)."""
    key = ("roots", layout, geographic, holes)
    if key not in _T:
        rows, cols, ts, roots = _ROOTS[layout]
        z = generate("fbm", 129, seed=rows * 7 + cols)[:rows, :cols].copy()
        if holes:
            z[rows // 3:rows // 3 + 6, cols - 5:] = np.nan
            z[rows - 4:, cols // 2:cols // 2 + 3] = np.nan  # and the last row
        geo = dict(crs="EPSG:4326", origin=(24.0, 61.0), spacing=1 / 1200) if geographic \
            else {}
        d = tmp_path_factory.mktemp("r")
        dem = write_geotiff(d / "d.tif", z, **geo)
        t = geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain", tile_size=ts))
        assert not t.grid.square and t.grid.roots == roots, (layout, t.grid)
        _T[key] = t
    return _T[key]


@pytest.mark.slow  # 12 stores of about 1 s each, then 1-2 s an example
@settings(max_examples=30, deadline=None)
@given(layout=st.sampled_from(sorted(_ROOTS)), geographic=st.booleans(), holes=st.booleans(),
       e=st.one_of(st.just(0.0), st.floats(0.0, 400.0), st.just(1e9)))
@example(layout="2x1 border", geographic=False, holes=False, e=0.5)
@example(layout="1x2", geographic=True, holes=True, e=3.0)
def test_a_root_grid_s_clipped_mesh_keeps_the_bound_and_covers_every_sample(
        tmp_path_factory, layout, geographic, holes, e):
    """The edge-padded static mesh on 2 × 1, 1 × 2 and 1 × 1 roots (a lattice short of
    the extent, a DEM ending on a tile border), geographic or projected, with voids:
    every property of the square's (:func:`_check_clipped`)."""
    t = _root_store(tmp_path_factory, layout, geographic, holes)
    assert rtin.edge_padding(t)
    _check_clipped(t, t.grid.rows, t.grid.cols, holes, e)


@pytest.mark.fast
@pytest.mark.parametrize("layout", sorted(_ROOTS))
def test_a_root_grid_s_static_mesh_is_edge_padded(tmp_path_factory, layout):
    """A root grid's static mesh replicates its padding as the square's does: the bound
    and conformity of :func:`_check_clipped` at a coarse and a fine e, far fewer
    triangles than the nodata rule's at a coarse one (which refines the DEM's last row
    and column to full resolution), never more at any."""
    t = _root_store(tmp_path_factory, layout, layout == "1x2", True)
    assert rtin.edge_padding(t)
    g = t.grid
    # the geographic one pads past its lattice: its padding's positions are proxies
    assert t.frame.lattice == (g.shape if layout == "1x2" else None)
    rows, cols = g.rows, g.cols
    for e in (2.0, 1e9):
        _check_clipped(t, rows, cols, True, e)
    # without voids, at each root centre's own δ_edge that root is its two base
    # triangles, along its diagonal (the bound holds along the one δ_edge measured)
    full = _root_store(tmp_path_factory, layout, layout == "1x2", False)
    c = g.tile_samples // 2
    for x in range(g.roots[0]):
        for y in range(g.roots[1]):
            _check_clipped(full, rows, cols, False,
                           float(full.tile_delta_edge(g.top_level, x, y)[c, c]))
    counts = {}
    for edge in (True, False):
        rtin.EDGE_PADDING = edge
        try:
            counts[edge] = [t.static_selection(e).stats["triangles"] for e in (2.0, 1e9)]
        finally:
            rtin.EDGE_PADDING = True
    assert counts[True][0] <= counts[False][0]
    assert counts[True][1] < 0.75 * counts[False][1], counts  # the edge not refined
    # streamed (the walk, clipped chunk by chunk) as in memory (the leaves, clipped)
    from geoterrain.lod.stream import static_chunks

    chunks = list(static_chunks(t, 2.0, chunk=997))
    ij = np.concatenate([c.ij for c in chunks])
    faces = np.concatenate([c.faces for c in chunks])
    np.testing.assert_array_equal(_triangles_of(ij, faces),
                                  _sorted_triangles(t.static_selection(2.0).mesh))


def _sorted_triangles(mesh) -> np.ndarray:
    """Each triangle as its corners' grid indices, rotated to start at the smallest (the
    winding kept), sorted: comparable across vertex numberings."""
    return _triangles_of(mesh.point_data["grid_ij"], mesh.regular_faces)


def _triangles_of(ij, faces) -> np.ndarray:
    """:func:`_sorted_triangles` of grid indices ``ij`` and ``faces``."""
    ij = np.round(np.asarray(ij, np.float64) * 4).astype(np.int64)
    k = (ij[:, 0] << 32) + ij[:, 1]
    f = k[np.asarray(faces, np.int64)]
    r = np.argmin(f, 1)
    f = np.stack([f[np.arange(len(f)), (r + q) % 3] for q in range(3)], 1)
    return f[np.lexsort(f.T[::-1])]


@pytest.mark.fast
@pytest.mark.parametrize("holes", [False, True])
def test_one_root_is_the_square_triangle_for_triangle(tmp_path, holes):
    """A 1 × 1 root grid over fewer tiles than its extent, which is the square's (50 × 60
    with 8-sample tiles: both span 65²), replicates the same padding: its edge-padded
    static mesh has the square store's triangles, at every bound tried."""
    z = generate("fbm", 65, seed=5)[:50, :60].copy()
    if holes:
        z[20:26, 55:] = np.nan
    dem = write_geotiff(tmp_path / "d.tif", z)
    t = {rg: geoterrain.open(geoterrain.preprocess(dem, tmp_path / f"{rg}.geoterrain",
                                                   tile_size=8, root_grid=rg))
         for rg in (True, False)}
    assert not t[True].grid.square and t[True].grid.extent == (65, 65) and t[False].grid.square
    for e in (0.0, 0.5, 3.0, 40.0, 1e9):
        a, b = (_sorted_triangles(t[rg].static_selection(e).mesh) for rg in (True, False))
        np.testing.assert_array_equal(a, b)

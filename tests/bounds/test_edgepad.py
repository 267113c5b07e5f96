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
    t = _store(tmp_path_factory, rows, cols, holes)
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

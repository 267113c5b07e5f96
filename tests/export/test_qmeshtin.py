"""TIN tiles (export/qmeshtin.py): neighbours keep the same edge points, each tile is
within its thresholds on the lattice, and the 1-D edge simplification keeps what it must.

Errors are measured by geoterrain.testing.measure (barycentric, over the valid samples),
which never imports the mesher; the decoded tile sets are checked in test_qmesh.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from geoterrain.export.qmeshtin import MIN_THRESHOLD, edge_keep, tin_tile
from geoterrain.ingest.synth import generate
from geoterrain.testing.measure import vertical_error

pytestmark = pytest.mark.fast


SIDES = {"north": (0, 0), "south": (0, -1), "west": (1, 0), "east": (1, -1)}


def _on(ij: np.ndarray, M: int, side: str) -> np.ndarray:
    """Which of the points ``ij`` lie on ``side``; their positions along it."""
    axis, at = SIDES[side]
    return ij[:, axis] == at % M


def _segments(ij: np.ndarray, faces: np.ndarray, M: int, side: str) -> set:
    """The (from, to) positions along ``side`` of the triangle edges lying on it."""
    axis, _ = SIDES[side]
    on = _on(ij, M, side)
    out = set()
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            if on[a] and on[b]:
                p, q = sorted((int(ij[a, 1 - axis]), int(ij[b, 1 - axis])))
                out.add((p, q))
    return out


def _voids(shape, seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    valid = np.ones(shape, bool)
    for _ in range(n):  # rectangles of nodata, some across the shared edge
        i, j = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        valid[i:i + rng.integers(1, 6), j:j + rng.integers(1, 6)] = False
    return valid


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(M=st.sampled_from([3, 5, 9, 17, 33]), seed=st.integers(0, 10_000),
       relief=st.sampled_from([0.0, 3.0, 100.0]),
       tau=st.sampled_from([0.0, 0.5, 4.0, 1e6]), thr_a=st.sampled_from([0.0, 0.3, 2.0, 30.0]),
       thr_b=st.sampled_from([0.0, 1.0, 8.0]), holes=st.integers(0, 4),
       north_south=st.booleans())
def test_neighbours_keep_the_same_edge_points_and_the_bound(M, seed, relief, tau, thr_a, thr_b,
                                                            holes, north_south):
    """Two tiles sharing an edge, built with different interior thresholds. Each tile's
    border points are exactly what its edges' own simplification keeps (so the two
    sides cut the shared edge at the same points: no T-junction); without nodata both
    sides draw the same edge points, and with nodata every edge segment is drawn
    between consecutive kept points, the same on both sides where both draw it. Each
    tile is within max(its threshold, the edge's) at every valid lattice sample it
    covers (0 uncovered without nodata)."""
    z = generate("fbm", (M, 2 * M - 1), seed=seed, relief=relief).astype(np.float64)
    valid = _voids(z.shape, seed, holes)
    if north_south:  # the shared edge is a row: tile a above (its south), b below (north)
        z, valid = z.T.copy(), valid.T.copy()
        tiles = ((np.s_[:M, :], "south", thr_a), (np.s_[M - 1:, :], "north", thr_b))
    else:  # a column: tile a west of it (its east edge), b east (its west edge)
        tiles = ((np.s_[:, :M], "east", thr_a), (np.s_[:, M - 1:], "west", thr_b))
    drawn, kept = [], []
    for sl, side, thr in tiles:
        h, v = z[sl].copy(), valid[sl].copy()
        h[~v] = np.nan
        if v.sum() < 3:
            return
        ij, faces = tin_tile(h, v, thr, tau)
        for s in SIDES:  # the whole triangulation's border points: the kept ones exactly
            axis, at = SIDES[s]
            line = np.take(h, at, axis=axis), np.take(v, at, axis=axis)
            keep = np.flatnonzero(edge_keep(line[0], line[1], float(tau)))
            assert np.array_equal(np.sort(ij[_on(ij, M, s), 1 - axis]), keep), s
            if s == side:
                kept.append(keep)
        segs = _segments(ij, faces, M, side)
        k = list(kept[-1])
        assert all(k.index(q) == k.index(p) + 1 for p, q in segs)  # consecutive kept points
        drawn.append(segs)
        if len(faces):
            err = vertical_error(ij, faces, h[ij[:, 0], ij[:, 1]], np.nan_to_num(h), v)
            assert err.max <= max(thr, tau, MIN_THRESHOLD) + 1e-6 * max(1.0, relief)
            if v.all():
                assert err.n_uncovered_valid == 0
    assert np.array_equal(kept[0], kept[1])
    if valid.all():
        assert drawn[0] == drawn[1] and drawn[0]


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 60), seed=st.integers(0, 10_000), tau=st.sampled_from([0.0, 1.0, 9.0]),
       holes=st.integers(0, 3))
def test_edge_simplification_is_within_tau_and_keeps_void_borders(n, seed, tau, holes):
    rng = np.random.default_rng(seed)
    h = np.cumsum(rng.normal(0, 3, n))
    valid = np.ones(n, bool)
    for _ in range(holes):
        i = rng.integers(0, n)
        valid[i:i + rng.integers(1, 4)] = False
    keep = edge_keep(h, valid, tau)
    assert keep[0] and keep[-1]
    change = np.flatnonzero(valid[1:] != valid[:-1])
    assert keep[change].all() and keep[change + 1].all()  # both sides of a void's border
    k = np.flatnonzero(keep)
    for a, b in zip(k[:-1], k[1:], strict=True):
        if valid[a] and valid[b] and b > a + 1:
            assert valid[a:b + 1].all()
            line = h[a] + (h[b] - h[a]) * (np.arange(a, b + 1) - a) / (b - a)
            assert np.abs(line - h[a:b + 1]).max() <= tau + 1e-9
    assert np.array_equal(keep, edge_keep(h.copy(), valid.copy(), tau))  # deterministic


def test_a_plane_needs_its_corners_alone():
    M = 17
    z = np.add.outer(np.arange(M) * 2.0, np.arange(M) * 0.5)
    ij, faces = tin_tile(z, np.ones_like(z, bool), 0.0, 0.0)
    assert len(faces) == 2
    assert sorted(map(tuple, ij.tolist())) == [(0, 0), (0, M - 1), (M - 1, 0), (M - 1, M - 1)]


@pytest.mark.slow
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(h=st.integers(24, 64), w=st.integers(24, 64), seed=st.integers(0, 10_000),
       relief=st.sampled_from([0.02, 0.2, 1.0]), holes=st.integers(0, 3),
       dx=st.floats(-0.02, 0.02), dy=st.floats(-0.02, 0.02),
       mesher=st.sampled_from(["tin", "rtin"]))
# the DEM's west edge on a tile boundary: a flat tile beside the first data tile (found by a
# longer run), for both meshers
@example(h=24, w=24, seed=0, relief=0.02, holes=0, dx=-0.001953125, dy=0.0, mesher="tin")
@example(h=24, w=24, seed=1, relief=0.02, holes=0, dx=-0.001953125, dy=0.0, mesher="tin")
@example(h=24, w=24, seed=0, relief=0.02, holes=0, dx=-0.001953125, dy=0.0, mesher="rtin")
# rtin next to nodata: a valid edge sample drawn on one side only, unlisted on the other
@example(h=24, w=30, seed=1024, relief=0.02, holes=2, dx=0.0, dy=0.0078125, mesher="rtin")
@example(h=24, w=24, seed=0, relief=0.02, holes=1, dx=0.0, dy=0.015625, mesher="rtin")
def test_decoded_neighbours_list_the_same_edge_vertices(tmp_path_factory, h, w, seed, relief,
                                                        holes, dx, dy, mesher):
    """End to end on small synthetic DEMs across tile corners (levels 9–11), decoded by
    quantized-mesh-tile: neighbouring tiles (TIN or rtin) list the same edge vertices, at
    the same heights, and each tile is within its declared error at the DEM samples it
    covers."""
    import json

    import matplotlib.tri as mtri
    import quantized_mesh_tile as qmt
    import rasterio

    import geoterrain
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.qmeshformat import tile_rect
    from tests.conftest import write_tif

    d = tmp_path_factory.mktemp("qtin")
    z = (generate("fbm", (h, w), seed=seed) * relief).astype(np.float32)
    z[~_voids(z.shape, seed, holes)] = -9999
    dem = write_tif(d / "d.tif", z, crs="EPSG:4326", origin=(138.515625 + dx, 35.5078125 + dy),
                    spacing=1 / 1200, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, d / "d.geoterrain", tile_size=32)) as t:
        write_tileset(t, d / "t", min_zoom=9, mesher=mesher)
    declared = json.loads((d / "t" / "geoterrain.json").read_text())["declared_error"]
    with rasterio.open(dem) as src:
        dh = src.read(1, masked=True)
        rows, cols = np.mgrid[0:dh.shape[0], 0:dh.shape[1]]
        slon, slat = (np.asarray(a) for a in rasterio.transform.xy(src.transform, rows.ravel(),
                                                                       cols.ravel()))
    dz = dh.filled(np.nan).ravel()
    tiles = {}
    for p in (d / "t").glob("*/*/*.terrain"):
        key = int(p.parent.parent.name), int(p.parent.name), int(p.stem)
        tt = qmt.TerrainTile(**dict(zip(("west", "south", "east", "north"), tile_rect(*key),
                                        strict=True)))
        tt.fromFile(str(p), hasLighting=True, hasWatermask=True, gzipped=True)
        tiles[key] = tt
        v = np.array(tt.getVerticesCoordinates(), np.float64)
        ws, ss, es, ns = tile_rect(*key)
        inside = (slon >= ws) & (slon <= es) & (slat >= ss) & (slat <= ns) & np.isfinite(dz)
        if inside.any() and len(tt.indices):
            tri = mtri.Triangulation(v[:, 0], v[:, 1], np.array(tt.indices).reshape(-1, 3))
            surf = np.ma.filled(mtri.LinearTriInterpolator(tri, v[:, 2])(slon[inside],
                                                                         slat[inside]), np.nan)
            diff = np.abs(surf - dz[inside])
            assert np.nanmax(diff, initial=0) <= declared["/".join(map(str, key))] + 1e-3
    for (zz, x, y), t in tiles.items():
        for (ox, oy), mine, theirs in (((1, 0), "eastI", "westI"), ((0, 1), "northI", "southI")):
            o = tiles.get((zz, x + ox, y + oy))
            if o is None:
                continue
            a = np.array(t.getVerticesCoordinates(), np.float64)[getattr(t, mine)]
            b = np.array(o.getVerticesCoordinates(), np.float64)[getattr(o, theirs)]
            a, b = a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]
            assert a.shape == b.shape, (zz, x, y, ox)
            assert np.array_equal(a[:, 2], b[:, 2])
            assert np.allclose(a[:, :2], b[:, :2], rtol=0, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(M=st.sampled_from([3, 5, 9, 17, 33]), seed=st.integers(0, 2**31),
       relief=st.sampled_from([0.0, 0.05, 3.0]),
       thr=st.sampled_from([MIN_THRESHOLD, 0.3, 50.0]))
def test_what_the_server_lists_tin_tiles_by(M, seed, relief, thr):
    """The server (export/qmeshtiles.py) lists a TIN tile whose lattice is all valid
    without building it: such a TIN covers the whole tile with triangles. A lattice with a
    void it builds: beside a cell of four valid samples the TIN may still keep no
    triangle (a ring of valid samples round a void, flat: each corner cell split along the
    diagonal through the void), where the lattice's own triangulation keeps one."""
    from geoterrain.export.qmesh import lattice_has_triangle

    rng = np.random.default_rng(seed)
    h = rng.normal(size=(M, M)).cumsum(0).cumsum(1) * relief
    valid = np.ones((M, M), bool)
    ij, faces = tin_tile(h, valid, thr, 0.1 * thr)
    a, b = (ij[faces][:, k] - ij[faces][:, 0] for k in (1, 2))
    area = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum() / 2
    assert area == (M - 1) ** 2
    ring = np.ones((5, 5), bool)
    ring[:4, 1:3] = ring[1:3, 3] = False
    assert lattice_has_triangle(ring)
    assert len(tin_tile(np.where(ring, 0.0, np.nan), ring, MIN_THRESHOLD, 1e-4)[1]) == 0

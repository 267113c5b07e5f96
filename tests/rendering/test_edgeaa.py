"""Geometric anti-aliasing (geoterrain.rendering.edgeaa): each pixel a silhouette edge crosses
gets the edge's coverage, measured here by clipping the pixel's square; hidden edges
leave the picture alone; ``auto`` takes MSAA where silhouettes crowd."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from geoterrain.rendering import edgeaa
from geoterrain.rendering.edgeaa import edge_antialias, silhouette_edges, sparse

W = H = 24
EYE = (0.0, 0.0, 10.0)  # above the z = 0 plane the quads lie in


def _quad_through(angle: float, offset: float):
    """A quad covering the picture's side of a line through the centre, its other
    three sides far outside: (points in NDC at z = 0, faces). With the identity
    projection, NDC x, y map to pixels as VTK's viewport does."""
    d = np.array([math.cos(angle), math.sin(angle)])  # along the edge
    n = np.array([-d[1], d[0]])  # towards the face
    p0 = offset * n - 4 * d
    p1 = offset * n + 4 * d
    pts = np.array([[*p0, 0.0], [*p1, 0.0], [*(p1 + 8 * n), 0.0], [*(p0 + 8 * n), 0.0]])
    return pts, np.array([[0, 1, 2], [0, 2, 3]]), n


def _to_pixels(p):
    return (p[..., 0] + 1) * 0.5 * W, (1 - p[..., 1]) * 0.5 * H


def _clipped_area(nx, ny, c, xx, yy):
    """The area of each unit pixel (corner xx, yy) where nx·x + ny·y > c: the pixel's
    square clipped by the half-plane (Sutherland-Hodgman), its area by the shoelace."""
    corners = [(xx, yy), (xx + 1, yy), (xx + 1, yy + 1), (xx, yy + 1)]
    d = [nx * x + ny * y - c for x, y in corners]
    px, py, keep = [], [], []
    for i in range(4):
        (x0, y0), (x1, y1), d0, d1 = corners[i], corners[(i + 1) % 4], d[i], d[(i + 1) % 4]
        px.append(x0), py.append(y0), keep.append(d0 > 0)
        with np.errstate(divide="ignore", invalid="ignore"):  # no crossing: not kept
            t = d0 / (d0 - d1)
            px.append(x0 + t * (x1 - x0)), py.append(y0 + t * (y1 - y0))
        keep.append((d0 > 0) != (d1 > 0))
    px, py, keep = np.array(px), np.array(py), np.array(keep)
    # a dropped vertex repeats the last kept one (cyclically): its edges have no area
    px, py = np.concatenate([px, px]), np.concatenate([py, py])
    keep = np.concatenate([keep, keep])
    for i in range(1, len(px)):
        px[i] = np.where(keep[i], px[i], px[i - 1])
        py[i] = np.where(keep[i], py[i], py[i - 1])
        keep[i] |= keep[i - 1]
    px, py = px[8:], py[8:]
    return 0.5 * np.abs((px * np.roll(py, -1, 0) - np.roll(px, -1, 0) * py).sum(0))


def _drawn(pts, n):
    """The picture a renderer draws without anti-aliasing (the face where a pixel's
    centre lies on its side), its depth, and each pixel's true coverage (the pixel's
    area on the face's side of the edge line, by clipping its square)."""
    ex, ey = _to_pixels(pts[:2])
    nx, ny = n[0], -n[1]  # the face's side, in pixel coordinates (y down)

    def side(x, y):
        return (x - ex[0]) * nx + (y - ey[0]) * ny > 0

    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    face = side(xx, yy)
    cov = _clipped_area(nx, ny, ex[0] * nx + ey[0] * ny, xx - 0.5, yy - 0.5)
    img = np.where(face[..., None], np.uint8(200), np.uint8(40)).astype(np.uint8)
    img = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img
    depth = np.where(face, 0.5, 1.0).astype(np.float32)  # z = 0 is window depth 0.5
    return img, depth, cov


@pytest.mark.fast
def test_the_clipped_area_is_the_supersampled_one():
    """The test's own truth: the clipped squares' areas against 64 × 64 samples."""
    yy, xx = np.mgrid[0:6, 0:6].astype(float)
    s = (np.arange(64) + 0.5) / 64
    for nx, ny, c in ((0.6, 0.8, 2.9), (-1.0, 0.0, -3.3), (0.7071, -0.7071, 0.1)):
        area = _clipped_area(nx, ny, c, xx, yy)
        sx, sy = np.meshgrid(s, s)
        sampled = (nx * (xx[..., None, None] + sx) + ny * (yy[..., None, None] + sy)
                   > c).mean((2, 3))
        assert np.abs(area - sampled).max() < 0.03
        assert area.min() == 0.0 and area.max() == 1.0


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 2 * math.pi), st.floats(-0.3, 0.3))
@example(0.78125, 0.265625)  # near a pixel's corner the centre's extent is not the area
@example(0.0, 0.005859375)  # along the rows: 0.07 of a pixel
def test_each_crossed_pixel_gets_the_edge_coverage(angle, offset):
    pts, faces, n = _quad_through(angle, offset)
    img, depth, cov = _drawn(pts, n)
    e = silhouette_edges(pts, faces, np.eye(4), (W, H), EYE)
    out = edge_antialias(img, depth, e).astype(float)[..., 0]
    want = 40 + 160 * cov
    inner = np.zeros((H, W), bool)
    inner[2:-2, 2:-2] = True  # the pass leaves the picture's outer rows and columns
    # each pixel the edge crosses gets its exact area share, near the pixels' corners too
    # (where the share is not the extent across the edge at the column's centre): within
    # the blend's rounding to 8 bits
    err = np.abs(out - want)[inner]
    assert err.max() <= 1.0, err.max()
    assert np.mean(err) <= 0.5, np.mean(err)
    # and far closer to it than the drawn picture (an edge along the pixels' borders: the
    # drawn picture is exact, and a blend by a coverage of 0.999 may round a grey level
    # away)
    raw = np.abs(img.astype(float)[..., 0] - want)[inner]
    assert np.maximum(err - 1.0, 0.0).sum() <= raw.sum() + 1e-9
    if raw.max() > 8:
        assert err.sum() < 0.1 * raw.sum(), (err.sum(), raw.sum())


@pytest.mark.fast
def test_a_hidden_edge_leaves_the_picture_alone():
    pts, faces, n = _quad_through(0.3, 0.05)
    img, depth, _ = _drawn(pts, n)
    near = depth.copy()
    near[:] = 0.2  # something nearer covers the whole picture
    e = silhouette_edges(pts, faces, np.eye(4), (W, H), EYE)
    assert np.array_equal(edge_antialias(img, near, e), img)
    assert not np.array_equal(edge_antialias(img, depth, e), img)


@pytest.mark.fast
def test_a_face_turned_away_is_a_silhouette_only_beside_one_turned_towards():
    # a ridge along x seen from the +y side, low: the face sloping down towards the eye
    # is turned towards it, the other away; the ridge is a silhouette, listed once per
    # face beside it
    pts = np.array([[0, 0, 1.0], [1, 0, 1], [0.5, 1, 0], [0.5, -1, 0]])
    ridge = np.array([[0, 1, 2], [1, 0, 3]])
    e = silhouette_edges(pts, ridge, np.eye(4), (W, H), eye=(0.5, 5.0, 0.5))
    pairs = [tuple(sorted(p)) for p in zip(e.a.tolist(), e.b.tolist(), strict=True)]
    assert pairs.count((0, 1)) == 2
    # seen from above, both faces are turned towards the eye: only the border
    e = silhouette_edges(pts, ridge, np.eye(4), (W, H), eye=(0.5, 0.0, 10.0))
    assert (0, 1) not in [tuple(sorted(p)) for p in zip(e.a.tolist(), e.b.tolist(), strict=True)]
    assert len(e.a) == 4


@pytest.mark.fast
def test_bad_input_is_refused_before_the_compiled_passes():
    pts, faces, n = _quad_through(0.2, 0.0)
    cases = [(pts[:, :2], faces), (np.where(pts == pts[0], np.nan, pts), faces),
             (pts, faces[:, :2]), (pts, faces + 4), (pts, faces - 1)]
    for p, f in cases:
        with pytest.raises(ValueError, match="points|faces"):
            silhouette_edges(p, f, np.eye(4), (W, H), EYE)
    with pytest.raises(ValueError, match="projection"):
        silhouette_edges(pts, faces, np.eye(3), (W, H), EYE)
    with pytest.raises(ValueError, match="projection"):
        silhouette_edges(pts, faces, np.eye(4), (0, H), EYE)
    e = silhouette_edges(pts, faces, np.eye(4), (W, H), EYE)
    img, depth, _ = _drawn(pts, n)
    for i, d in ((img[:-1], depth[:-1]), (img, depth[:, :-1]), (img.astype(float), depth)):
        with pytest.raises(ValueError, match="the size the edges were found for"):
            edge_antialias(i, d, e)


@pytest.mark.fast
def test_sparse_counts_distinct_edges_on_screen():
    pts, faces, _ = _quad_through(0.2, 0.0)
    e = silhouette_edges(pts, faces, np.eye(4), (W, H), EYE)
    assert e.on_screen() == 1  # the one border edge through the picture
    assert sparse(e)


@pytest.mark.fast
def test_auto_takes_msaa_where_silhouettes_crowd(tmp_path_factory, monkeypatch):
    """``auto`` draws with MSAA when the edges are dense, blends them when they are
    sparse, and each picture is the fixed mode's, pixel for pixel, in either order."""
    from geoterrain.rendering.scene import TerrainScene, default_view
    from geoterrain.rendering.window import pyvista_plotter
    from tests.rendering.test_render import synth_store

    t = synth_store(tmp_path_factory, "draw", size=129)
    size = (240, 160)
    scenes = {m: TerrainScene(pyvista_plotter(size, m), t) for m in ("auto", "msaa", "edges")}
    try:
        v = default_view(t, size, 30.0)
        ref = {m: scenes[m].frame(v, 1.0)[0] for m in ("msaa", "edges")}
        got = []
        for limit in (math.inf, 0.0, math.inf):
            monkeypatch.setattr(edgeaa, "SPARSE_EDGES_PER_KPX", limit)
            img, stats = scenes["auto"].frame(v, 1.0)
            got.append(stats["anti_aliasing"])
            assert np.array_equal(img, ref[stats["anti_aliasing"]])
        assert got == ["edges", "msaa", "edges"]
        assert not np.array_equal(ref["msaa"], ref["edges"])
    finally:
        for s in scenes.values():
            s.plotter.close()


def test_auto_is_as_close_to_a_supersampled_picture_as_msaa(tmp_path_factory):
    """Against the same mesh and atlas drawn 4 × 4 larger and box-filtered, ``auto``
    is within 1 dB of 4× MSAA or closer: it takes the geometric pass where that holds
    (a gentle fBm) and MSAA where silhouettes crowd (a rough one, where the pass alone
    is 1-2 dB further)."""
    from geoterrain.rendering.scene import TerrainScene, default_view
    from geoterrain.rendering.window import draw, pyvista_plotter
    from tests.rendering.test_render import psnr, synth_store

    size, S = (320, 200), 4
    out = []
    for t in (synth_store(tmp_path_factory, "fbm"),
              synth_store(tmp_path_factory, "gentle", relief=200.0)):
        scenes = {m: TerrainScene(pyvista_plotter(size, m), t) for m in ("msaa", "auto", "none")}
        try:
            for az, el in ((200.0, 30.0), (60.0, 15.0)):
                v = default_view(t, size, az, el)
                pics, taken = {}, None
                for m, s_ in scenes.items():
                    pics[m], st_ = s_.frame(v, 1.0)
                    taken = st_["anti_aliasing"] if m == "auto" else taken
                big = scenes["none"].plotter
                big.window_size = [size[0] * S, size[1] * S]
                hi = draw(big).astype(float)
                big.window_size = list(size)
                truth = np.rint(hi.reshape(size[1], S, size[0], S, 3).mean((1, 3)))
                out.append({m: psnr(truth.astype(np.uint8), p) for m, p in pics.items()}
                           | {"taken": taken})
        finally:
            for s_ in scenes.values():
                s_.plotter.close()
    print(out)
    assert {o["taken"] for o in out} == {"edges", "msaa"}
    for o in out:
        assert o["auto"] >= o["msaa"] - 1.0, o
        assert o["auto"] >= o["none"] + 3.0, o


@pytest.mark.fast
def test_a_mesh_too_large_for_the_edge_table_is_drawn_with_msaa(tmp_path_factory,
                                                                   monkeypatch):
    from geoterrain.rendering import scene as rendering
    from geoterrain.rendering.scene import TerrainScene, default_view
    from geoterrain.rendering.window import pyvista_plotter
    from tests.rendering.test_render import synth_store

    t = synth_store(tmp_path_factory, "draw", size=129)
    monkeypatch.setattr(rendering, "SPARSE_MAX_FACES", 10)
    scene = TerrainScene(pyvista_plotter((160, 120), "auto"), t)
    try:
        _, stats = scene.frame(default_view(t, (160, 120)), 1.0)
    finally:
        scene.plotter.close()
    assert stats["anti_aliasing"] == "msaa" and stats["triangles"] > 10


pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _reference_edges(pts, faces, eye, ok):
    """The silhouette and border edges listed one by one (a dict of each undirected
    edge's faces in face order): (a, b, c) of each face listed beside its edge, the
    first face seen and the last other one, as :func:`silhouette_edges` documents them,
    edges ordered by their smaller vertex, then by their first face and side."""
    e = np.asarray(eye, float)
    u, v = pts[faces[:, 1]] - pts[faces[:, 0]], pts[faces[:, 2]] - pts[faces[:, 0]]
    n = np.cross(u, v)
    n[n[:, 2] < 0] *= -1
    toward = (np.einsum("ij,ij->i", n, e - pts[faces[:, 0]]) > 0) & ok[faces].all(1)
    by_edge: dict = {}
    for f, tri in enumerate(faces.tolist()):
        for k in range(3):
            by_edge.setdefault(frozenset((tri[k], tri[(k + 1) % 3])), []).append((f, k))
    out = []
    # in the order the pictures depend on (a pixel two edges cross gets the later
    # one's blend): by the edge's smaller vertex, then its first face and side
    for _, sides in sorted(by_edge.items(), key=lambda kv: (min(kv[0]), kv[1][0])):
        pair = [sides[0]] + ([sides[-1]] if len(sides) > 1 else [])
        if len(pair) == 2 and toward[pair[0][0]] == toward[pair[1][0]]:
            continue
        for f, k in pair:
            tri = faces[f].tolist()
            if ok[tri].all():
                out.append((tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]))
    return out


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(2, 7), st.integers(2, 7), st.integers(0, 2**32 - 1))
def test_the_edges_are_each_edges_faces_listed_one_by_one(rows, cols, seed):
    # a random height field (random diagonals, holes, a repeated face: an edge with three
    # faces) seen from a random eye, through a projection that puts part of it behind
    # the eye (w < 0) and part of it off the picture
    rng = np.random.default_rng(seed)
    j, i = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    pts = np.column_stack([j.ravel() - cols / 2, i.ravel() - rows / 2,
                           rng.normal(0, 1, rows * cols)])
    faces = []
    for r in range(rows - 1):
        for c in range(cols - 1):
            a, b, d, e = r * cols + c, r * cols + c + 1, (r + 1) * cols + c, (r + 1) * cols + c + 1
            tris = [[a, b, e], [a, e, d]] if rng.random() < 0.5 else [[a, b, d], [b, e, d]]
            faces += [t for t in tris if rng.random() < 0.85]
    if not faces:
        return
    faces = np.array(faces)
    if len(faces) > 2:
        faces = np.vstack([faces, faces[rng.integers(len(faces))][[1, 0, 2]]])
    eye = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3, 6))
    proj = np.eye(4) * 0.3
    proj[3] = (0.2, 0.1, 0.0, 1.0)  # w = 1 + 0.2 x + 0.1 y: behind the eye where < 0
    e = silhouette_edges(pts, faces, proj, (W, H), eye)
    ok = (proj[3, :3] @ pts.T + proj[3, 3]) > 1e-12
    got = list(zip(e.a.tolist(), e.b.tolist(), e.c.tolist(), strict=True))
    assert got == _reference_edges(pts, faces, eye, ok)  # in order: the blend's
    # the count of distinct edges on screen made while listing them is the numpy one
    again = edgeaa.Silhouettes(e.x, e.y, e.z, e.a, e.b, e.c, e.tol, e.size)
    assert e.n_on_screen == again.on_screen()


@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(st.integers(3, 200), st.integers(0, 2**32 - 1))
def test_a_vertex_with_many_edges_lists_each_edge_once(n, seed):
    # a fan of n faces round vertex 0 (its bucket holds 2n half-edges: past the
    # compiled pass's 64-bit record of those met), closed or open, random heights, a
    # face repeated (an edge with three faces)
    rng = np.random.default_rng(seed)
    a = np.sort(rng.uniform(0, 2 * np.pi, n))
    pts = np.vstack([[0.0, 0.0, rng.normal()], np.column_stack(
        [np.cos(a), np.sin(a), rng.normal(0, 1, n)])])
    faces = [[0, 1 + k, 1 + (k + 1) % n] for k in range(n if rng.random() < 0.5 else n - 1)]
    faces.append(faces[rng.integers(len(faces))][::-1])
    faces = np.array(faces)[rng.permutation(len(faces))]
    eye = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(0.5, 4))
    e = silhouette_edges(pts, faces, np.eye(4) * 0.3 + np.diag([0, 0, 0, 0.7]), (W, H), eye)
    got = list(zip(e.a.tolist(), e.b.tolist(), e.c.tolist(), strict=True))
    assert got == _reference_edges(pts, faces, eye, np.ones(len(pts), bool))

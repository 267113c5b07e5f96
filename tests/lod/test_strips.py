"""Seed 002's triangle strips (geoterrain/lod/strips.py): the golden strip of L490, the
strip statistics of T12, and strips of a view's mesh that draw its triangles (winding
included) and its picture."""

from __future__ import annotations

import numpy as np
import pytest

from geoterrain.lod.strips import anexa_strip, seed_order, strip_triangles, triangle_strips

# the labels of the seed's 5 × 5 example (x east, y north; seed notes §2.7)
LABEL = {(0, 0): 0, (4, 0): 1, (4, 4): 2, (0, 4): 3, (2, 2): 4, (0, 2): 5, (2, 0): 6,
         (4, 2): 7, (2, 4): 8, (1, 1): 9, (3, 1): 10, (2, 1): 17}


@pytest.mark.fast
def test_the_seeds_example_strip():
    """T11: active {4, 5, 6, 7, 8, 9, 10, 17} gives L490's strip after the two leading
    copies of vertex 0; 14 triangles of total area 16."""
    act = {v for v, k in LABEL.items() if k in (4, 5, 6, 7, 8, 9, 10, 17)}
    strip = [LABEL[v] for v in anexa_strip(lambda v: v in act, 4)]
    assert strip[2:] == [0, 9, 6, 9, 17, 4, 17, 10, 6, 10, 1, 10, 7, 4, 2, 4, 8, 4, 3, 4, 5,
                         9, 0]
    pts = sorted(LABEL, key=LABEL.get)
    idx = {p: q for q, p in enumerate(pts)}
    s = [idx[v] for v in anexa_strip(lambda v: v in act, 4)][1:]
    tris = strip_triangles(np.array([len(s), *s]))
    xy = np.array(pts, float)
    u, v = xy[tris[:, 1]] - xy[tris[:, 0]], xy[tris[:, 2]] - xy[tris[:, 0]]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    assert len(tris) == 14 and area.sum() == 16.0


@pytest.mark.fast
@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_full_refinement_strip_statistics(k):
    """T12: full refinement of a (2^k + 1)² grid draws 2·4^k triangles with a strip of
    (10·4^k + 11)/3 vertices (the two leading copies included); the strips made from
    its triangles in the seed's order are one strip of the same length less one."""
    strip = anexa_strip(lambda v: True, 2 * k)
    assert len(strip) == (10 * 4 ** k + 11) // 3
    pts = sorted(set(strip))
    idx = {p: q for q, p in enumerate(pts)}
    s = [idx[v] for v in strip[1:]]
    tris = strip_triangles(np.array([len(s), *s]))
    assert len(tris) == 2 * 4 ** k
    side = 1 << k
    ij = np.array([[side - y, x] for x, y in pts])
    shuffled = tris[np.random.default_rng(k).permutation(len(tris))]
    cells, st = triangle_strips(shuffled[seed_order(shuffled, ij, k)])
    assert st["strips"] == 1 and st["strip_vertices"] == len(strip) - 2


@pytest.mark.fast
def test_root_alone_and_root_inactive():
    assert len(strip_triangles(_cells(anexa_strip(lambda v: False, 2)))) == 2
    assert len(strip_triangles(_cells(anexa_strip(lambda v: v == (1, 1), 2)))) == 4


def _cells(strip):
    pts = sorted(set(strip))
    idx = {p: q for q, p in enumerate(pts)}
    s = [idx[v] for v in strip[1:]]
    return np.array([len(s), *s])


@pytest.mark.fast
def test_strips_of_a_view_draw_its_triangles(tmp_path):
    """The strips of an rtin view's mesh draw exactly its triangles, each with its
    winding, and far fewer vertex references than the lists (seed order)."""
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    t = geoterrain.open(geoterrain.preprocess(
        write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=2)), tile_size=32))
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    sel = t.select(geoterrain.View(tuple(c + [0, -2500.0, 1200]), tuple(c), size=(640, 360)))
    faces = np.asarray(sel.mesh.regular_faces)
    order = seed_order(faces, np.asarray(sel.mesh.point_data["grid_ij"]), t.grid.n)
    cells, st = triangle_strips(faces[order])
    canon = lambda f: {tuple(np.roll(r, -int(np.argmin(r)))) for r in f}  # noqa: E731
    assert canon(strip_triangles(cells)) == canon(faces)
    assert st["triangles"] == len(faces)
    assert st["strip_vertices"] < 0.75 * 3 * len(faces)
    assert st["triangles"] / st["strips"] > 10


def test_a_strips_picture_is_the_lists_picture(tmp_path):
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.rendering.scene import default_view, render_array

    t = geoterrain.open(geoterrain.preprocess(
        write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=4)), tile_size=32))
    v = default_view(t, (320, 240))
    a, _ = render_array(t, v, anti_aliasing="none")
    b, _ = render_array(t, v, anti_aliasing="none", strips=True)
    assert (a != b).any(axis=2).mean() < 0.002  # the same triangles: rasterised alike

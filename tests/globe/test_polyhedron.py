"""Seed 001's base polyhedron: the rhombic triacontahedron, its face grids, distortion."""

from __future__ import annotations

import numpy as np
import pytest

from geoterrain.globe.polyhedron import (
    FACES,
    cube_distortion,
    distortion,
    face_area_fraction,
    face_directions,
    face_points,
    triacontahedron,
)


def test_the_triacontahedron_has_32_vertices_60_edges_30_planar_rhombi():
    rt = triacontahedron()
    assert rt.vertices.shape == (32, 3) and len(rt.edges) == 60 and rt.faces.shape == (30, 4)
    deg = np.bincount(rt.faces.ravel(), minlength=32)
    assert (deg[:12] == 5).all() and (deg[12:] == 3).all()  # icosahedron / dodecahedron
    for C in rt.corners:
        n = np.cross(C[1] - C[0], C[3] - C[0])
        assert abs(n @ (C[2] - C[0])) < 1e-12  # planar
        assert n @ C.mean(0) > 0  # outward
        sides = np.linalg.norm(np.roll(C, -1, 0) - C, axis=1)
        assert np.allclose(sides, sides[0], rtol=1e-12)  # a rhombus
        long_, short = np.linalg.norm(C[2] - C[0]), np.linalg.norm(C[3] - C[1])
        assert long_ / short == pytest.approx((1 + 5 ** 0.5) / 2, rel=1e-12)  # golden
    # every side is shared by exactly two faces, each naming the other its neighbour
    for f in range(FACES):
        for k in range(4):
            g = rt.neighbours[f, k]
            assert g != f and f in rt.neighbours[g]


def test_each_face_covers_a_thirtieth_of_the_sphere():
    rt = triacontahedron()
    for f in range(FACES):
        assert face_area_fraction(rt, f, 32) == pytest.approx(1 / 30, rel=1e-9)


def test_faces_sharing_an_edge_place_its_samples_bit_for_bit_alike():
    rt = triacontahedron()
    t = np.arange(0, 129) / 128.0
    for f in range(FACES):
        for k, (u, v) in enumerate(((t, 0 * t), (0 * t + 1, t), (t, 0 * t + 1), (0 * t, t))):
            a = face_points(f, u, v, rt)
            g = int(rt.neighbours[f, k])
            ends = {int(rt.faces[f, k]), int(rt.faces[f, (k + 1) % 4])}
            # the same points seen from face g: find the side of g with these two ends
            for kk, (uu, vv) in enumerate(((t, 0 * t), (0 * t + 1, t), (t, 0 * t + 1),
                                           (0 * t, t))):
                if {int(rt.faces[g, kk]), int(rt.faces[g, (kk + 1) % 4])} == ends:
                    b = face_points(g, uu, vv, rt)
                    break
            # as sets of points, bit for bit
            sa = {tuple(p) for p in a.tolist()}
            sb = {tuple(p) for p in b.tolist()}
            assert sa == sb, (f, k, g)


def test_distortion_matches_the_seeds_figures_within_2_percent():
    # seed 001 summary §2.2: area ratio ≈ 1.62, edge ratio ≈ 1.31; a cube face ≈ 5.17
    area, edge = distortion(512)
    assert area == pytest.approx(1.62, rel=0.02)
    assert edge == pytest.approx(1.31, rel=0.02)
    assert cube_distortion(512)[0] == pytest.approx(5.17, rel=0.02)


def test_face_directions_are_unit_and_children_nest_in_parents():
    n = face_directions(4, np.linspace(0, 1, 9)[None, :], np.linspace(0, 1, 9)[:, None])
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-15)
    fine = face_directions(4, np.linspace(0, 1, 17)[None, :], np.linspace(0, 1, 17)[:, None])
    assert np.array_equal(fine[::2, ::2], n)  # even samples of the finer grid, bit for bit

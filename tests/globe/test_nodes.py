"""Node keys and seed 001 §3.2.1 bounds: six planes, 8 corners, a sphere, the horizon."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.globe.nodes import (
    Occluder,
    children,
    decode,
    encode,
    geometry,
    horizon_hidden,
    hull,
    parent,
    shell_distance,
)
from geoterrain.globe.polyhedron import face_directions


@given(st.integers(0, 29), st.integers(0, 22), st.data())
def test_keys_round_trip_and_children_name_their_parent(face, depth, data):
    x = data.draw(st.integers(0, 2 ** depth - 1))
    y = data.draw(st.integers(0, 2 ** depth - 1))
    k = encode(face, depth, x, y)
    assert decode(k) == (face, depth, x, y)
    kids = children(np.array([k]))[0]
    assert (parent(kids) == k).all()
    assert sorted(decode(kids)[2].tolist()) == sorted([2 * x, 2 * x + 1] * 2)


def _node_points(key, lo, hi, rng, n=4000):
    f, D, x, y = decode(key)
    s = 2.0 ** -D
    u = (x + rng.uniform(0, 1, n)) * s
    v = (y + rng.uniform(0, 1, n)) * s
    u[:8], v[:8] = np.repeat([x * s, (x + 1) * s], 4), np.tile([y * s, (y + 1) * s], 4)
    d = face_directions(f, u, v)
    t = rng.uniform(lo, hi, n)
    t[:8] = np.tile([lo, hi], 4)
    return d * t[:, None]


@given(st.integers(0, 29), st.integers(0, 14), st.data())
def test_every_point_of_a_shell_sector_lies_within_its_six_planes_and_sphere(face, depth,
                                                                               data):
    x = data.draw(st.integers(0, 2 ** depth - 1))
    y = data.draw(st.integers(0, 2 ** depth - 1))
    key = encode(face, depth, x, y)
    lo, hi = 6.35e6, 6.39e6
    P = _node_points(key, lo, hi, np.random.default_rng(depth))
    g = geometry(np.array([key]))
    tol = 1e-9 * hi
    assert (np.einsum("kj,nj->nk", g.planes[0], P) <= tol).all()  # 4 side planes
    c = P @ g.centre[0]
    assert (c <= hi + tol).all() and (c >= lo * g.cmin[0] - tol).all()  # top, bottom
    C, mid, rad = hull(g, np.array([lo]), np.array([hi]))
    assert (np.linalg.norm(P - mid[0], axis=1) <= rad[0] + tol).all()
    # the 8 corners are the hull's: each point is a convex combination → its projection on
    # any direction lies within the corners' range
    for w in np.random.default_rng(0).normal(size=(16, 3)):
        assert (P @ w <= (C[0] @ w).max() + tol).all()


@given(st.integers(0, 29), st.integers(0, 10), st.data())
def test_shell_distance_is_exact_from_below(face, depth, data):
    x = data.draw(st.integers(0, 2 ** depth - 1))
    y = data.draw(st.integers(0, 2 ** depth - 1))
    key = encode(face, depth, x, y)
    lo, hi = 6.36e6, 6.38e6
    rng = np.random.default_rng(depth)
    P = _node_points(key, lo, hi, rng, 20000)
    g = geometry(np.array([key]))
    for _ in range(5):
        eye = rng.normal(size=3)
        eye *= rng.uniform(6.3e6, 2e7) / np.linalg.norm(eye)
        d = shell_distance(eye, g, np.array([lo]), np.array([hi]))[0]
        near = np.linalg.norm(P - eye, axis=1).min()
        assert d <= near + 1e-6 * near  # never more than the true distance
        # and within one sample spacing of it (the samples are random)
        assert near - d <= 4156e3 * 2.0 ** -depth * 0.1 + 0.03 * near


def test_horizon_hidden_hulls_are_really_hidden_and_its_cull_is_conservative():
    occ = Occluder(6.3e6, 6.28e6)
    rng = np.random.default_rng(3)
    eye = np.array([0.0, 0.0, 6.3e6 + 2000.0])
    # random small hulls all around the planet
    cen = rng.normal(size=(3000, 3))
    cen /= np.linalg.norm(cen, axis=1)[:, None]
    cen *= rng.uniform(6.28e6, 6.32e6, (3000, 1))
    corners = cen[:, None, :] + rng.normal(scale=2e3, size=(3000, 8, 3))
    hidden, front = horizon_hidden(occ, eye, corners)
    assert hidden.sum() > 1000 and not (hidden & front).any()
    # a hidden corner's sight line from the eye passes through the occluder
    s = np.array([1 / occ.a, 1 / occ.a, 1 / occ.b])
    E = eye * s
    for P in corners[hidden].reshape(-1, 3)[:2000]:
        D = P * s - E
        a, b, c = D @ D, 2 * E @ D, E @ E - 1
        disc = b * b - 4 * a * c
        assert disc >= 0
        t = (-b - disc ** 0.5) / (2 * a)
        assert 0 <= t <= 1

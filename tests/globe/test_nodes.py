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


def _shell_distance_reference(eye, g, lo, hi):
    """The same distance in whole-array numpy (the form it had before its compiled pass)."""
    e = np.asarray(eye, np.float64)
    re = float(np.linalg.norm(e))
    inside = (np.einsum("nkj,j->nk", g.planes, e) <= 0).all(1)
    out = np.maximum(np.maximum(lo - re, re - hi), 0.0)
    k = np.flatnonzero(~inside)
    a = g.dirs[k]
    b = np.roll(a, -1, axis=1)
    n = g.planes[k]
    h = np.einsum("mkj,j->mk", n, e)
    q = e[None, None, :] - h[..., None] * n
    axb = np.cross(a, b)
    alpha = np.einsum("mkj,mkj->mk", np.cross(q, b), axb)
    beta = np.einsum("mkj,mkj->mk", np.cross(a, q), axb)
    qn = np.linalg.norm(q, axis=-1)
    radial = np.maximum(np.maximum(lo[k, None] - qn, qn - hi[k, None]), 0.0)

    def seg(A, B):
        ab = B - A
        t = np.clip(np.einsum("...j,...j", q - A, ab) / np.maximum(
            np.einsum("...j,...j", ab, ab), 1e-300), 0.0, 1.0)
        return np.linalg.norm(q - (A + t[..., None] * ab), axis=-1)

    s = np.minimum(seg(a * lo[k, None, None], a * hi[k, None, None]),
                   seg(b * lo[k, None, None], b * hi[k, None, None]))
    out[k] = np.sqrt(h * h + np.where((alpha >= 0) & (beta >= 0), radial, s) ** 2).min(1)
    return out


@given(st.integers(0, 29), st.integers(0, 24), st.integers(0, 2 ** 31), st.sampled_from(
    [2.0, 50.0, 3e3, 1e6, 2e7]))
def test_shell_distance_compiled_pass_matches_the_whole_array_form(face, depth, seed,
                                                                   height):
    """The compiled pass the selection runs gives the whole-array form's distances (to
    rounding), for nodes from a face down to centimetres and eyes from 2 m up to 20 000 km:
    around the node, beside it, and over its neighbours."""
    rng = np.random.default_rng(seed)
    m = 1 << depth
    x = rng.integers(0, m, 64)
    y = rng.integers(0, m, 64)
    # the node and its neighbours (clipped to the face), and the eye over one of them
    x = np.clip(x[:1] + rng.integers(-2, 3, 64), 0, m - 1)
    y = np.clip(y[:1] + rng.integers(-2, 3, 64), 0, m - 1)
    g = geometry(encode(face, depth, x, y))
    lo = rng.uniform(6.34e6, 6.36e6, 64)
    hi = lo + rng.uniform(0.0, 3e4, 64)
    s = 2.0 ** -depth
    u, v = (x[0] + rng.uniform(-1, 2)) * s, (y[0] + rng.uniform(-1, 2)) * s
    d = face_directions(face, np.clip(u, 0, 1), np.clip(v, 0, 1))
    eye = d * (6.36e6 + height)
    got = shell_distance(eye, g, lo, hi)
    ref = _shell_distance_reference(eye, g, lo, hi)
    assert np.all(np.abs(got - ref) <= 1e-9 * ref + 1e-6), np.abs(got - ref).max()

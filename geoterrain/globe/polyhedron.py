"""Seed 001's base polyhedron: the rhombic triacontahedron (RT) and its 30 face grids.

The RT (as in Crusta, seed 001 §2.2, L300) has 32 vertices (the 12 of an icosahedron,
degree 5, and the 20 of a dodecahedron, degree 3), 60 edges and 30 golden rhombi. Each
rhombus is one quadtree root. A face is a parallelogram, so the seed's bilinear map
p(u, v) = (1−u)(1−v)V0 + u(1−v)V1 + uv·V2 + (1−u)v·V3 is affine,
p = V0 + u(V1 − V0) + v(V3 − V0), and a direction on the globe is n = p / |p| (the
seed's "bilinear, then normalise", L350). Midpoint subdivision nests exactly: the even
samples of a child's grid are its parent's samples.

Conventions
-----------
- V0 and V2 are icosahedron vertices (the long diagonal, u = v), V1 and V3 dodecahedron
  vertices (the short one); (V1 − V0) × (V3 − V0) points outward.
- The polyhedron is turned so that an icosahedron vertex is the north pole (0, 0, 1):
  five faces meet at each pole, and no face edge follows the antimeridian.
- A face sample at depth D is (i, j), 0 ≤ i, j ≤ n·2^D (n cells a node side): u = j/(n·2^D),
  v = i/(n·2^D). The fractions are dyadic, so every level computes a sample's point from
  the same (u, v), bit for bit.
- A point on a face edge is computed from that edge's two vertices, the lower vertex id
  first, so the two faces that share the edge place it bit for bit alike.

Examples
--------
>>> rt = triacontahedron()
>>> rt.corners.shape, len(rt.vertices), len(rt.edges)
((30, 4, 3), 32, 60)
>>> round(float(face_area_fraction(rt, 0)), 12)  # each face is 1/30 of the sphere
0.033333333333
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["Triacontahedron", "triacontahedron", "face_points", "face_directions",
           "face_coordinates", "distortion", "cube_distortion", "face_area_fraction", "FACES"]

FACES = 30
PHI = (1.0 + 5.0 ** 0.5) / 2.0


@dataclass(frozen=True)
class Triacontahedron:
    """The RT's geometry, float64.

    ``vertices`` (32, 3): unit icosahedron vertices (ids 0–11) scaled to 1, dodecahedron
    vertices (ids 12–31) scaled so that every rhombus is planar. ``faces`` (30, 4): the
    vertex ids V0, V1, V2, V3 of each face. ``corners`` (30, 4, 3): their positions.
    ``edges`` (60, 2): vertex id pairs, lower first. ``neighbours`` (30, 4): the face across
    each side (V0V1, V1V2, V2V3, V3V0)."""

    vertices: np.ndarray
    faces: np.ndarray
    corners: np.ndarray
    edges: np.ndarray
    neighbours: np.ndarray


def _pole_rotation(v: np.ndarray) -> np.ndarray:
    """The rotation taking unit ``v`` to (0, 0, 1) (Rodrigues)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(v, z)
    s, c = np.linalg.norm(axis), float(v @ z)
    if s < 1e-15:
        return np.eye(3)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * (K @ K)


@lru_cache(maxsize=1)
def triacontahedron() -> Triacontahedron:
    """The RT, built from the icosahedron (cached; arrays are read-only).

    Examples
    --------
    >>> rt = triacontahedron()
    >>> bool(np.allclose(rt.vertices[0], [0, 0, 1]))  # a degree-5 vertex at the pole
    True
    """
    ico = []
    for s1, s2 in itertools.product((1.0, -1.0), repeat=2):
        ico += [(0.0, s1, s2 * PHI), (s1, s2 * PHI, 0.0), (s2 * PHI, 0.0, s1)]
    ico = np.array(ico)
    ico /= np.linalg.norm(ico, axis=1)[:, None]
    ico = ico @ _pole_rotation(ico[0]).T
    d = np.linalg.norm(ico[:, None] - ico[None], axis=2)
    e = d[d > 1e-9].min()
    near = np.abs(d - e) < 1e-9
    edges = [(a, b) for a in range(12) for b in range(a + 1, 12) if near[a, b]]
    tris = [t for t in itertools.combinations(range(12), 3)
            if near[t[0], t[1]] and near[t[1], t[2]] and near[t[0], t[2]]]
    cen = np.array([ico[list(t)].mean(0) for t in tris])
    cen /= np.linalg.norm(cen, axis=1)[:, None]
    a, b = edges[0]
    m = ico[a] + ico[b]
    k0 = next(k for k, t in enumerate(tris) if a in t and b in t)
    scale = float((ico[a] @ m) / (cen[k0] @ m))  # makes each rhombus planar
    verts = np.concatenate([ico, cen * scale])
    faces, corners = [], []
    for a, b in edges:
        c1, c2 = (12 + k for k, t in enumerate(tris) if a in t and b in t)
        V0, V1, V3 = verts[a], verts[c1], verts[c2]
        if np.cross(V1 - V0, V3 - V0) @ (V0 + verts[b]) < 0:
            c1, c2 = c2, c1
        faces.append((a, c1, b, c2))
        corners.append(verts[[a, c1, b, c2]])
    faces = np.array(faces, np.int64)
    rt_edges = sorted({tuple(sorted((int(f[k]), int(f[(k + 1) % 4])))) for f in faces
                       for k in range(4)})
    side = {}
    for fi, f in enumerate(faces):
        for k in range(4):
            side.setdefault(tuple(sorted((int(f[k]), int(f[(k + 1) % 4])))), []).append(fi)
    nb = np.array([[next(g for g in side[tuple(sorted((int(f[k]), int(f[(k + 1) % 4]))))]
                         if g != fi) for k in range(4)] for fi, f in enumerate(faces)])
    out = Triacontahedron(verts, faces, np.array(corners), np.array(rt_edges, np.int64), nb)
    for arr in (out.vertices, out.faces, out.corners, out.edges, out.neighbours):
        arr.setflags(write=False)
    return out


def face_points(face: int | np.ndarray, u: np.ndarray, v: np.ndarray,
                rt: Triacontahedron | None = None) -> np.ndarray:
    """Flat RT points p(u, v) (..., 3) of ``face`` at parameters ``u``, ``v`` in [0, 1].

    Points on a face edge are taken along that edge from its lower vertex id, so the
    faces sharing it agree bit for bit.

    Examples
    --------
    >>> rt = triacontahedron()
    >>> bool(np.array_equal(face_points(0, np.array([0.0]), np.array([0.0]))[0],
    ...                     rt.corners[0, 0]))
    True
    """
    rt = rt or triacontahedron()
    u, v = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    if np.ndim(face) == 0:  # one face: no per-point gather of its corners
        C0 = rt.corners[int(face)]
        P = C0[0] + u[..., None] * (C0[1] - C0[0]) + v[..., None] * (C0[3] - C0[0])
        edge = (u == 0) | (u == 1) | (v == 0) | (v == 1)
        if not edge.any():
            return P
        P[edge] = face_points(np.full(int(edge.sum()), int(face)), u[edge], v[edge], rt)
        return P
    face = np.broadcast_to(np.asarray(face, np.int64), u.shape)
    C = rt.corners[face]  # (..., 4, 3)
    V0, V1, V3 = C[..., 0, :], C[..., 1, :], C[..., 3, :]
    P = V0 + u[..., None] * (V1 - V0) + v[..., None] * (V3 - V0)
    ids = rt.faces[face]  # (..., 4)
    # edges: (corner a, corner b, parameter along a → b)
    for ka, kb, on, t in ((0, 1, v == 0, u), (1, 2, u == 1, v), (3, 2, v == 1, u),
                          (0, 3, u == 0, v)):
        if not on.any():
            continue
        A, B = C[on][:, ka], C[on][:, kb]
        tt = t[on]
        flip = ids[on][:, ka] > ids[on][:, kb]
        A2 = np.where(flip[:, None], B, A)
        B2 = np.where(flip[:, None], A, B)
        tt = np.where(flip, 1.0 - tt, tt)
        P[on] = A2 + tt[:, None] * (B2 - A2)
    for k, (cu, cv) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):  # the vertices exactly
        at = (u == cu) & (v == cv)
        if at.any():
            P[at] = C[at][:, k]
    return P


def face_directions(face: int | np.ndarray, u: np.ndarray, v: np.ndarray,
                    rt: Triacontahedron | None = None) -> np.ndarray:
    """Unit directions n = p / |p| (float64) of face points (seed 001, L350).

    Examples
    --------
    >>> n = face_directions(3, np.array([0.5]), np.array([0.5]))
    >>> round(float(np.linalg.norm(n)), 12)
    1.0
    """
    P = face_points(face, u, v, rt)
    return P / np.linalg.norm(P, axis=-1)[..., None]


def face_coordinates(d: np.ndarray, rt: Triacontahedron | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The inverse of :func:`face_directions`: for unit rays ``d`` (N, 3), the face each
    leaves the RT through, its parameters u, v there and |p| of that flat face point.

    The ray leaves through the face whose plane it meets first (the RT is convex); the
    face's map is affine, so u, v solve a 2 × 2 system.

    Examples
    --------
    >>> f, u, v, fn = face_coordinates(face_directions(7, np.array([0.3]), np.array([0.6])))
    >>> int(f[0]), round(float(u[0]), 12), round(float(v[0]), 12)
    (7, 0.3, 0.6)
    """
    rt = rt or triacontahedron()
    d = np.asarray(d, np.float64).reshape(-1, 3)
    C = np.asarray(rt.corners)
    E1, E2 = C[:, 1] - C[:, 0], C[:, 3] - C[:, 0]
    nrm = np.cross(E1, E2)
    c = np.einsum("fj,fj->f", nrm, C[:, 0])
    nrm = nrm / c[:, None]  # the face's plane is nrm·p = 1
    f = np.argmax(d @ nrm.T, axis=1)
    t = 1.0 / np.einsum("nj,nj->n", d, nrm[f])
    F = d * t[:, None] - C[f, 0]
    a, b = E1[f], E2[f]
    g11, g12, g22 = (np.einsum("nj,nj->n", a, a), np.einsum("nj,nj->n", a, b),
                     np.einsum("nj,nj->n", b, b))
    r1, r2 = np.einsum("nj,nj->n", a, F), np.einsum("nj,nj->n", b, F)
    det = g11 * g22 - g12 * g12
    u = (g22 * r1 - g12 * r2) / det
    v = (g11 * r2 - g12 * r1) / det
    return f, u, v, t


def _spherical_triangle_area(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Solid angle of unit-vector triangles (Van Oosterom & Strackee)."""
    num = np.abs(np.einsum("...i,...i", a, np.cross(b, c)))
    den = 1 + np.einsum("...i,...i", a, b) + np.einsum("...i,...i", b, c) \
        + np.einsum("...i,...i", c, a)
    return 2 * np.arctan2(num, den)


def _grid_stats(P: np.ndarray) -> tuple[float, float]:
    """(largest / smallest cell area, longest / shortest cell edge) of a unit-sphere grid."""
    A = _spherical_triangle_area(P[:-1, :-1], P[:-1, 1:], P[1:, 1:]) \
        + _spherical_triangle_area(P[:-1, :-1], P[1:, 1:], P[1:, :-1])
    e1 = np.arccos(np.clip(np.einsum("...i,...i", P[:, :-1], P[:, 1:]), -1, 1))
    e2 = np.arccos(np.clip(np.einsum("...i,...i", P[:-1], P[1:]), -1, 1))
    E = np.concatenate([e1.ravel(), e2.ravel()])
    return float(A.max() / A.min()), float(E.max() / E.min())


def distortion(cells: int = 512, face: int = 0) -> tuple[float, float]:
    """Seed 001's distortion figures for one RT face's bilinear-then-normalise grid of
    ``cells`` × ``cells``: (largest / smallest spherical cell area, longest / shortest cell
    edge). The seed summary gives ≈ 1.62 and ≈ 1.31 (§2.2, [DERIVED]).

    Examples
    --------
    >>> a, e = distortion(64)
    >>> round(a, 3), round(e, 3)
    (1.604, 1.309)
    """
    u = np.linspace(0.0, 1.0, cells + 1)
    U, V = np.meshgrid(u, u)
    return _grid_stats(face_directions(face, U, V))


def cube_distortion(cells: int = 512) -> tuple[float, float]:
    """The same figures for a cube face gridded at equal spacing, then normalised (the
    gnomonic cube map): the seed summary gives an area ratio ≈ 5.17.

    Examples
    --------
    >>> round(cube_distortion(64)[0], 2)
    5.03
    """
    x = np.linspace(-1.0, 1.0, cells + 1)
    X, Y = np.meshgrid(x, x)
    Q = np.stack([X, Y, np.ones_like(X)], -1)
    return _grid_stats(Q / np.linalg.norm(Q, axis=-1)[..., None])


def face_area_fraction(rt: Triacontahedron, face: int, cells: int = 64) -> float:
    """The fraction of the sphere that ``face`` covers (1/30 for every face)."""
    u = np.linspace(0.0, 1.0, cells + 1)
    U, V = np.meshgrid(u, u)
    P = face_directions(face, U, V, rt)
    A = _spherical_triangle_area(P[:-1, :-1], P[:-1, 1:], P[1:, 1:]) \
        + _spherical_triangle_area(P[:-1, :-1], P[1:, 1:], P[1:, :-1])
    return float(A.sum() / (4 * np.pi))

"""Seed 001 §3.2.1–3.2.2: a node's bounds and the tests made on them, on arrays of nodes.

A node is (face, depth, x, y): the face's u ∈ [x, x + 1]/2^D, v ∈ [y, y + 1]/2^D. Every point
it draws, and every lattice point of its subtree, lies on a ray through its flat quad and
between two distances from the centre, ρ_lo and ρ_hi: a *shell sector*. Its bounds are the
seed's six planes:

- **4 side planes** through the centre and each flat edge (n_k·x ≤ 0 inside, normals
  outward). They are exact on the ellipsoid too, because every vertex lies on its own ray
  (:mod:`geoterrain.globe.model`): the seed's worry that an ellipsoid's non-uniform scale
  breaks plane bounds (L539) does not arise for points placed along rays.
- **a top plane** c·x ≤ ρ_hi (c the centre direction): tangent to the sphere S_max;
- **a bottom plane** c·x ≥ ρ_lo·min_k(c·ĉ_k): through the corner farthest from c (on the
  long diagonal) projected onto S_min.

The **8 corners** are the side edges' ends on the top and bottom planes; their hull is the
six-plane volume. The **bounding sphere** is centred on their mean.

Tests (all conservative, all on whole arrays):

- :func:`shell_distance`: the exact distance from the eye to the shell sector (the seed
  intersects its volume with a sphere by SAT; ours is exact and tighter: the distance to the
  cone's side wedges, or radially inside the cone);
- :func:`frustum_state`: outside when all 8 corners lie outside one frustum plane, inside
  when all lie inside every plane (then the children skip the test);
- :func:`horizon_hidden`: all 8 corners in the region the occluder hides from the eye (the
  horizon cone behind the horizon plane), in the space where the occluding ellipsoid (the
  lowest possible surface) is the unit sphere. That region is convex, so the hull is hidden.

Examples
--------
>>> g = geometry(np.array([encode(0, 0, 0, 0)]))
>>> g.planes.shape, bool(np.all(np.einsum("nkj,nj->nk", g.planes, g.centre) < 0))
((1, 4, 3), True)
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.globe.polyhedron import FACES, face_directions, face_points

__all__ = ["encode", "decode", "children", "parent", "Geometry", "geometry", "hull",
           "shell_distance", "frustum_state", "horizon_hidden", "Occluder",
           "OUTSIDE", "INTERSECTS", "INSIDE", "node_widths"]

OUTSIDE, INTERSECTS, INSIDE = 0, 1, 2
_XY = 26  # bits of x and y in a key (62 bits in all: face and depth take 10)
_EXACT_DEPTHS = 6  # node widths measured on every node down to here, then halved


def encode(face, depth, x, y):
    """An int64 key of node (face, depth, x, y) (arrays or ints).

    Examples
    --------
    >>> k = encode(7, 3, 5, 2); decode(k)
    (7, 3, 5, 2)
    """
    return ((np.int64(face) * 32 + np.int64(depth)) << np.int64(2 * _XY)) \
        | (np.int64(y) << np.int64(_XY)) | np.int64(x)


def decode(key):
    """(face, depth, x, y) of keys (arrays, or ints for an int)."""
    k = np.asarray(key, np.int64)
    m = np.int64((1 << _XY) - 1)
    x = k & m
    y = (k >> np.int64(_XY)) & m
    fd = k >> np.int64(2 * _XY)
    out = (fd // 32, fd % 32, x, y)
    if np.ndim(key) == 0:
        return tuple(int(v) for v in out)
    return out


def children(keys: np.ndarray) -> np.ndarray:
    """The four children of each key, (N, 4), in quadrant order (x bit, then y bit)."""
    f, d, x, y = decode(np.asarray(keys, np.int64))
    q = np.arange(4)
    return encode(f[:, None], d[:, None] + 1, 2 * x[:, None] + (q & 1), 2 * y[:, None] + (q >> 1))


def parent(keys: np.ndarray) -> np.ndarray:
    """Each key's parent (depth − 1)."""
    f, d, x, y = decode(np.asarray(keys, np.int64))
    return encode(f, d - 1, x // 2, y // 2)


class Geometry(NamedTuple):
    """What a node's key fixes: unit corner directions ``dirs`` (N, 4, 3) in face order
    (u0v0, u1v0, u1v1, u0v1), outward side-plane normals ``planes`` (N, 4, 3) (side k joins
    corner k and k + 1), the centre direction ``centre`` (N, 3) and ``cmin`` (N,) = min_k
    c·ĉ_k, the largest angle's cosine."""

    dirs: np.ndarray
    planes: np.ndarray
    centre: np.ndarray
    cmin: np.ndarray


def geometry(keys: np.ndarray) -> Geometry:
    """The :class:`Geometry` of nodes ``keys``."""
    f, d, x, y = decode(np.asarray(keys, np.int64).reshape(-1))
    s = 1.0 / (2.0 ** d)
    u0, v0 = x * s, y * s
    uu = np.stack([u0, u0 + s, u0 + s, u0], 1)
    vv = np.stack([v0, v0, v0 + s, v0 + s], 1)
    F = face_points(f[:, None], uu, vv)
    dirs = F / np.linalg.norm(F, axis=-1)[..., None]
    cen = face_points(f, u0 + s / 2, v0 + s / 2)
    cen /= np.linalg.norm(cen, axis=-1)[..., None]
    nrm = np.cross(F, np.roll(F, -1, axis=1))
    nrm /= np.linalg.norm(nrm, axis=-1)[..., None]
    # outward: the centre lies on the inner side
    sign = np.where(np.einsum("nkj,nj->nk", nrm, cen) > 0, -1.0, 1.0)
    nrm *= sign[..., None]
    cmin = np.einsum("nkj,nj->nk", dirs, cen).min(1)
    return Geometry(dirs, nrm, cen, cmin)


def hull(g: Geometry, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """The 8 corners (N, 8, 3) of the six-plane volume of shell sectors [lo, hi], its
    bounding sphere's centres (N, 3) and radii (N,)."""
    cd = np.einsum("nkj,nj->nk", g.dirs, g.centre)  # c·ĉ_k
    top = (hi[:, None] / cd)[..., None] * g.dirs
    bottom = ((lo * g.cmin)[:, None] / cd)[..., None] * g.dirs
    C = np.concatenate([bottom, top], 1)
    mid = C.mean(1)
    rad = np.linalg.norm(C - mid[:, None], axis=-1).max(1)
    return C, mid, rad


@njit(cache=True)
def _segment_nb(qx, qy, qz, ax, ay, az, bx, by, bz):
    """Distance from point q to segment a–b."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    t = ((qx - ax) * ux + (qy - ay) * uy + (qz - az) * uz) / max(
        ux * ux + uy * uy + uz * uz, 1e-300)
    t = min(max(t, 0.0), 1.0)
    dx, dy, dz = qx - (ax + t * ux), qy - (ay + t * uy), qz - (az + t * uz)
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _shell_nb(eye, dirs, planes, lo, hi, out):
    ex, ey, ez = eye[0], eye[1], eye[2]
    re = math.sqrt(ex * ex + ey * ey + ez * ez)
    for i in range(out.shape[0]):
        d = max(max(lo[i] - re, re - hi[i]), 0.0)
        inside = True
        for k in range(4):
            if planes[i, k, 0] * ex + planes[i, k, 1] * ey + planes[i, k, 2] * ez > 0:
                inside = False
        if not inside:
            d = math.inf
            for k in range(4):
                ax, ay, az = dirs[i, k, 0], dirs[i, k, 1], dirs[i, k, 2]
                j = (k + 1) % 4
                bx, by, bz = dirs[i, j, 0], dirs[i, j, 1], dirs[i, j, 2]
                nx, ny, nz = planes[i, k, 0], planes[i, k, 1], planes[i, k, 2]
                h = nx * ex + ny * ey + nz * ez
                qx, qy, qz = ex - h * nx, ey - h * ny, ez - h * nz
                # q = α·a + β·b: inside the wedge's angle when α, β ≥ 0 (by cross products:
                # their signs hold for nodes a few centimetres wide)
                cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
                alpha = (qy * bz - qz * by) * cx + (qz * bx - qx * bz) * cy \
                    + (qx * by - qy * bx) * cz
                beta = (ay * qz - az * qy) * cx + (az * qx - ax * qz) * cy \
                    + (ax * qy - ay * qx) * cz
                if alpha >= 0 and beta >= 0:
                    qn = math.sqrt(qx * qx + qy * qy + qz * qz)
                    w = max(max(lo[i] - qn, qn - hi[i]), 0.0)
                else:
                    w = min(_segment_nb(qx, qy, qz, ax * lo[i], ay * lo[i], az * lo[i],
                                        ax * hi[i], ay * hi[i], az * hi[i]),
                            _segment_nb(qx, qy, qz, bx * lo[i], by * lo[i], bz * lo[i],
                                        bx * hi[i], by * hi[i], bz * hi[i]))
                d = min(d, math.sqrt(h * h + w * w))
        out[i] = d


def shell_distance(eye: np.ndarray, g: Geometry, lo: np.ndarray, hi: np.ndarray
                   ) -> np.ndarray:
    """Exact distance from ``eye`` (3,) to each node's shell sector {t·d: d in its cone,
    lo ≤ t ≤ hi} (0 inside).

    Inside the cone the nearest point is radial; outside it lies on a side wedge (the
    nearest direction in a convex spherical polygon to one outside it is on its boundary),
    an annular sector in the side plane: the in-plane distance to it (radial when the
    eye's projection q on the plane lies within the wedge's angle, q = α·a + β·b with
    α, β ≥ 0; else the nearer of its two edge segments), and the eye's height over the
    plane. One compiled pass over the nodes (the selection calls it at every level).

    Examples
    --------
    >>> g = geometry(np.array([encode(0, 0, 0, 0)]))
    >>> e = g.centre[0] * 7e6
    >>> round(float(shell_distance(e, g, np.array([6.3e6]), np.array([6.4e6]))[0]), 3)
    600000.0
    """
    lo = np.ascontiguousarray(lo, np.float64)
    out = np.empty(len(lo))
    if len(lo):
        _shell_nb(np.ascontiguousarray(eye, np.float64).reshape(3),
                  np.ascontiguousarray(g.dirs, np.float64),
                  np.ascontiguousarray(g.planes, np.float64), lo,
                  np.ascontiguousarray(hi, np.float64), out)
    return out


def frustum_state(planes: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """OUTSIDE / INTERSECTS / INSIDE of hulls (N, 8, 3) against inward frustum ``planes``
    (P, 4): outside when all 8 corners are outside one plane (seed 001 L338)."""
    s = np.einsum("nvj,pj->npv", corners, planes[:, :3]) + planes[None, :, 3, None]
    out = np.full(len(corners), INTERSECTS, np.int8)
    out[(s >= 0).all((1, 2))] = INSIDE
    out[(s < 0).all(2).any(1)] = OUTSIDE
    return out


class Occluder(NamedTuple):
    """The ellipsoid nothing can be seen through: semi-axes ``a``, ``b`` (metres), at or
    below the lowest possible surface, less the largest sag of a drawn chord."""

    a: float
    b: float


def horizon_hidden(occ: Occluder, eye: np.ndarray, corners: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(hidden, in front): per hull, whether all its corners lie in the region the occluder
    hides from ``eye`` (the horizon cone behind the horizon plane, seed 001 L344; exact for
    an ellipsoid in the space that makes it the unit sphere), and whether all lie in front
    of the horizon plane (then no part of the hull can be hidden: its children skip the
    test).

    Examples
    --------
    >>> occ = Occluder(6.0e6, 6.0e6)
    >>> eye = np.array([0.0, 0.0, 7.0e6])
    >>> behind = np.tile([0.0, 0.0, -6.5e6], (1, 8, 1)); front = np.tile([0.0, 1e5, 6.5e6],
    ...                                                                     (1, 8, 1))
    >>> horizon_hidden(occ, eye, np.concatenate([behind, front]))[0].tolist()
    [True, False]
    """
    s = np.array([1.0 / occ.a, 1.0 / occ.a, 1.0 / occ.b])
    C = np.asarray(eye, np.float64) * s
    P = corners * s
    vh2 = C @ C - 1.0
    if vh2 <= 0:  # the eye is inside the occluder: hide nothing
        z = np.zeros(len(corners), bool)
        return z, z
    vt = P - C
    proj = -np.einsum("nvj,j->nv", vt, C)  # along the eye → centre axis
    behind = proj > vh2  # beyond the horizon plane
    in_cone = proj * proj >= vh2 * np.einsum("nvj,nvj->nv", vt, vt)
    hidden = (behind & in_cone).all(1)
    return hidden, (~behind).all(1)


def node_widths(max_depth: int, lattice: int = 0) -> np.ndarray:
    """Per depth D ≤ ``max_depth``, the largest chord (unit sphere) between two corners of one
    cell of face lattice level D + ``lattice`` (a node when 0, a cell of an n-cell node when
    log₂ n): the diagonals, the longest. Measured on every cell down to level 6, then
    halved per level with 1 % to spare (the cells become similar).

    Examples
    --------
    >>> w = node_widths(8)
    >>> bool(np.all(np.diff(w) < 0)), round(float(w[0]), 3)
    (True, 1.051)
    """
    out = np.zeros(max_depth + 1)
    for D in range(max_depth + 1):
        L = D + lattice
        if L <= _EXACT_DEPTHS:
            m = 1 << L
            g = np.arange(m + 1) / m
            V, U = np.meshgrid(g, g, indexing="ij")
            w = 0.0
            for f in range(FACES):
                d = face_directions(f, U, V)
                w = max(w, float(np.linalg.norm(d[:-1, :-1] - d[1:, 1:], axis=-1).max()),
                        float(np.linalg.norm(d[1:, :-1] - d[:-1, 1:], axis=-1).max()))
            out[D] = w
        else:
            out[D] = out[D - 1] * 0.5 * 1.01 if D > 0 else 0.0
    if lattice and lattice > _EXACT_DEPTHS:  # every level beyond the measured ones
        w0 = node_widths(0, _EXACT_DEPTHS)[0] * (0.5 * 1.01) ** (lattice - _EXACT_DEPTHS)
        out = w0 * (0.5 * 1.01) ** np.arange(max_depth + 1)
    return out

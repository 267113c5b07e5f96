"""Clip a grid mesh to the data's rectangle (the static mesh of a padded store).

With the padding replicated from the data's edge (:mod:`geoterrain.bounds.edgepad`), the static
mesh may hold triangles that reach past the DEM's last row or column. Each is cut by the
half-planes i ≤ rows − 1 and j ≤ cols − 1 in grid-index space (Sutherland–Hodgman), and the
piece is fanned into triangles. A cut point lies on its triangle's plane, so every
sample keeps the height it had; and it is made once per mesh edge (or once for the
rectangle's corner), so the two triangles of a cut edge share it and no crack opens.
Positions are interpolated along the edge (in x, y, z): on a curvilinear frame the cut
edge is the triangle's chord of the border (see :func:`geoterrain.bounds.curvature.metric_bounds`,
``window``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.typed import Dict

__all__ = ["clip_in_place", "clip_kernel", "new_cuts"]


class ClipRoom(NamedTuple):
    """The working arrays of a clip (:func:`_room`): the cut points made (grid indices
    ``oi``, positions ``oxyz``, keys ``okey``) and the two polygons of :func:`_polygon`,
    the one being cut and the one being made (corner ids ``pid``, the ends ``pu``,
    ``pw`` of the edge a corner was cut from, grid indices ``pc``)."""

    oi: np.ndarray
    oxyz: np.ndarray
    okey: np.ndarray
    pid: np.ndarray
    pu: np.ndarray
    pw: np.ndarray
    pc: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _key(ij, v, M):
    """The sample of grid vertex v (flat index i·M + j): names cut edges, orders pairs."""
    return np.int64(ij[v, 0]) * M + np.int64(ij[v, 1])


@njit(cache=True, nogil=True)
def _cut(ij, xyz, u, w, axis, lim, oi, oxyz, n, M):
    """Write the point of edge (u, w) at ``ij[:, axis] = lim`` as new vertex n (computed
    from the pair ordered by sample, so both triangles of the edge get the same bits,
    in memory or streamed)."""
    if _key(ij, u, M) > _key(ij, w, M):
        u, w = w, u
    t = (lim - ij[u, axis]) / (ij[w, axis] - ij[u, axis])
    for k in range(2):
        oi[n, k] = ij[u, k] + t * (ij[w, k] - ij[u, k])
    oi[n, axis] = lim
    for k in range(3):
        oxyz[n, k] = xyz[u, k] + t * (xyz[w, k] - xyz[u, k])


@njit(cache=True, nogil=True)
def _classify(faces, F, ij, li, lj, cls):
    """Per face: 0 inside, 1 outside (dropped), 2 crossing (cut); returns how many cut."""
    ncut = 0
    for f in range(F):
        ni = nj = 0
        for k in range(3):
            v = faces[f, k]
            ni += ij[v, 0] > li
            nj += ij[v, 1] > lj
        if ni == 3 or nj == 3:
            cls[f] = 1
        elif ni > 0 or nj > 0:
            cls[f] = 2
            ncut += 1
        else:
            cls[f] = 0
    return ncut


@njit(cache=True, nogil=True)
def _polygon(f, faces, ij, xyz, li, lj, M, made, next_id, room, nnew):
    """Face f cut by i ≤ li then j ≤ lj (Sutherland–Hodgman); the polygon's corners go to
    ``room.pid`` (a vertex id, or −1 − the id of a cut point) and ``room.pc`` (grid
    indices), row ``cur``. A cut point new to ``made`` gets id ``next_id + nnew`` and its
    place in ``room.oi``, ``oxyz``, ``okey`` row ``nnew``. Returns (corners, cur, nnew)."""
    oi, oxyz, okey, pid, pu, pw, pc = room
    lim = (li, lj)
    n = 3
    for k in range(3):
        v = faces[f, k]
        pid[0, k], pu[0, k], pw[0, k] = v, v, v
        pc[0, k, 0], pc[0, k, 1] = ij[v, 0], ij[v, 1]
    cur = 0
    for axis in range(2):
        L = lim[axis]
        m = 0
        nxt = 1 - cur
        for k in range(n):
            q = (k + 1) % n
            ain = pc[cur, k, axis] <= L
            bin_ = pc[cur, q, axis] <= L
            if ain:
                pid[nxt, m], pu[nxt, m], pw[nxt, m] = pid[cur, k], pu[cur, k], pw[cur, k]
                pc[nxt, m, 0], pc[nxt, m, 1] = pc[cur, k, 0], pc[cur, k, 1]
                m += 1
            # a strict crossing makes a point (an end on the line is that point)
            if ain != bin_ and pc[cur, k, axis] != L and pc[cur, q, axis] != L:
                a_orig = pu[cur, k] == pw[cur, k] and pu[cur, k] >= 0
                b_orig = pu[cur, q] == pw[cur, q] and pu[cur, q] >= 0
                if a_orig and b_orig:
                    u, w = pu[cur, k], pu[cur, q]
                elif a_orig or b_orig:
                    o = q if a_orig else k  # the cut point
                    v = pu[cur, k] if a_orig else pu[cur, q]
                    u, w = pu[cur, o], pw[cur, o]
                    if v != u and v != w:  # v on the first cut line, as the point
                        u, w = -1, -1
                else:  # both on the first cut line: the rectangle's corner
                    u, w = -1, -1
                if u < 0:
                    key = np.int64(-1)
                else:
                    ku, kw = _key(ij, u, M), _key(ij, w, M)
                    key = (min(ku, kw) * M + max(ku, kw)) * 2 + axis
                if u >= 0:  # its place (again, if made before: the same bits)
                    _cut(ij, xyz, u, w, axis, L, oi, oxyz, nnew, M)
                else:  # barycentric in the face of the corner (li, lj)
                    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
                    d = ((ij[b, 0] - ij[a, 0]) * (ij[c, 1] - ij[a, 1])
                         - (ij[c, 0] - ij[a, 0]) * (ij[b, 1] - ij[a, 1]))
                    wb = ((li - ij[a, 0]) * (ij[c, 1] - ij[a, 1])
                          - (ij[c, 0] - ij[a, 0]) * (lj - ij[a, 1])) / d
                    wc = ((ij[b, 0] - ij[a, 0]) * (lj - ij[a, 1])
                          - (li - ij[a, 0]) * (ij[b, 1] - ij[a, 1])) / d
                    wa = 1.0 - wb - wc
                    oi[nnew, 0], oi[nnew, 1] = li, lj
                    for r in range(3):
                        oxyz[nnew, r] = wa * xyz[a, r] + wb * xyz[b, r] + wc * xyz[c, r]
                cp0, cp1 = oi[nnew, 0], oi[nnew, 1]
                if key in made:
                    gid = made[key]
                else:
                    gid = next_id + nnew
                    made[key] = gid
                    okey[nnew] = key
                    nnew += 1
                pid[nxt, m] = -1 - gid
                pu[nxt, m], pw[nxt, m] = u, w
                if u < 0:
                    pu[nxt, m], pw[nxt, m] = -2, -3  # neither an original nor one edge
                pc[nxt, m, 0], pc[nxt, m, 1] = cp0, cp1
                m += 1
        n = m
        cur = nxt
        if n < 3:
            break
    return n, cur, nnew


@njit(cache=True, nogil=True, inline="always")
def _fan_start(n, cur, pc):
    """The corner first in (i, j) order: a fan from it gives the same pieces whichever
    corner the face starts at (a streamed mesh meets its faces rotated)."""
    k0 = 0
    for k in range(1, n):
        if pc[cur, k, 0] < pc[cur, k0, 0] or (pc[cur, k, 0] == pc[cur, k0, 0]
                                              and pc[cur, k, 1] < pc[cur, k0, 1]):
            k0 = k
    return k0


@njit(cache=True, nogil=True, inline="always")
def _piece(n, cur, pc, k0, k):
    """Fan piece k (corners k0, k0 + k, k0 + k + 1 mod n), or (−1, −1) without area."""
    p1, p2 = (k0 + k) % n, (k0 + k + 1) % n
    ar = ((pc[cur, p1, 0] - pc[cur, k0, 0]) * (pc[cur, p2, 1] - pc[cur, k0, 1])
          - (pc[cur, p2, 0] - pc[cur, k0, 0]) * (pc[cur, p1, 1] - pc[cur, k0, 1]))
    if abs(ar) <= 1e-9:
        return -1, -1
    return p1, p2


@njit(cache=True, nogil=True)
def _room(ncut):
    """A :class:`ClipRoom` for ``ncut`` cut faces: cut points (up to 5 a face, 1 spare)
    and the two polygons of :func:`_polygon`."""
    return ClipRoom(np.empty((5 * ncut + 1, 2)), np.empty((5 * ncut + 1, 3)),
                    np.empty(5 * ncut + 1, np.int64), np.empty((2, 6), np.int64),
                    np.empty((2, 6), np.int64), np.empty((2, 6), np.int64),
                    np.empty((2, 6, 2)))


@njit(cache=True, nogil=True)
def clip_kernel(faces, ij, xyz, li, lj, M, made, next_id):
    """Clip ``faces`` (vertex ids into ``ij``, ``xyz``; grid vertices of a grid with
    row length ``M``) to i ≤ li, j ≤ lj.

    ``made``: cut key → vertex id, kept from call to call by a streamed mesh; new cut
    points get ids from ``next_id`` on. Returns the faces (a vertex id, or −1 − the id
    of a cut point), the source face of each, and the new cut points' grid indices,
    positions (ids ``next_id`` …) and keys."""
    F = faces.shape[0]
    cls = np.empty(F, np.uint8)
    ncut = _classify(faces, F, ij, li, lj, cls)
    out = np.empty((F + 2 * ncut, 3), np.int64)
    src = np.empty(F + 2 * ncut, np.int64)  # the face each output face comes from
    room = _room(ncut)
    oi, oxyz, okey, pid, pu, pw, pc = room
    nnew = 0
    nf = 0
    for f in range(F):
        if cls[f] == 0:
            out[nf] = faces[f]
            src[nf] = f
            nf += 1
        elif cls[f] == 2:
            n, cur, nnew = _polygon(f, faces, ij, xyz, li, lj, M, made, next_id, room, nnew)
            k0 = _fan_start(n, cur, pc)
            for k in range(1, n - 1):
                p1, p2 = _piece(n, cur, pc, k0, k)
                if p1 >= 0:
                    out[nf, 0], out[nf, 1], out[nf, 2] = pid[cur, k0], pid[cur, p1], pid[cur, p2]
                    src[nf] = f
                    nf += 1
    return out[:nf], src[:nf], oi[:nnew], oxyz[:nnew], okey[:nnew]


@njit(cache=True, nogil=True)
def clip_in_place(faces, level, F, ij, xyz, V, li, lj, M):
    """:func:`clip_kernel` on a whole mesh in place, touching only the faces and
    vertices at the border: faces[:F] (with ``level``) and vertices ij/xyz[:V], the
    arrays having room for the cut points (rows + cols + 1 at most: bintree edges cut a
    grid line at whole samples) and the extra pieces. A cut face keeps its first piece
    in its row; rows left empty take the extra pieces, then the last faces; vertex rows
    beyond the rectangle (used by no piece) take the cut points, then the last vertices.
    Returns the new F and V.

    Examples
    --------
    >>> faces = np.zeros((6, 3), np.int32); faces[0] = (0, 2, 1)  # room for 5 more
    >>> ij = np.zeros((8, 2)); ij[:3] = [[0, 0], [0, 2], [2, 0]]
    >>> xyz = np.zeros((8, 3)); xyz[:3] = np.c_[ij[:3], ij[:3, 0]]
    >>> F, V = clip_in_place(faces, np.zeros(6, np.int16), 1, ij, xyz, 3, 1.0, 1.0, 3)
    >>> F, sorted(map(tuple, ij[:V].tolist()))  # the unit square's two halves
    (2, [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)])
    """
    cls = np.empty(F, np.uint8)
    ncut = _classify(faces, F, ij, li, lj, cls)
    if ncut == 0 and not (cls == 1).any():
        return F, V
    made = Dict.empty(key_type=types.int64, value_type=types.int64)
    room = _room(ncut)
    oi, oxyz, okey, pid, pu, pw, pc = room
    extra = np.empty((2 * ncut + 1, 3), np.int64)
    extra_lv = np.empty(2 * ncut + 1, level.dtype)
    holes = np.empty(F, np.int64)  # face rows to fill (only the first few are used)
    nh = 0
    ne = 0
    nnew = 0
    for f in range(F):
        if cls[f] == 1:
            holes[nh] = f
            nh += 1
        elif cls[f] == 2:
            n, cur, nnew = _polygon(f, faces, ij, xyz, li, lj, M, made, V, room, nnew)
            k0 = _fan_start(n, cur, pc)
            first = True
            for k in range(1, n - 1):
                p1, p2 = _piece(n, cur, pc, k0, k)
                if p1 < 0:
                    continue
                if first:
                    faces[f, 0], faces[f, 1], faces[f, 2] = pid[cur, k0], pid[cur, p1], pid[cur, p2]
                    first = False
                else:
                    extra[ne, 0], extra[ne, 1], extra[ne, 2] = (pid[cur, k0], pid[cur, p1],
                                                                pid[cur, p2])
                    extra_lv[ne] = level[f]
                    ne += 1
            if first:
                holes[nh] = f
                nh += 1
    # cut points: into the rows of vertices beyond the rectangle, then after V
    vout = np.empty(V, np.int64)
    no = 0
    for v in range(V):
        if ij[v, 0] > li or ij[v, 1] > lj:
            vout[no] = v
            no += 1
    # a point cut by the first line and off the second is made but not in any piece
    used = np.zeros(nnew, np.bool_)
    for f in range(F):
        if cls[f] == 2:
            for k in range(3):
                if faces[f, k] < 0:
                    used[-1 - faces[f, k] - V] = True
    for e in range(ne):
        for k in range(3):
            if extra[e, k] < 0:
                used[-1 - extra[e, k] - V] = True
    nuse = 0
    for n in range(nnew):
        nuse += used[n]
    if (V + max(0, nuse - no) > min(ij.shape[0], xyz.shape[0])
            or F + ne - nh > min(faces.shape[0], level.shape[0])):
        raise ValueError("clip_in_place: no room for the cut points or pieces")
    slot = np.empty(nnew, np.int64)  # cut point (V + n) → its row
    nu = 0
    for n in range(nnew):
        if not used[n]:
            continue
        slot[n] = vout[nu] if nu < no else V + (nu - no)
        r = slot[n]
        ij[r, 0], ij[r, 1] = oi[n, 0], oi[n, 1]
        xyz[r, 0], xyz[r, 1], xyz[r, 2] = oxyz[n, 0], oxyz[n, 1], oxyz[n, 2]
        nu += 1
    Vn = V + max(0, nu - no)
    nnew = nu  # the rows of vout taken
    # cut ids (−1 − (V + n)) → rows, in the cut faces and the extra pieces
    for f in range(F):
        if cls[f] == 2:
            for k in range(3):
                if faces[f, k] < 0:
                    faces[f, k] = slot[-1 - faces[f, k] - V]
    for e in range(ne):
        for k in range(3):
            if extra[e, k] < 0:
                extra[e, k] = slot[-1 - extra[e, k] - V]
    # face rows: holes take the extra pieces, then the last faces; or pieces go after F
    Fn = F
    h = 0
    for e in range(ne):
        if h < nh:
            r = holes[h]
            h += 1
        else:
            r = Fn
            Fn += 1
        faces[r, 0], faces[r, 1], faces[r, 2] = extra[e, 0], extra[e, 1], extra[e, 2]
        level[r] = extra_lv[e]
    while h < nh:  # more holes than pieces: move the last faces down
        r = holes[nh - 1]
        if r == Fn - 1:  # the last row is itself a hole
            nh -= 1
            Fn -= 1
            continue
        faces[holes[h], 0], faces[holes[h], 1], faces[holes[h], 2] = (
            faces[Fn - 1, 0], faces[Fn - 1, 1], faces[Fn - 1, 2])
        level[holes[h]] = level[Fn - 1]
        Fn -= 1
        h += 1
    # vertex rows beyond the rectangle left over: the last vertices move into them
    if no > nnew:
        moved = Dict.empty(key_type=types.int64, value_type=types.int64)
        end = Vn  # rows [0, end) are kept
        for q in range(nnew, no):
            r = vout[q]
            while end > 0 and (ij[end - 1, 0] > li or ij[end - 1, 1] > lj):
                end -= 1  # a row beyond the rectangle at the end: dropped as it is
            if r >= end:
                break
            end -= 1
            ij[r, 0], ij[r, 1] = ij[end, 0], ij[end, 1]
            xyz[r, 0], xyz[r, 1], xyz[r, 2] = xyz[end, 0], xyz[end, 1], xyz[end, 2]
            moved[end] = r
        Vn = end
        if len(moved):
            for f in range(Fn):
                for k in range(3):
                    v = faces[f, k]
                    if v >= Vn and v in moved:
                        faces[f, k] = moved[v]
    return Fn, Vn


def new_cuts():
    """An empty cut-point table for :func:`clip_kernel` (key → vertex id)."""
    return Dict.empty(key_type=types.int64, value_type=types.int64)

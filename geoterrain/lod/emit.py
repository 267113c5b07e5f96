"""Emitting a frame's mesh (numba): the walk that numbers and gathers vertices in one
pass, and the culling of invalid or outside triangles, in place or into new arrays.

Seed 002's bisection walk (:func:`geoterrain.lod.kernels.walk_leaves`) gives the leaf
triangles; here each vertex is numbered as it is first met, its position read from its
pooled tile (:func:`geoterrain.lod.kernels.sample_xy`), and the triangles with an
invalid corner or entirely outside one frustum plane are dropped.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.lod.kernels import _coarsest_tile, sample_xy, walk_leaves


@njit(cache=True, nogil=True)
def _corner_bits(xyz, planes, eye, slack):
    """Per vertex: bit 6 = invalid (z not finite), bit k = outside plane k by more than
    ``slack``·|c_k|·d (d the vertex's distance to ``eye``).

    A triangle is dropped when its three corners are outside one plane. The samples
    under it lie within |Δz| ≤ (τ/λ)·d of its surface (ρ ≤ τ), and the plane value moves
    by at most |c_k|·|Δz| for a vertical shift, while d is convex (a point of the
    triangle is no farther than its farthest corner). So with ``slack`` ≥ τ/(λ − τ) no
    sample inside the frustum lies under a dropped triangle. ``slack`` = 0: the plain
    test."""
    V, P = xyz.shape[0], planes.shape[0]
    bits = np.zeros(V, np.uint8)
    for v in range(V):
        x, y, z = xyz[v, 0], xyz[v, 1], xyz[v, 2]
        b = 0
        if not np.isfinite(z):
            b = 64
            z = 0.0
        m = 0.0
        if slack > 0.0 and P > 0:
            dx, dy, dz = x - eye[0], y - eye[1], z - eye[2]
            m = slack * np.sqrt(dx * dx + dy * dy + dz * dz)
        for k in range(P):
            if planes[k, 0] * x + planes[k, 1] * y + planes[k, 2] * z + planes[k, 3] \
                    < -m * abs(planes[k, 2]):
                b |= 1 << k
        bits[v] = b
    return bits


@njit(cache=True, nogil=True)
def _face_levels(faces, lvl):
    out = np.empty(faces.shape[0], np.int16)
    for f in range(faces.shape[0]):
        out[f] = min(lvl[faces[f, 0]], lvl[faces[f, 1]], lvl[faces[f, 2]])
    return out


@njit(cache=True, nogil=True)
def _any(bits):
    for v in range(bits.shape[0]):
        if bits[v] != 0:
            return True
    return False


@njit(cache=True, nogil=True)
def cull_compact(faces, xyz, planes, lvl, eye, slack):
    """Drop triangles with an invalid corner (z NaN) or entirely outside one frustum
    plane (``planes`` (P, 4), P = 0 for none; by the margin of :func:`_corner_bits`);
    renumber the vertices left in order.

    Returns the kept faces (renumbered), the kept vertices' indices (None when every
    vertex is kept: nothing was dropped) and each kept triangle's level (the
    coarsest level shared by its corners: min of ``lvl``).
    """
    V, F = xyz.shape[0], faces.shape[0]
    bits = _corner_bits(xyz, planes, eye, slack)
    if not _any(bits):
        return faces, None, _face_levels(faces, lvl)
    keep = np.zeros(F, np.bool_)
    used = np.zeros(V, np.bool_)
    nf = 0
    for f in range(F):
        b0, b1, b2 = bits[faces[f, 0]], bits[faces[f, 1]], bits[faces[f, 2]]
        if ((b0 | b1 | b2) & 64) == 0 and (b0 & b1 & b2 & 63) == 0:
            keep[f] = True
            nf += 1
            used[faces[f, 0]] = True
            used[faces[f, 1]] = True
            used[faces[f, 2]] = True
    remap = np.full(V, -1, np.int32)
    nv = 0
    for v in range(V):
        if used[v]:
            remap[v] = nv
            nv += 1
    vid = np.empty(nv, np.int64)
    for v in range(V):
        if used[v]:
            vid[remap[v]] = v
    out = np.empty((nf, 3), faces.dtype)
    level = np.empty(nf, np.int16)
    n = 0
    for f in range(F):
        if keep[f]:
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            out[n, 0], out[n, 1], out[n, 2] = remap[a], remap[b], remap[c]
            level[n] = min(lvl[a], lvl[b], lvl[c])
            n += 1
    return out, vid, level



_HASH_MUL = np.uint64(0x9E3779B97F4A7C15)  # Fibonacci hashing of sample indices


@njit(cache=True, nogil=True, inline="always")
def _slot(keys, idx):
    """Open-addressing slot of ``idx`` in the power-of-two table ``keys`` (−1: empty)."""
    M = keys.shape[0]
    h = np.int64((np.uint64(idx) * _HASH_MUL) >> np.uint64(40)) & (M - 1)
    while keys[h] != -1 and keys[h] != idx:
        h = (h + 1) & (M - 1)
    return h


@njit(cache=True, nogil=True)
def walk_gather(flags, stack, state, vid, keys, slabs, faces, verts, xyz, ij, lvl):
    """:func:`_walk` over the active set ``flags`` (:class:`~geoterrain.lod.kernels.ActiveFlags`)
    with the gather of :func:`gather_pooled` (from the pool's ``slabs``,
    :class:`~geoterrain.lod.pool.PoolSlabs`) done as each vertex is first numbered, so
    the mesh is emitted in one pass: faces to ``faces``, and per vertex its sample index,
    position (x, y, height · zfac), grid indices (float64) and pyramid level.

    Vertex numbers live in the dense scratch ``vid`` (N², −1 = none; reset on return)
    or, when ``keys`` is not empty, in a hash table (``keys`` all −1, power-of-two
    length, numbers in ``vid[:len(keys)]``): a view's few thousand vertices then stay in
    cache instead of being spread over the N² scratch.
    Returns (faces, vertices, status): status 0 done, 1 an output array or the table is
    full, 2 a vertex lies in a tile that is not pooled."""
    active, mixed, gen = flags.active, flags.mixed, flags.gen
    top, t, base, slot_of = slabs.top, slabs.t, slabs.base, slabs.slot_of
    H, X, Y, aff, zfac = slabs.H, slabs.X, slabs.Y, slabs.aff, slabs.zfac
    cap, capv = faces.shape[0], xyz.shape[0]
    hashed = keys.shape[0] > 0
    if hashed:
        capv = min(capv, keys.shape[0] // 2)  # keep probes short: at most half full
    N = active.shape[1]  # the row stride (a root grid's extent is wider than tall)
    buf = np.empty((4096, 3), np.int64)  # leaves pass through a cache-sized buffer
    nf, nv, status = 0, 0, 0
    while status == 0:
        n = walk_leaves(active, mixed, gen, stack, state, buf)
        if n == 0:
            break
        if nf + n > cap:
            status = 1
            break
        for f in range(n):
            for k in range(3):
                idx = buf[f, k]
                if hashed:
                    h = _slot(keys, idx)
                    v = vid[h] if keys[h] == idx else -1
                else:
                    v = vid[idx]
                if v < 0:
                    if nv >= capv:
                        status = 1
                        break
                    i, j = idx // N, idx % N
                    L, ti, a, b = _coarsest_tile(i, j, top, t, base)
                    s = slot_of[ti] if ti >= 0 else -1
                    if s < 0:
                        status = 2
                        break
                    v = nv
                    if hashed:
                        keys[h] = idx
                        vid[h] = nv
                    else:
                        vid[idx] = nv
                    verts[nv] = idx
                    x, y = sample_xy(X, Y, aff, s, a, b, i, j)
                    xyz[v, 0], xyz[v, 1], xyz[v, 2] = x, y, H[s, a, b] * zfac
                    ij[v, 0], ij[v, 1] = i, j
                    lvl[v] = L
                    nv += 1
                faces[nf + f, k] = v
            if status != 0:
                break
        nf += n
    if not hashed:
        for k in range(nv):
            vid[verts[k]] = -1
    return nf, nv, status


@njit(cache=True, nogil=True)
def cull_in_place(faces, xyz, ij, planes, lvl, eye, slack):
    """:func:`cull_compact` without copies: the kept faces (renumbered) and vertices
    move to the front of ``faces``, ``xyz`` and ``ij`` (a kept item never moves back,
    so one forward pass is safe). Returns (faces kept, vertices kept, face levels)."""
    V, F = xyz.shape[0], faces.shape[0]
    bits = _corner_bits(xyz, planes, eye, slack)
    if not _any(bits):
        return F, V, _face_levels(faces, lvl)
    remap = np.full(V, -1, np.int32)
    level = np.empty(F, np.int16)
    nf = 0
    for f in range(F):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        b0, b1, b2 = bits[a], bits[b], bits[c]
        if ((b0 | b1 | b2) & 64) == 0 and (b0 & b1 & b2 & 63) == 0:
            remap[a] = 0
            remap[b] = 0
            remap[c] = 0
            faces[nf, 0], faces[nf, 1], faces[nf, 2] = a, b, c
            level[nf] = min(lvl[a], lvl[b], lvl[c])
            nf += 1
    nv = 0
    for v in range(V):
        if remap[v] == 0:
            remap[v] = nv
            xyz[nv, 0], xyz[nv, 1], xyz[nv, 2] = xyz[v, 0], xyz[v, 1], xyz[v, 2]
            ij[nv, 0], ij[nv, 1] = ij[v, 0], ij[v, 1]
            nv += 1
    for f in range(nf):
        faces[f, 0] = remap[faces[f, 0]]
        faces[f, 1] = remap[faces[f, 1]]
        faces[f, 2] = remap[faces[f, 2]]
    return nf, nv, level[:nf]

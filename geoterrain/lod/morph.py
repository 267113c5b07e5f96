"""Geomorphing of the rtin mesh (seed 002 §2.10, eq. 3–4): no vertex pops in or out.

A tolerance band (τ_min, τ_max) replaces τ. A vertex becomes active at ρ > τ_min
(LP eq. 2 with τ_min) and reaches its true height at ρ ≥ τ_max:

- eq. 3: t = (ρ − τ_min) / (τ_max − τ_min), clipped to [0, 1], with ρ = λδ/(d − r)
  as the selection computes it (ρ = ∞ inside the sphere, and for a mixed diamond);
- eq. 4: z = t·z_true + (1 − t)·(z_a + z_b)/2, where a and b end the bintree edge the
  vertex splits, at their *morphed* heights (seed 002's cascade, with the corrected
  argument order of ``RefinaSubMalhaMorph``).

Vertices are processed coarse to fine, each once, so a vertex has one height however
many triangles use it (no crack while morphing), and a vertex that appears (t = 0)
lies on the edge it splits (no pop). Choice: the seed's eq. 8 (squared distances) and
eq. 3 agree only at the ends; eq. 3 on the selection's own ρ is used, so t grows with
ρ and, as nested spheres and saturated δ make ρ monotone up the bintree, a vertex's t
never exceeds its parent's (seed 002's T18, and more).

With τ_max = τ the drawn surface keeps measured ρ ≤ τ (tested): a morphing vertex's
surface is a blend of the coarser one (error ≤ ρ_v < τ) and the finer one. The cost is
the triangles of activating at τ_min = ``MORPH_START`` · τ.

Examples
--------
>>> edge_ends(2, 2, 5)  # the centre of a 5 × 5 grid splits the main diagonal
((0, 0), (4, 4))
>>> edge_ends(0, 2, 5)  # the middle of the top edge splits it
((0, 0), (0, 4))
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.lod.kernels import _coarsest_tile

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["MORPH_START", "edge_ends", "morph_heights", "morph_mesh"]

_MUL = np.uint64(0x9E3779B97F4A7C15)
MORPH_START = 0.75  # τ_min = MORPH_START · τ: vertices appear at 3/4 of the tolerance


@njit(cache=True, nogil=True, inline="always")
def _ends(i, j, S):
    """The bintree edge sample (i, j) splits: its two end points, or (−1, …) for a
    domain corner (which splits nothing): a corner of the square of side ``S`` = N − 1,
    or of a root of that side (a root grid)."""
    low = i | j
    if low == 0 or (i % S == 0 and j % S == 0):
        return -1, -1, -1, -1
    k = 0
    while (low & 1) == 0:
        low >>= 1
        k += 1
    s = 1 << k
    if (i >> k) & 1 and (j >> k) & 1:  # a diagonal: the union-jack rule at stride 2s
        A, B = (i - s) >> (k + 1), (j - s) >> (k + 1)
        if (A & 1) == (B & 1):
            return i - s, j - s, i + s, j + s
        return i - s, j + s, i + s, j - s
    if (i >> k) & 1:
        return i - s, j, i + s, j
    return i, j - s, i, j + s


def edge_ends(i: int, j: int, N: int) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """The two ends of the bintree edge that sample (i, j) of an N × N grid splits
    (None for a domain corner)."""
    a, b, c, d = _ends(i, j, N - 1)
    return None if a < 0 else ((a, b), (c, d))


@njit(cache=True, nogil=True)
def _depth_k(i, j):
    low = i | j
    if low == 0:
        return 63
    k = 0
    while (low & 1) == 0:
        low >>= 1
        k += 1
    return k


@njit(cache=True, nogil=True, inline="always")
def _lookup(keys, vals, key, shift, M):
    h = np.int64((np.uint64(key) * _MUL) >> shift)
    while keys[h] != -1 and keys[h] != key:
        h = (h + 1) & (M - 1)
    return vals[h] if keys[h] == key else -1


@njit(cache=True, nogil=True, inline="always")
def _true_z(key, N, top, t, base, slot_of, H, zfac):
    L, ti, a, b = _coarsest_tile(key // N, key % N, top, t, base)
    s = slot_of[ti] if ti >= 0 else -1
    return H[s, a, b] * zfac if s >= 0 else np.nan


@njit(cache=True, nogil=True)
def morph_heights(verts, xyz, N, slabs, eye, axis, lam, tmin, tmax, tout, span):
    """Morph ``xyz[:, 2]`` in place (eq. 3–4) for mesh vertices ``verts`` (flat i·N + j;
    ``span`` the side of the square, N − 1, or of a root grid's roots);
    ``tout`` receives each vertex's t; ρ = λδ/(d − r), or with the eye plane ``axis``
    (4,) (f, −f·eye) ρ = λδ/(z − r − δ), z the depth: the picture's bound that
    :meth:`~geoterrain.core.view.View.terms` selects with (``lam`` then λk, without
    τ). δ, r and the ends' true heights are read from the
    pooled tiles (``slabs``: :class:`~geoterrain.lod.pool.PoolSlabs`, its ``D``, ``R``,
    ``H`` × ``zfac``) as the selection read them.

    Only vertices with t < 1 move; the end of an edge is either one of them (already
    moved: they are processed coarse first) or at its true height."""
    top, t, base, slot_of = slabs.top, slabs.t, slabs.base, slabs.slot_of
    D, R, H, zfac = slabs.D, slabs.R, slabs.H, slabs.zfac
    nv = verts.shape[0]
    moving = np.empty(nv, np.int64)
    nm = 0
    for v in range(nv):  # eq. 3, every vertex
        tout[v] = 1.0
        z = xyz[v, 2]
        if not z == z:
            continue
        i, j = verts[v] // N, verts[v] % N
        if _ends(i, j, span)[0] < 0:
            continue
        L, ti, a, b = _coarsest_tile(i, j, top, t, base)
        s = slot_of[ti] if ti >= 0 else -1
        if s < 0:
            continue
        dl = np.float64(D[s, a, b])
        if dl == np.inf:
            continue
        r = np.float64(R[s, a, b])
        if axis.shape[0] == 4:  # the nearest depth of the sphere and of the drawn point
            d = axis[0] * xyz[v, 0] + axis[1] * xyz[v, 1] + axis[2] * z + axis[3] - dl
        else:
            dx, dy, dz = xyz[v, 0] - eye[0], xyz[v, 1] - eye[1], z - eye[2]
            d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d <= r:
            continue
        tt = (lam * dl / (d - r) - tmin) / (tmax - tmin)
        if tt < 1.0:
            tout[v] = max(tt, 0.0)
            moving[nm] = v
            nm += 1
    if nm == 0:
        return
    M, bits = 1, 0
    while M < 2 * nm + 2:
        M <<= 1
        bits += 1
    shift = np.uint64(64 - max(bits, 1))
    keys = np.full(M, -1, np.int64)  # the moving vertices by sample (Fibonacci hashing)
    vals = np.empty(M, np.int64)
    count = np.zeros(65, np.int64)
    depth = np.empty(nm, np.int64)
    for q in range(nm):
        v = moving[q]
        h = np.int64((np.uint64(verts[v]) * _MUL) >> shift)
        while keys[h] != -1:
            h = (h + 1) & (M - 1)
        keys[h] = verts[v]
        vals[h] = v
        depth[q] = _depth_k(verts[v] // N, verts[v] % N)
        count[64 - depth[q]] += 1
    start = np.zeros(65, np.int64)  # coarse first: a counting sort on the bintree depth
    for k in range(1, 65):
        start[k] = start[k - 1] + count[k - 1]
    order = np.empty(nm, np.int64)
    for q in range(nm):
        c = 64 - depth[q]
        order[start[c]] = moving[q]
        start[c] += 1
    for q in range(nm):  # eq. 4 with the cascade
        v = order[q]
        i, j = verts[v] // N, verts[v] % N
        ai, aj, bi, bj = _ends(i, j, span)
        ka, kb = ai * N + aj, bi * N + bj
        u = _lookup(keys, vals, ka, shift, M)
        za = xyz[u, 2] if u >= 0 else _true_z(ka, N, top, t, base, slot_of, H, zfac)
        u = _lookup(keys, vals, kb, shift, M)
        zb = xyz[u, 2] if u >= 0 else _true_z(kb, N, top, t, base, slot_of, H, zfac)
        target = 0.5 * (za + zb)
        if not np.isfinite(target):  # an end is nodata: no morph
            tout[v] = 1.0
            continue
        tt = tout[v]
        xyz[v, 2] = tt * xyz[v, 2] + (1.0 - tt) * target


def morph_mesh(terrain: TerrainLike, verts: np.ndarray, xyz: np.ndarray, view, tmin: float,
               tmax: float, depth: bool = True
               ) -> np.ndarray:
    """Morph the heights ``xyz[:, 2]`` of an rtin mesh's vertices ``verts`` in place, for
    ``view`` and the band (``tmin``, ``tmax``); returns each vertex's t. ``depth``: the
    selection's metric (:data:`geoterrain.lod.rtin.DEPTH`: the picture's bound, else LP's
    distance), so t follows the same ρ that selected the mesh."""
    from geoterrain.lod.kernels import mark_tiles
    from geoterrain.lod.pool import tile_pool

    pool = tile_pool(terrain)
    occ = np.zeros(len(pool.slot_of), bool)
    mark_tiles(verts, pool.N, pool.top, pool.t, pool.kbase, occ)
    pool.slots(np.flatnonzero(occ), ("delta", "radius", "height"))
    tout = np.ones(len(verts))
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    vt = view.terms(tmax, depth=depth)  # the selection's metric (lam − τ: λk)
    morph_heights(verts, xyz, pool.N, pool.slabs(zfac), view.eye, vt.axis,
                  vt.lam - vt.tau if depth else vt.lam, float(tmin), float(tmax), tout,
                  np.int64(1) << terrain.grid.n)
    return tout

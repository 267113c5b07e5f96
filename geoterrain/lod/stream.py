"""The static mesh in chunks: bounded memory for meshes larger than RAM would allow.

:func:`geoterrain.lod.static` builds the whole mesh (every vertex with δ > e) as one
``PolyData``; at 4097² and e = 0.1 that is tens of millions of triangles and
several GB. Here the same mesh comes out chunk by chunk (:func:`static_chunks`):

1. **Active set.** The dense flags of :func:`geoterrain.lod.rtin.static_active`
   (δ > e, δ = inf marks a mixed diamond, then the upward closure), but the δ
   tiles are read through a private :class:`~geoterrain.lod.pool.TilePool` with a
   byte budget, a batch of tiles at a time, so the whole pyramid's δ never sits
   in memory at once.
2. **Bisection, resumable.** The depth-first longest-edge bisection of
   :func:`geoterrain.lod.kernels.walk_leaves` (the walk `extract` uses, seed 002)
   stops after ``chunk`` leaf triangles and resumes where it stopped.
3. **Numbering.** A triangle with an invalid corner (no height) is dropped, as
   :func:`geoterrain.lod.emit.cull_compact` does; the corners of the triangles
   kept get global vertex ids in order of first appearance (one int32 map over the
   N² samples). Each chunk hands back its new vertices (positions gathered through
   the pool) and its faces in global ids, so a writer can stream both to disk.

Memory: two N² bool flags, one N² int32 map, the pool's budget and one chunk;
independent of the mesh's size. The triangles are those of the in-memory static
mesh (the vertex order may differ where a vertex is first used by a dropped
triangle); ``tests/test_meshstream.py`` checks it.

Examples
--------
>>> chunks = list(static_chunks(t, 5.0, chunk=500))
>>> sum(len(c.faces) for c in chunks) == t.static_selection(5.0).stats["triangles"]
True
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numba import njit

from geoterrain.lod.kernels import fill_static, gather_pooled, mark_tiles, walk_leaves, walk_start
from geoterrain.lod.pool import TilePool
from geoterrain.lod.rtin import ActiveSet
from geoterrain.lod.tiles import tile_index

CHUNK = 1 << 20  # leaf triangles per chunk
POOL_BYTES = 192 << 20  # the private tile pool's budget (heights, x, y; δ while flagging)
_INVALID = np.int32(-(2 ** 31))  # vertex map: a sample seen without a valid height


@dataclass
class MeshChunk:
    """One chunk of a streamed mesh.

    ``first``: global id of the first new vertex; ``xyz`` (n, 3) float64 scene
    positions and ``ij`` (n, 2) grid row/column of the vertices new in this chunk
    (ids ``first … first + n − 1``); ``faces`` (F, 3) int64 global vertex ids,
    counter-clockwise seen from above; ``done``/``total``: leaf triangles walked
    so far and in all (for progress).
    """

    first: int
    xyz: np.ndarray
    ij: np.ndarray
    faces: np.ndarray
    done: int
    total: int


def _count_leaves(active, mixed) -> int:
    """Leaf triangles of the whole walk (for progress), without storing them."""
    stack, state = walk_start(active.shape[0])
    buf = np.empty((4096, 3), np.int64)
    n = 0
    while True:
        k = walk_leaves(active, mixed, True, stack, state, buf)
        if k == 0:
            return n
        n += k


@njit(cache=True, nogil=True)
def _new_samples(tris, vid, cand):
    """Samples of ``tris`` never seen before (vid = −1), in order of first appearance:
    written to ``cand``, and marked in ``vid`` with −2 − (their index in ``cand``)."""
    k = 0
    for f in range(tris.shape[0]):
        for c in range(3):
            s = tris[f, c]
            if vid[s] == -1:
                vid[s] = -2 - k
                cand[k] = s
                k += 1
    return k


@njit(cache=True, nogil=True)
def _number(tris, vid, valid, cand, nv, faces, order):
    """Keep the triangles whose corners all have a height; give their new corners global
    ids from ``nv`` on, in order of first appearance.

    ``valid[k]``: candidate k (``vid`` = −2 − k) has a height. Kept faces go to
    ``faces`` (global ids), the candidate index of each new vertex to ``order``.
    Candidates left unused get back −1 (valid: a later chunk may use them) or the
    invalid mark. Returns (faces kept, vertices new).
    """
    nf, nn = 0, 0
    for f in range(tris.shape[0]):
        ok = True
        for c in range(3):
            v = vid[tris[f, c]]
            if v == _INVALID or (v <= -2 and not valid[-2 - v]):
                ok = False
        if not ok:
            continue
        for c in range(3):
            s = tris[f, c]
            v = vid[s]
            if v <= -2 and v != _INVALID:
                order[nn] = -2 - v
                v = nv + nn
                vid[s] = v
                nn += 1
            faces[nf, c] = v
        nf += 1
    for k in range(cand.shape[0]):
        s = cand[k]
        if vid[s] <= -2 and vid[s] != _INVALID:
            vid[s] = -1 if valid[k] else _INVALID
    return nf, nn


def static_flags(terrain, max_error: float, pool: TilePool) -> ActiveSet:
    """:func:`geoterrain.lod.rtin.static_active` with δ read through ``pool`` in batches
    that fit its budget (the same flags, bounded memory).

    Examples
    --------
    >>> from geoterrain.lod.rtin import static_active
    >>> a = static_flags(t, 2.0, TilePool(t, 1 << 20))
    >>> b = static_active(t, tile_index(t), 2.0)
    >>> bool((a.active == b.active).all() and (a.mixed == b.mixed).all())
    True
    """
    index = tile_index(terrain)
    act = ActiveSet(terrain)
    rows = np.flatnonzero(index.delta_max > max_error)
    batch = max(1, pool.budget_slots // 2)
    for k in range(0, len(rows), batch):
        idx, i0, j0, step = act.tiles(rows[k:k + batch], index)
        slots = pool.slots(idx, ("delta",))
        fill_static(slots, i0, j0, step, pool.D, float(max_error), act.active, act.mixed)
    return act  # closed already: δ is saturated (see static_active)


def _gather(pool: TilePool, flat: np.ndarray, zfac: float):
    """Scene positions and grid indices of samples ``flat`` through ``pool`` (the
    chunk's tiles only); invalid samples have z NaN."""
    occ = np.zeros(len(pool.slot_of), bool)
    mark_tiles(flat, pool.N, pool.top, pool.t, pool.base, occ)
    pool.slots(np.flatnonzero(occ), ("height", "xy"))
    n = len(flat)
    xyz, ij, lvl = np.empty((n, 3)), np.empty((n, 2), np.int64), np.empty(n, np.int64)
    gather_pooled(flat, pool.N, pool.top, pool.t, pool.base, pool.slot_of, pool.H, pool.X,
                  pool.Y, pool.aff, zfac, xyz, ij, lvl)
    return xyz, ij


def static_chunks(terrain, max_error: float, *, chunk: int = CHUNK,
                  pool_bytes: int = POOL_BYTES, count: bool = True) -> Iterator[MeshChunk]:
    """The static mesh of bound ``max_error`` (every vertex with δ > e), chunk by chunk.

    The union of the chunks is the mesh of :func:`geoterrain.lod.static` (same
    vertices, same triangles, same winding). ``chunk``: leaf triangles walked per
    chunk; ``pool_bytes``: the tile pool's budget; ``count``: count the leaves first
    so that each chunk reports ``total`` (one more walk, no gather).
    """
    if chunk < 1:
        raise ValueError(f"chunk must be ≥ 1, got {chunk}")
    pool = TilePool(terrain, pool_bytes)
    act = static_flags(terrain, float(max_error), pool)
    active, mixed = act.active, act.mixed
    N = active.shape[0]
    total = int(_count_leaves(active, mixed)) if count else 0
    vid = np.full(N * N, -1, np.int32)
    stack, state = walk_start(N)
    tris = np.empty((chunk, 3), np.int64)
    cand = np.empty(3 * chunk, np.int64)
    faces = np.empty((chunk, 3), np.int64)
    order = np.empty(3 * chunk, np.int64)
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    nv, done = 0, 0
    while True:
        n = walk_leaves(active, mixed, True, stack, state, tris)
        if n == 0:
            return
        done += n
        k = _new_samples(tris[:n], vid, cand)
        new = cand[:k]
        pos, gij = _gather(pool, new, zfac)
        valid = np.isfinite(pos[:, 2])
        nf, nn = _number(tris[:n], vid, valid, new, nv, faces, order)
        pick = order[:nn]
        yield MeshChunk(nv, pos[pick], gij[pick], faces[:nf].copy(), done, max(total, done))
        nv += nn

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
triangle); ``tests/export/test_meshstream.py`` checks it.

Examples
--------
>>> chunks = list(static_chunks(t, 5.0, chunk=500))
>>> sum(len(c.faces) for c in chunks) == t.static_selection(5.0).stats["triangles"]
True
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.lod import rtin
from geoterrain.lod.clip import clip_kernel, new_cuts
from geoterrain.lod.kernels import (
    fill_static,
    gather_pooled,
    mark_tiles,
    walk_leaves,
    walk_shape,
    walk_start,
)
from geoterrain.lod.pool import TilePool
from geoterrain.lod.rtin import ActiveSet
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

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


def _as_generation(active: np.ndarray, mixed: np.ndarray) -> tuple:
    """The static flags (bool) as the view's generation flags (uint8, generation 1; the
    same bytes, no copy), so the walk is the one compiled kernel the views use.

    Examples
    --------
    >>> a, m, gen = _as_generation(np.eye(2, dtype=bool), np.zeros((2, 2), bool))
    >>> a.dtype.name, a.tolist(), int(gen)
    ('uint8', [[1, 0], [0, 1]], 1)
    """
    return active.view(np.uint8), mixed.view(np.uint8), np.uint8(1)


def _count_leaves(active, mixed) -> int:
    """Leaf triangles of the whole walk (for progress), without storing them."""
    stack, state = walk_start(*walk_shape(active.shape))  # a square, or every root
    buf = np.empty((4096, 3), np.int64)
    n = 0
    active, mixed, gen = _as_generation(active, mixed)
    while True:
        k = walk_leaves(active, mixed, gen, stack, state, buf)
        if k == 0:
            return n
        n += k


_PROV = np.int64(1) << 50  # provisional ids of a chunk's new cut points
_NO_KEYS = np.zeros(0, np.int64)


@njit(cache=True, nogil=True)
def _new_samples(codes, vid, cand):
    """Samples of ``codes`` (faces' corners: a sample's flat index ≥ 0, or a cut point
    < 0, skipped) never seen before (vid = −1), in order of first appearance: written to
    ``cand``, and marked in ``vid`` with −2 − (their index in ``cand``)."""
    k = 0
    for f in range(codes.shape[0]):
        for c in range(3):
            s = codes[f, c]
            if s >= 0 and vid[s] == -1:
                vid[s] = -2 - k
                cand[k] = s
                k += 1
    return k


@njit(cache=True, nogil=True)
def _number(codes, vid, valid, cand, nv, faces, order, okey, cuts):
    """Keep the faces whose corners all have a height; give their new corners global
    ids from ``nv`` on, in order of first appearance (the walk's order).

    A corner is a sample (≥ 0): ``valid[k]`` says whether candidate k (``vid`` = −2 − k)
    has a height; its candidate index goes to ``order``. Or it is a cut point (−1 − id,
    :mod:`geoterrain.lod.clip`): it keeps its id, or, new in this chunk (id ≥ ``_PROV``,
    provisional, key ``okey[id − _PROV]``), gets the next id at its first use
    (``order``: −1 − its provisional index) and ``cuts`` learns it. Kept faces go to
    ``faces`` (global ids). Candidates left unused get back −1 (valid: a later chunk may
    use them) or the invalid mark. Returns (faces kept, vertices new).
    """
    nf, nn = 0, 0
    final = np.full(okey.shape[0], -1, np.int64)
    for f in range(codes.shape[0]):
        ok = True
        for c in range(3):
            s = codes[f, c]
            if s >= 0:
                v = vid[s]
                if v == _INVALID or (v <= -2 and not valid[-2 - v]):
                    ok = False
        if not ok:
            continue
        for c in range(3):
            s = codes[f, c]
            if s >= 0:
                v = vid[s]
                if v <= -2 and v != _INVALID:
                    order[nn] = -2 - v
                    v = nv + nn
                    vid[s] = v
                    nn += 1
            else:
                g = -1 - s
                if g >= _PROV:
                    n = g - _PROV
                    if final[n] < 0:
                        final[n] = nv + nn
                        order[nn] = -1 - n
                        nn += 1
                    v = final[n]
                else:
                    v = g
            faces[nf, c] = v
        nf += 1
    for k in range(cand.shape[0]):
        s = cand[k]
        if vid[s] <= -2 and vid[s] != _INVALID:
            vid[s] = -1 if valid[k] else _INVALID
    for n in range(okey.shape[0]):
        if final[n] >= 0:
            cuts[okey[n]] = final[n]
        else:  # unused (its pieces had no area): made again where a later face needs it
            cuts.pop(okey[n])
    return nf, nn


def _edge_chunk(tris, pool, zfac, g, vid, nv, cuts):
    """A chunk of a padded store's static mesh (replicated padding, clipped to the data
    as :func:`geoterrain.lod.static` clips it), faces in the walk's order: faces (global
    ids), new vertices' positions and grid indices (ids from ``nv`` on)."""
    N = pool.N
    i, j = tris // N, tris % N
    ni, nj = (i > g.rows - 1).sum(1), (j > g.cols - 1).sum(1)
    inside = (ni == 0) & (nj == 0)
    cross = np.flatnonzero(~inside & (ni < 3) & (nj < 3))
    codes, okey, oi, oxyz = tris[inside], np.zeros(0, np.int64), np.zeros((0, 2)), None
    where = np.flatnonzero(inside)  # each piece's face in the walk's order
    if len(cross):
        flat = np.ascontiguousarray(tris[cross].ravel())
        P, IJ = _gather(pool, flat, zfac, (g.rows, g.cols))
        ok = np.isfinite(P[:, 2]).reshape(-1, 3).all(1)  # a corner without height: dropped
        local = np.arange(len(flat), dtype=np.int64).reshape(-1, 3)[ok]
        out, src, oi, oxyz, okey = clip_kernel(
            local, IJ.astype(np.float64), P, float(g.rows - 1), float(g.cols - 1),
            np.int64(N), cuts, _PROV)
        pieces = np.where(out >= 0, flat[np.maximum(out, 0)], out)  # samples, cut points
        codes = np.concatenate([codes, pieces])
        where = np.concatenate([where, cross[ok][src]])
        # a cut point in ``cuts`` from an earlier chunk keeps its id; one new here has a
        # provisional id until its first use below
    codes = np.ascontiguousarray(codes[np.argsort(where, kind="stable")])
    cand = np.empty(3 * len(codes) + 1, np.int64)
    k = _new_samples(codes, vid, cand)
    new = cand[:k]
    pos, gij = _gather(pool, new, zfac)
    valid = np.isfinite(pos[:, 2])
    faces = np.empty((len(codes), 3), np.int64)
    order = np.empty(3 * len(codes) + 1, np.int64)
    nf, nn = _number(codes, vid, valid, new, nv, faces, order, okey, cuts)
    order = order[:nn]
    corner = order >= 0
    xyz, ij = np.empty((nn, 3)), np.empty((nn, 2))
    xyz[corner], ij[corner] = pos[order[corner]], gij[order[corner]]
    if oxyz is not None:
        xyz[~corner], ij[~corner] = oxyz[-1 - order[~corner]], oi[-1 - order[~corner]]
    return faces[:nf], xyz, ij


def static_flags(terrain: TerrainLike, max_error: float, pool: TilePool,
                 edge: bool = False) -> ActiveSet:
    """:func:`geoterrain.lod.rtin.static_active` with δ read through ``pool`` in batches
    that fit its budget (the same flags, bounded memory); ``edge``: δ_edge, the second δ
    of a padded store (:mod:`geoterrain.bounds.edgepad`), as :func:`geoterrain.lod.static` reads
    it.

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
    keys = rtin.static_keys(terrain, index, pool, float(max_error), edge)
    batch = max(1, pool.budget_slots // 2)
    kind = "delta_edge" if edge else "delta"
    for k in range(0, len(keys), batch):
        some = keys[k:k + batch]
        i0, j0, step = pool.origins(some)
        slots = pool.slots(pool.table_index(some), (kind,))  # may grow the slabs: then read
        fill_static(slots, i0, j0, step, pool.DE if edge else pool.D, float(max_error),
                    act.active, act.mixed)
    # closed already: δ is saturated (see static_active); on a root grid but for parents
    # past a level's last tile, which the walk never needs (lod/leaves.py)
    return act


def _gather(pool: TilePool, flat: np.ndarray, zfac: float, window=None):
    """Scene positions and grid indices of samples ``flat`` through ``pool`` (the
    chunk's tiles only); invalid samples have z NaN. ``window`` (rows, cols): a sample
    beyond it takes the height of the nearest sample of the data's last row or column
    (replicated padding, :mod:`geoterrain.bounds.edgepad`)."""
    N = pool.N
    more = np.zeros(0, np.int64)
    if window is not None:
        i, j = flat // N, flat % N
        pad = (i >= window[0]) | (j >= window[1])
        more = np.minimum(i[pad], window[0] - 1) * N + np.minimum(j[pad], window[1] - 1)
    occ = np.zeros(len(pool.slot_of), bool)
    mark_tiles(np.concatenate([flat, more]), N, pool.top, pool.t, pool.kbase, occ)
    # with "delta_edge", the unstored tiles holding a second δ are served too
    pool.slots(np.flatnonzero(occ), ("height", "xy") if window is None else
               ("delta_edge", "height", "xy"))
    n = len(flat)
    xyz, ij, lvl = np.empty((n, 3)), np.empty((n, 2), np.int64), np.empty(n, np.int64)
    slabs = pool.slabs(zfac)
    gather_pooled(flat, N, slabs, xyz, ij, lvl)
    if len(more):
        rep = np.empty((len(more), 3))
        gather_pooled(more, N, slabs, rep, np.empty((len(more), 2), np.int64),
                      np.empty(len(more), np.int64))
        xyz[pad, 2] = rep[:, 2]
    return xyz, ij


def static_chunks(terrain: TerrainLike, max_error: float, *, chunk: int = CHUNK,
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
    g = terrain.grid
    edge = rtin.edge_padding(terrain)  # replicated padding, clipped (geoterrain.bounds.edgepad)
    cuts = new_cuts()
    act = static_flags(terrain, float(max_error), pool, edge)
    active, mixed = act.active, act.mixed
    total = int(_count_leaves(active, mixed)) if count else 0
    vid = np.full(active.size, -1, np.int32)  # flat i·C + j, C the flags' row (pool.N)
    stack, state = walk_start(*walk_shape(active.shape))
    active, mixed, gen = _as_generation(active, mixed)
    tris = np.empty((chunk, 3), np.int64)
    cand = np.empty(3 * chunk, np.int64)
    faces = np.empty((chunk, 3), np.int64)
    order = np.empty(3 * chunk, np.int64)
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    nv, done = 0, 0
    while True:
        n = walk_leaves(active, mixed, gen, stack, state, tris)
        if n == 0:
            return
        done += n
        if edge:  # faces past the data's last row or column: clipped, or dropped
            f, xyz, ij = _edge_chunk(tris[:n], pool, zfac, g, vid, nv, cuts)
            yield MeshChunk(nv, xyz, ij, f, done, max(total, done))
            nv += len(xyz)
            continue
        k = _new_samples(tris[:n], vid, cand)
        new = cand[:k]
        pos, gij = _gather(pool, new, zfac)
        valid = np.isfinite(pos[:, 2])
        nf, nn = _number(tris[:n], vid, valid, new, nv, faces, order, _NO_KEYS, cuts)
        pick = order[:nn]
        yield MeshChunk(nv, pos[pick], gij[pick], faces[:nf].copy(), done, max(total, done))
        nv += nn

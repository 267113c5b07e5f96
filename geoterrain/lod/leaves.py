"""The static mesh straight from its active vertices: no walk (seed 002, bisection).

In a closed active set (every active vertex's two diamond parents are active, which
saturated δ gives for δ > e, LP §2.4) every active vertex m is split, so both
triangles of its diamond exist and each splits into two children at m. A child is a
leaf exactly when the midpoint of its own hypotenuse is not active (or is not a sample:
the finest level). Every leaf has one parent split, so

    leaves = {children of active vertices whose midpoint is inactive}
             ∪ {a root's two base triangles, when its centre is inactive},

each met once (a root grid's roots, :mod:`geoterrain.core.grid`, each its own bintree,
their shared edges conforming as any other edge). On a root grid the active set may
miss a parent beyond a level's last tile (a vertex there is in no tile, so its δ is not
stored): then the child's triangles on that side, which lie beyond the data's last row
or column, are not emitted, as the walk never reaches them. That turns the depth-first
walk of :func:`~geoterrain.lod.emit.walk_gather` into flat passes over the tiles and the
active vertices, in parallel:

1. per tile, the active vertices it owns (a sample shared by two tiles belongs to the
   one :func:`~geoterrain.lod.kernels._coarsest_tile` names), listed, then numbered
   tile by tile with their positions and elevations read from the pooled tile;
2. per block of vertices, its leaves: written with room for four per vertex (the most a
   vertex has) into kept scratch and gathered to their final rows, or, for a mesh too
   large for the scratch, counted first and written to their final rows.

The children of a sample (i, j) follow from the lowest set bit h of i | j. When i/h and
j/h are both odd, (i, j) is the centre of a square of half-size h, and its children are
the four triangles it makes with the square's sides, whichever diagonal was the
hypotenuse. Otherwise its hypotenuse runs h either way along the axis in which i/h or
j/h is odd, its apexes lie h away across it (one of them outside the grid on the
domain's edge), and its children are the four triangles of that diamond's halves.
Samples are numbered i·N + j with N the row stride: a square's side, a root grid's
extent's columns; ``lim`` = (rows − 1, columns − 1) of the square or the extent.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.core.bintree import root_triangles
from geoterrain.core.threads import ParallelKernel, serial_for
from geoterrain.lod.kernels import _coarsest_tile, sample_xy
from geoterrain.lod.pool import PooledTiles

_SERIAL: dict = {}


class SampleAt(NamedTuple):
    """Where a vertex's sample lies: in pool slot ``slot``, row ``a`` and column ``b`` of
    its tile; grid row ``i`` and column ``j``, pyramid level ``L``."""

    slot: int
    a: int
    b: int
    i: int
    j: int
    L: int


class LeafVertices(NamedTuple):
    """The static mesh's vertices as its kernels number and write them: ``vid`` the dense
    N² (a root grid: its extent's) vertex-number scratch (−1: none), and per vertex its
    position ``xyz`` (x, y, z), grid indices ``ij`` (float64), pyramid level ``lvl`` and
    elevation ``elev``."""

    vid: np.ndarray
    xyz: np.ndarray
    ij: np.ndarray
    lvl: np.ndarray
    elev: np.ndarray


def _parallel(f):
    """``f`` as a :class:`~geoterrain.core.threads.ParallelKernel` (its serial twin also
    in :data:`_SERIAL`): numba's GNU OpenMP layer aborts a process forked from one that
    used it at its first parallel launch, so a forked child runs the twin."""
    k = ParallelKernel(f, cache=True, nogil=True)
    _SERIAL[f.__name__] = k.serial
    return k


def _kernel(name: str, samples: int):
    """The parallel kernel ``name``, or its serial twin in a forked child, inside
    :func:`~geoterrain.core.threads.serial_kernels`, or for fewer than
    :data:`~geoterrain.core.threads.PARALLEL_MIN_SAMPLES` pooled samples (a small mesh
    compiles and runs only the twins, as :func:`~geoterrain.core.threads.cores_for`)."""
    return _SERIAL[name] if serial_for(samples) else globals()[name].parallel


@njit(cache=True, nogil=True, inline="always")
def _listed(D, sl, a, b, coarse, inner_row, inner_col, e, i, j, S):
    """Whether sample (a, b) (grid sample (i, j)) of the tile in slot ``sl`` of ``D`` is
    an active vertex (δ > e) that the tile owns: new at its level (unless ``coarse`` is
    False), not on the tile's last row (column) if the tile is not the level's last in
    that direction (``inner_row``, ``inner_col``), and not a root's corner (``S``: a
    root's side, the square's last row and column)."""
    T = D.shape[1]
    if coarse and (a & 1) == 0 and (b & 1) == 0:
        return False  # a coarser level's vertex, owned by that level's tile
    if (a == T - 1 and inner_row) or (b == T - 1 and inner_col):
        return False
    if not np.float64(D[sl, a, b]) > e:
        return False
    return not (i % S == 0 and j % S == 0)


@_parallel
def _find_active(tiles, D, e, top_step, cnt, loc):
    """Per tile k of ``tiles``: how many vertices :func:`_listed` names, in ``cnt[k]``,
    and (unless ``loc`` has no columns) their local indices (a << 16 | b) in ``loc[k]``."""
    T = D.shape[1]
    S = top_step * (T - 1)  # a root's side
    keep = loc.shape[1] > 0
    slots, i0, j0, step = tiles.slots, tiles.i0, tiles.j0, tiles.step
    tx, ty, tps, tpd = tiles.tx, tiles.ty, tiles.tps, tiles.tpd
    for k in prange(slots.shape[0]):
        sl = slots[k]
        coarse = step[k] < top_step
        inner_row, inner_col = ty[k] != tpd[k] - 1, tx[k] != tps[k] - 1
        c = 0
        for a in range(T):
            i = i0[k] + a * step[k]
            for b in range(T):
                if _listed(D, sl, a, b, coarse, inner_row, inner_col, e, i,
                           j0[k] + b * step[k], S):
                    if keep:
                        loc[k, c] = (a << 16) | b
                    c += 1
        cnt[k] = c


@njit(cache=True, nogil=True, inline="always")
def _position(at, X, Y, aff, H, zfac):
    """The scene position (x, y, height · zfac) of the sample ``at`` (:class:`SampleAt`),
    read from the pool's slabs (:class:`~geoterrain.lod.pool.PoolSlabs`' fields)."""
    x, y = sample_xy(X, Y, aff, at.slot, at.a, at.b, at.i, at.j)
    return x, y, H[at.slot, at.a, at.b] * zfac


@njit(cache=True, nogil=True, inline="always")
def _vertex(v, at, N, p, inv_scale, vid, xyz, ij, lvl, elev):
    """Number the sample ``at`` (:class:`SampleAt`) v in ``vid`` (N²) and write its
    position ``p`` (:func:`_position`), grid indices, level and elevation (z ·
    ``inv_scale`` as float32, :func:`~geoterrain.lod.mesh.add_elevation`'s formula);
    returns whether its height is invalid. The arrays it reads and writes come one by
    one, bound before the callers' loops (:class:`LeafVertices`' fields): inlined into a
    parallel loop, writes through arrays unpacked from a tuple would be dropped as dead
    by numba's parfors, and a tuple's fields read in the loop cost a fifth more time."""
    sl, a, b, i, j, L = at
    x, y, z = p
    vid[i * N + j] = v
    xyz[v, 0], xyz[v, 1], xyz[v, 2] = x, y, z
    elev[v] = np.float32(z * inv_scale)
    ij[v, 0], ij[v, 1] = i, j
    lvl[v] = L
    return not np.isfinite(z)


@njit(cache=True, nogil=True)
def _replicate(pad, rows, cols, N, slabs, inv_scale, verts):
    """Vertices ``pad`` of ``verts`` (beyond the data's rows × cols) take the height of
    the nearest sample of the data's last row or column (replicated padding, edgepad.py;
    read from the pool's ``slabs``); returns how many now have one."""
    top, t, base, slot_of, H, zfac = (slabs.top, slabs.t, slabs.base, slabs.slot_of, slabs.H,
                                      slabs.zfac)
    ij, xyz, elev = verts.ij, verts.xyz, verts.elev
    fixed = 0
    for k in range(pad.shape[0]):
        v = pad[k]
        i = min(np.int64(ij[v, 0]), rows - 1)
        j = min(np.int64(ij[v, 1]), cols - 1)
        _, ti, a, b = _coarsest_tile(i, j, top, t, base)
        s = slot_of[ti]
        z = H[s, a, b] * zfac if s >= 0 else np.nan
        xyz[v, 2] = z
        elev[v] = np.float32(z * inv_scale)
        fixed += np.isfinite(z)
    return fixed


@_parallel
def _number_active(tiles, slabs, e, top_step, inv_scale, N, cnt, loc, first, verts,
                   invalid):
    """Per tile, the vertices :func:`_find_active` counted (read from ``loc``, or found
    again, by their δ ``slabs.D``, when it has no columns): number them from
    ``first[k]`` into ``verts.vid`` (row stride ``N``) and write each one's data
    (:func:`_vertex`); ``invalid[k]``: how many have no valid height."""
    D = slabs.D
    T = D.shape[1]
    S = top_step * (T - 1)  # a root's side
    slots, i0, j0, step, level = tiles.slots, tiles.i0, tiles.j0, tiles.step, tiles.level
    tx, ty, tps, tpd = tiles.tx, tiles.ty, tiles.tps, tiles.tpd
    X, Y, aff, H, zfac = slabs.X, slabs.Y, slabs.aff, slabs.H, slabs.zfac
    vid = verts.vid  # one by one, before the parallel loop (see _vertex)
    xyz = verts.xyz
    ij = verts.ij
    lvl = verts.lvl
    elev = verts.elev
    for k in prange(slots.shape[0]):
        sl, v, bad = slots[k], first[k], 0
        if loc.shape[1] > 0:
            for r in range(cnt[k]):
                a, b = loc[k, r] >> 16, loc[k, r] & 0xFFFF
                at = SampleAt(sl, a, b, i0[k] + a * step[k], j0[k] + b * step[k], level[k])
                p = _position(at, X, Y, aff, H, zfac)
                bad += _vertex(v, at, N, p, inv_scale, vid, xyz, ij, lvl, elev)
                v += 1
        else:
            coarse = step[k] < top_step
            inner_row, inner_col = ty[k] != tpd[k] - 1, tx[k] != tps[k] - 1
            for a in range(T):
                i = i0[k] + a * step[k]
                for b in range(T):
                    j = j0[k] + b * step[k]
                    if _listed(D, sl, a, b, coarse, inner_row, inner_col, e, i, j, S):
                        at = SampleAt(sl, a, b, i, j, level[k])
                        p = _position(at, X, Y, aff, H, zfac)
                        bad += _vertex(v, at, N, p, inv_scale, vid, xyz, ij, lvl, elev)
                        v += 1
        invalid[k] = bad


@njit(cache=True, nogil=True, inline="always")
def _leaf(faces, level, f, stop, va, vb, vc, lv, split):
    """Write face (a, b, c) and its level at row f (below ``stop``, the block's end) and
    keep it (return f + 1) unless the child is ``split``: no branch on the data (a
    split child's row is written over by the next leaf)."""
    if f < stop:
        faces[f, 0], faces[f, 1], faces[f, 2] = va, vb, vc
        level[f] = lv
    return f + 1 - split


@_parallel
def _emit_leaves(ij, lvl, vid, lim, per, start, stop, cnt, faces, level):
    """The leaves of each block of ``per`` vertices, in rows ``start[block]`` to
    ``stop[block]``, how many in ``cnt[block]``; with their level: that of their split
    vertex m, the finest of their corners (the others lie on multiples of 2h). ``lim``:
    the grid's last row and column; a side whose apex lies beyond them, or is no vertex
    (a root grid's parent beyond a level's last tile), has no children.

    A child is a leaf when the midpoint of its hypotenuse is not active: a square
    centre's children always have one (their hypotenuses are 2h long), an edge
    midpoint's only when h ≥ 2 (at (i ± h/2, j ± h/2)). Every face is wound like the
    walk's base triangles: positive cross (b − a) × (c − a) in (i, j), which bisection
    keeps."""
    si, sj = lim
    N = sj + 1
    V = ij.shape[0]
    for c in prange(cnt.shape[0]):
        f, e = start[c], stop[c]
        for v in range(c * per, min(V, (c + 1) * per)):
            i, j = np.int64(ij[v, 0]), np.int64(ij[v, 1])
            low = i | j
            h = low & -low
            m = i * N + j
            vm, lv = vid[m], lvl[v]  # v + the roots' corners
            if (i & h) != 0 and (j & h) != 0:
                # a square's centre: its four children have the square's sides as
                # hypotenuses, split at the sides' midpoints m ± h (row), m ± hN (column)
                a00 = vid[m - h * N - h]
                a01 = vid[m - h * N + h]
                a10 = vid[m + h * N - h]
                a11 = vid[m + h * N + h]
                sn = vid[m - h * N] >= 0
                ss = vid[m + h * N] >= 0
                sw = vid[m - h] >= 0
                se = vid[m + h] >= 0
                f = _leaf(faces, level, f, e, a00, vm, a01, lv, sn)  # north side (i - h)
                f = _leaf(faces, level, f, e, a01, vm, a11, lv, se)  # east side (j + h)
                f = _leaf(faces, level, f, e, a11, vm, a10, lv, ss)
                f = _leaf(faces, level, f, e, a10, vm, a00, lv, sw)
            elif (j & h) != 0:
                # hypotenuse along the row: ends (i, j ∓ h), apexes (i ∓ h, j)
                vp, vq = vid[m - h], vid[m + h]
                deep = h >= 2
                g = h >> 1
                if i - h >= 0 and vid[m - h * N] >= 0:
                    vc = vid[m - h * N]
                    s1 = deep and vid[m - g * N - g] >= 0
                    s2 = deep and vid[m - g * N + g] >= 0
                    f = _leaf(faces, level, f, e, vc, vp, vm, lv, s1)
                    f = _leaf(faces, level, f, e, vq, vc, vm, lv, s2)
                if i + h <= si and vid[m + h * N] >= 0:
                    vc = vid[m + h * N]
                    s1 = deep and vid[m + g * N - g] >= 0
                    s2 = deep and vid[m + g * N + g] >= 0
                    f = _leaf(faces, level, f, e, vc, vm, vp, lv, s1)
                    f = _leaf(faces, level, f, e, vq, vm, vc, lv, s2)
            else:
                # hypotenuse along the column: ends (i ∓ h, j), apexes (i, j ∓ h)
                vp, vq = vid[m - h * N], vid[m + h * N]
                deep = h >= 2
                g = h >> 1
                if j - h >= 0 and vid[m - h] >= 0:
                    vc = vid[m - h]
                    s1 = deep and vid[m - g * N - g] >= 0
                    s2 = deep and vid[m + g * N - g] >= 0
                    f = _leaf(faces, level, f, e, vc, vm, vp, lv, s1)
                    f = _leaf(faces, level, f, e, vq, vm, vc, lv, s2)
                if j + h <= sj and vid[m + h] >= 0:
                    vc = vid[m + h]
                    s1 = deep and vid[m - g * N + g] >= 0
                    s2 = deep and vid[m + g * N + g] >= 0
                    f = _leaf(faces, level, f, e, vc, vp, vm, lv, s1)
                    f = _leaf(faces, level, f, e, vq, vc, vm, lv, s2)
        cnt[c] = f - start[c]


@_parallel
def _count_leaves(ij, vid, lim, per, cnt):
    """How many leaves :func:`_emit_leaves` writes for each block of ``per`` vertices."""
    si, sj = lim
    N = sj + 1
    V = ij.shape[0]
    for c in prange(cnt.shape[0]):
        n = 0
        for v in range(c * per, min(V, (c + 1) * per)):
            i, j = np.int64(ij[v, 0]), np.int64(ij[v, 1])
            low = i | j
            h = low & -low
            m = i * N + j
            if (i & h) != 0 and (j & h) != 0:
                n += 4 - (vid[m - h * N] >= 0) - (vid[m + h * N] >= 0) \
                    - (vid[m - h] >= 0) - (vid[m + h] >= 0)
                continue
            g = h >> 1
            row = (j & h) != 0
            di, dj = (h, 0) if row else (0, h)  # towards the apexes
            gi, gj = (g * N, g) if row else (g, g * N)  # to the children's midpoints
            for side in (-1, 1):
                if row and (i + side * h < 0 or i + side * h > si):
                    continue
                if not row and (j + side * h < 0 or j + side * h > sj):
                    continue
                if vid[m + side * (h * N if row else h)] < 0:
                    continue  # an apex that is no vertex (see _emit_leaves)
                n += 2
                if h >= 2:
                    n -= (vid[m + side * gi - gj] >= 0) + (vid[m + side * gi + gj] >= 0)
        cnt[c] = n


@_parallel
def _gather_blocks(ef, el, per, cnt, first, faces, level, vid, ij, N):
    """Each block's leaves, from row 4·per·block of ``ef``/``el``, to row ``first[block]``
    of ``faces``/``level``; and the block's vertices' numbers in ``vid`` back to −1
    (``ij``: their grid indices)."""
    V = ij.shape[0]
    for c in prange(cnt.shape[0]):
        src, dst = 4 * per * c, first[c]
        for f in range(cnt[c]):
            faces[dst + f, 0] = ef[src + f, 0]
            faces[dst + f, 1] = ef[src + f, 1]
            faces[dst + f, 2] = ef[src + f, 2]
            level[dst + f] = el[src + f]
        for v in range(c * per, min(V, (c + 1) * per)):
            vid[np.int64(ij[v, 0]) * N + np.int64(ij[v, 1])] = -1


@njit(cache=True, nogil=True)
def _corners(ci, cj, N, slabs, inv_scale, verts):
    """Vertices 0, 1, …: the roots' corners (rows ``ci``, columns ``cj``), read from the
    top level's tiles (pooled in ``slabs``) by :func:`_vertex`; returns how many have
    no valid height."""
    vid, xyz, ij, lvl, elev = verts
    bad = 0
    for v in range(ci.shape[0]):
        i, j = ci[v], cj[v]
        L, ti, a, b = _coarsest_tile(i, j, slabs.top, slabs.t, slabs.base)
        at = SampleAt(slabs.slot_of[ti], a, b, i, j, L)
        p = _position(at, slabs.X, slabs.Y, slabs.aff, slabs.H, slabs.zfac)
        bad += _vertex(v, at, N, p, inv_scale, vid, xyz, ij, lvl, elev)
    return bad


@_parallel
def _reset(vid, ij, N):
    for v in prange(ij.shape[0]):
        vid[np.int64(ij[v, 0]) * N + np.int64(ij[v, 1])] = -1


#: Scratch arrays up to this size are kept between calls (fresh pages cost their zeroing):
#: the per-tile lists, and the spare-room faces and levels together, so a terrain keeps at
#: most twice this (128 MB) after a static mesh.
KEEP_BYTES = 64 << 20


def _buffer(scratch: dict, name: str, shape: tuple, dtype) -> np.ndarray:
    """An uninitialised array of ``shape``, from ``scratch[name]`` when that is large
    enough, else new (and kept there when at most :data:`KEEP_BYTES`)."""
    n = int(np.prod(shape))
    have = scratch.get(name)
    if have is not None and have.size >= n and have.dtype == dtype:
        return have[:n].reshape(shape)
    out = np.empty(n, dtype)
    if out.nbytes <= KEEP_BYTES:
        scratch[name] = out
    return out.reshape(shape)


def static_leaves(keys: np.ndarray, slots: np.ndarray, pool, zfac: float, e: float,
                  vid: np.ndarray, scratch: dict | None = None, z_scale: float = 1.0,
                  D: np.ndarray | None = None, window: tuple[int, int] | None = None,
                  room: tuple[int, int] = (0, 0)):
    """The leaf triangles and vertices of the static mesh δ > ``e`` over the tiles
    ``keys`` (level, x, y) with pool ``slots`` (every tile holding a vertex with δ > e;
    their δ, heights and positions pooled, and the top tile's too).

    ``vid`` is the dense N² vertex-number scratch (a root grid: its extent's), all −1;
    it is left all −1. On a root grid each root is its own bintree (two base triangles,
    :func:`geoterrain.core.bintree.root_triangles`), every root's corners pooled.
    ``scratch``: a dict that keeps the working arrays from one call to the next.
    ``D``: the pooled δ to read (default ``pool.D``; ``pool.DE`` for δ_edge).
    ``window``: (rows, cols) of the data when the padding is replicated
    (:mod:`geoterrain.bounds.edgepad`): a vertex beyond it takes the height of the nearest
    sample of the data's last row or column, whose tile must be pooled too.
    ``room``: spare rows after the vertices and after the faces (the returned arrays are
    views of larger ones, for :func:`geoterrain.lod.clip.clip_in_place`).
    Returns faces (F, 3) int32 and their levels (int16), and per vertex: position
    (x, y, z), grid indices (float64), pyramid level (int8) and elevation (float32,
    z / ``z_scale``), and how many vertices have no valid height (0: no face needs
    culling).

    Examples
    --------
    >>> out = static_leaves(keys, slots, pool, 1.0, 5.0, vid)  # doctest: +SKIP
    >>> faces, level, xyz, ij, lvl, elevation, bad = out  # doctest: +SKIP
    """
    g, top = pool.grid, pool.top
    R, C = g.extent  # N × N, or the roots' extent
    N, lim = C, (np.int64(R - 1), np.int64(C - 1))
    i0, j0, step = pool.origins(keys)
    L = keys[:, 0].astype(np.int64)
    across, down = (np.array([g.tiles(k)[q] for k in g.levels], np.int64) for q in (0, 1))
    tiles = PooledTiles(slots, i0, j0, step, L, keys[:, 1].astype(np.int64),
                        keys[:, 2].astype(np.int64), across[L], down[L])
    cnt = np.zeros(len(slots), np.int64)
    top_step = np.int64(1) << top
    T = pool.T
    slabs = pool.slabs(zfac)
    if D is not None:
        slabs = slabs._replace(D=D)
    find, number, emit, count, gather, reset = (_kernel(n, len(slots) * T * T) for n in (
        "_find_active", "_number_active", "_emit_leaves", "_count_leaves", "_gather_blocks",
        "_reset"))
    scratch = {} if scratch is None else scratch
    listed = len(slots) * T * T * 4 <= KEEP_BYTES  # else found again: no fresh lists
    loc = _buffer(scratch, "loc", (len(slots), T * T if listed else 0), np.uint32)
    find(tiles, slabs.D, float(e), top_step, cnt, loc)
    rx, ry = g.roots
    S = 1 << g.n  # a root's side
    ci, cj = (a.ravel() * S for a in np.indices((ry + 1, rx + 1), np.int64))  # corners
    nc = len(ci)
    first = np.empty(len(slots), np.int64)
    if len(cnt):
        first[0] = nc
        np.cumsum(cnt[:-1], out=first[1:])
        first[1:] += nc
    V = nc + int(cnt.sum())
    rv, rf = room  # views of larger arrays: their .base has the room
    xyz, ij = np.empty((V + rv, 3))[:V], np.empty((V + rv, 2))[:V]
    lvl, elev = np.empty(V + rv, np.int8)[:V], np.empty(V + rv, np.float32)[:V]
    inv = 1.0 / float(z_scale)
    verts = LeafVertices(vid, xyz, ij, lvl, elev)
    bad = _corners(ci, cj, N, slabs, inv, verts)
    invalid = np.zeros(len(slots), np.int64)
    number(tiles, slabs, float(e), top_step, inv, N, cnt, loc, first, verts, invalid)
    bad += int(invalid.sum())
    if window is not None:  # padding vertices: their replicated heights
        pad = np.flatnonzero((ij[:, 0] >= window[0]) | (ij[:, 1] >= window[1]))
        bad -= _replicate(pad, window[0], window[1], N, slabs, inv, verts)
    # a root whose centre is inactive: its two base triangles are leaves
    a, b, c = (p[:, 0] * N + p[:, 1] for p in root_triangles(g.n, (rx, ry)))
    base = vid[a[::2] + (b[::2] - a[::2]) // 2] < 0  # each root's centre: its diagonal's
    corner = {int(k): v for v, k in enumerate((ci * N + cj).tolist())}
    roots = np.array([[corner[int(k)] for k in (a[r], b[r], c[r])] for r in range(len(a))
                      if base[r // 2]], np.int32).reshape(-1, 3)
    per = 4096
    nb = -(-(V - nc) // per)
    lcnt = np.zeros(nb, np.int64)
    rows = 4 * per * nb  # room for 4 leaves per vertex, the most it can have
    lfirst = np.zeros(nb, np.int64)
    if rows * 14 <= KEEP_BYTES:  # emit into kept scratch, gather to the exact size
        ef = _buffer(scratch, "faces", (rows, 3), np.int32)
        el = _buffer(scratch, "level", (rows,), np.int16)
        at = np.arange(nb) * (4 * per)
        emit(ij[nc:], lvl[nc:], vid, lim, per, at, at + 4 * per, lcnt, ef, el)
        np.cumsum(lcnt[:-1], out=lfirst[1:])
        F = int(lcnt.sum())
        B = F + len(roots)
        faces = np.empty((B + rf, 3), np.int32)[:B]
        level = np.empty(B + rf, np.int16)[:B]
        gather(ef, el, per, lcnt, lfirst, faces, level, vid, ij[nc:], N)
        reset(vid, ij[:nc], N)
    else:  # a large mesh: count, then emit to the exact rows (no room to spare)
        count(ij[nc:], vid, lim, per, lcnt)
        np.cumsum(lcnt[:-1], out=lfirst[1:])
        F = int(lcnt.sum())
        B = F + len(roots)
        faces = np.empty((B + rf, 3), np.int32)[:B]
        level = np.empty(B + rf, np.int16)[:B]
        emit(ij[nc:], lvl[nc:], vid, lim, per, lfirst, lfirst + lcnt, lcnt, faces, level)
        reset(vid, ij, N)
    # the base triangles of the roots whose centre is inactive (a square's: (0, 0),
    # (s, s), (0, s) and (s, s), (0, 0), (s, 0))
    faces[F:B] = roots
    level[F:B] = top
    return faces, level, xyz, ij, lvl, elev, bad

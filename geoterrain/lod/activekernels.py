"""Compiled bintree extraction (numba): the active set's flags, one resumable stack-based
walk, vertices numbered in order, the closure upward and the static fill (``δ > e``); the
sample positions every pooled kernel reads (:func:`sample_xy`).

Benchmarked against the level-by-level numpy bisection it replaced; today's figures come
from ``benchmarks/bench_lod.py`` (docs/benchmarks.md; history in docs/lab/lod-flight.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.core.bintree import parents_nb


class ActiveFlags(NamedTuple):
    """The dense per-sample flags a selection fills and walks: ``active`` and ``mixed``
    (N, N), bools or generation stamps where ``== gen`` means set, and ``boxes``
    (levels, 4): rows i0, i1 and columns j0, j1 of the active vertices per pyramid level
    (what the closure scans)."""

    active: np.ndarray
    mixed: np.ndarray
    gen: bool | int
    boxes: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def sample_xy(X, Y, aff, s, a, b, i, j):
    """Scene x, y of sample (i, j), sample (a, b) of pool slot ``s``: from the slabs
    ``X``, ``Y``, or for an affine frame (``aff`` = a, b, c, d, e, f of the geotransform,
    the origin x, y and the unit in metres, then 1; all 0 for a curvilinear frame) by
    ``Frame.xy``'s formula, in its order."""
    if aff[9] == 0.0:
        return X[s, a, b], Y[s, a, b]
    jj, ii = j + 0.5, i + 0.5
    x = aff[0] * jj + aff[1] * ii + aff[2]
    y = aff[3] * jj + aff[4] * ii + aff[5]
    return (x - aff[6]) * aff[8], (y - aff[7]) * aff[8]


def walk_start(N: int, roots: tuple[int, int] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """The stack and state (stack pointer) of a walk over an N × N grid: the two
    base triangles, both counter-clockwise; with ``roots`` (across, down), over a root
    grid of roots of side N − 1: two triangles per root
    (:func:`geoterrain.core.bintree.root_triangles`).

    Examples
    --------
    >>> stack, state = walk_start(5, (2, 1))
    >>> int(state[0]), stack[:4].tolist()
    (4, [[0, 0, 4, 4, 0, 4], [4, 4, 0, 0, 4, 0], [4, 4, 0, 8, 0, 4], [0, 8, 4, 4, 4, 8]])
    """
    s = N - 1
    if roots is None or tuple(roots) == (1, 1):
        stack = np.empty((256, 6), np.int64)
        stack[0] = (0, 0, s, s, 0, s)
        stack[1] = (s, s, 0, 0, s, 0)
        return stack, np.array([2], np.int64)
    from geoterrain.core.bintree import root_triangles

    a, b, c = root_triangles(int(s).bit_length() - 1, roots)
    stack = np.empty((256 + len(a), 6), np.int64)
    stack[:len(a)] = np.concatenate([a, b, c], axis=1)
    return stack, np.array([len(a)], np.int64)


@njit(cache=True, nogil=True)
def walk_leaves(active, mixed, gen, stack, state, out):
    """Resumable depth-first longest-edge bisection (seed 002): up to ``len(out)`` leaf
    triangles as flat sample indices (i·N + j); returns how many, 0 once done.

    A triangle (a, b, c) splits at m = (a + b) / 2 when ``active[m] == gen``; leaves
    over a mixed diamond (``mixed[m] == gen``) are skipped. ``stack``/``state`` (from
    :func:`walk_start`) carry the walk between calls.
    """
    N = active.shape[1]  # a row's samples (a root grid's extent is wider than tall)
    sp = state[0]
    nf = 0
    cap = out.shape[0]
    while sp > 0 and nf < cap:
        sp -= 1
        ai, aj, bi, bj, ci, cj = stack[sp]
        si, sj = ai + bi, aj + bj
        if (si & 1) == 0 and (sj & 1) == 0:
            mi, mj = si >> 1, sj >> 1
            if active[mi, mj] == gen:
                # LP bisection: children (c, a, m) and (b, c, m)
                stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = ci, cj, ai, aj
                stack[sp, 4], stack[sp, 5] = mi, mj
                sp += 1
                stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = bi, bj, ci, cj
                stack[sp, 4], stack[sp, 5] = mi, mj
                sp += 1
                continue
            if mixed[mi, mj] == gen:
                continue
        out[nf, 0] = ai * N + aj
        out[nf, 1] = bi * N + bj
        out[nf, 2] = ci * N + cj
        nf += 1
    state[0] = sp
    return nf


@njit(cache=True, nogil=True)
def _walk(active, mixed, gen, stack, state, vid, tris, verts):
    """The whole walk, numbering vertices in order of first use: faces go to ``tris``
    and first-seen sample indices to ``verts``; when ``tris`` is too small the walk
    stops and returns -1 triangles (``vid`` is reset either way)."""
    cap = tris.shape[0]
    buf = np.empty((4096, 3), np.int64)  # leaves pass through a cache-sized buffer
    nf, nv = 0, 0
    while True:
        n = walk_leaves(active, mixed, gen, stack, state, buf)
        if n == 0:
            break
        if nf + n > cap:
            nf = -1
            break
        for f in range(n):
            for k in range(3):
                idx = buf[f, k]
                v = vid[idx]
                if v < 0:
                    v = nv
                    vid[idx] = nv
                    verts[nv] = idx
                    nv += 1
                tris[nf + f, k] = v
        nf += n
    for k in range(nv):
        vid[verts[k]] = -1
    return nf, nv


def extract(active: np.ndarray, mixed: np.ndarray, vid: np.ndarray, gen=True,
            capacity: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Leaf triangles of the refinement: faces (F, 3) and flat sample indices (V,).

    ``active``/``mixed`` are bool flags, or generation stamps compared with ``gen``.
    ``vid`` is a scratch (N*N,) int32 array filled with -1; it is left that way.
    ``capacity`` is a first guess of the triangle count (grown on demand).

    Examples
    --------
    >>> a = np.zeros((3, 3), bool)
    >>> f, v = extract(a, a, np.full(9, -1, np.int32))
    >>> f.shape, sorted(v.tolist())
    ((2, 3), [0, 2, 6, 8])
    """
    cap = max(int(capacity), 1024)
    while True:
        tris = np.empty((cap, 3), np.int32)
        verts = np.empty(3 * cap, np.int64)
        stack, state = walk_start(*walk_shape(active.shape))
        nf, nv = _walk(active, mixed, gen, stack, state, vid, tris, verts)
        if nf >= 0:
            return tris[:nf], verts[:nv]
        cap *= 4


def walk_shape(shape: tuple[int, int]) -> tuple[int, tuple[int, int] | None]:
    """:func:`walk_start`'s arguments for flags of ``shape``: a square N × N, or a root
    grid's extent (2 × 1 or 1 × 2 roots, :data:`geoterrain.core.grid.MAX_ROOTS`).

    Examples
    --------
    >>> walk_shape((5, 5)), walk_shape((5, 9)), walk_shape((9, 5))
    ((5, None), (5, (2, 1)), (5, (1, 2)))
    """
    R, C = shape
    if R == C:
        return R, None
    s = min(R, C) - 1
    return s + 1, ((C - 1) // s, (R - 1) // s)


@njit(cache=True, nogil=True)
def _set_parents(active, i, j, h, gen):
    R, C = active.shape
    p0i, p0j, p1i, p1j = parents_nb(i, j, h)  # the bintree's rule (seed 002 §2.3)
    if 0 <= p0i < R and 0 <= p0j < C:
        active[p0i, p0j] = gen
    if 0 <= p1i < R and 0 <= p1j < C:
        active[p1i, p1j] = gen


@njit(cache=True, nogil=True)
def close_upward_boxes(active, boxes, gen=True):
    """Activate both parents of every active vertex, finest depth first, in place.

    Depth order: for h = 1, 2, 4, ...: the edge midpoints of half-size h, then the
    block centres of half-size h (the edges' parents), then the next h. Only a
    box is scanned at each h: the union of ``boxes[L]`` (rows i0, i1, columns
    j0, j1 of the tiles filled at pyramid level L = log2 h, capped at the last
    row of ``boxes``) and the previous box grown by h (parents lie h away).
    ``active`` holds bools, or generation stamps where ``== gen`` means active; N × N,
    or a root grid's extent (its roots' side the shorter one less 1: the roots' centres
    are the last vertices with parents).
    """
    R, C = active.shape
    top = boxes.shape[0] - 1
    i0, i1, j0, j1 = R, -1, C, -1
    h, L = np.int64(1), 0  # not a literal 1: _set_parents compiles once
    while h < min(R, C) - 1:
        b = boxes[min(L, top)]
        i0, i1, j0, j1 = min(i0, b[0]), max(i1, b[1]), min(j0, b[2]), max(j1, b[3])
        if i1 >= 0:
            ia, ja = (i0 // h) * h, (j0 // h) * h
            for i in range(ia, i1 + 1, h):  # edge midpoints: i/h + j/h odd
                jb = ja if ((i // h) + (ja // h)) % 2 == 1 else ja + h
                for j in range(jb, j1 + 1, 2 * h):
                    if active[i, j] == gen:
                        _set_parents(active, i, j, h, gen)
            i0, j0 = max(0, i0 - h), max(0, j0 - h)  # their parents lie h away
            i1, j1 = min(R - 1, i1 + h), min(C - 1, j1 + h)
            ia, ja = (i0 // h) * h, (j0 // h) * h
            ib = ia if (ia // h) % 2 == 1 else ia + h  # block centres: i/h, j/h odd
            jb = ja if (ja // h) % 2 == 1 else ja + h
            for i in range(ib, i1 + 1, 2 * h):
                for j in range(jb, j1 + 1, 2 * h):
                    if active[i, j] == gen:
                        _set_parents(active, i, j, h, gen)
            i0, j0 = max(0, i0 - h), max(0, j0 - h)
            i1, j1 = min(R - 1, i1 + h), min(C - 1, j1 + h)
        h *= 2
        L += 1


def close_upward(active: np.ndarray) -> None:
    """:func:`close_upward_boxes` over the whole grid.

    Examples
    --------
    >>> a = np.zeros((5, 5), bool); a[1, 0] = True
    >>> close_upward(a); [tuple(map(int, p)) for p in np.argwhere(a)]
    [(0, 2), (0, 4), (1, 0), (1, 1), (2, 0), (2, 2), (4, 0)]
    """
    R, C = active.shape
    close_upward_boxes(active, np.array([[0, R - 1, 0, C - 1]], np.int64))


@njit(cache=True, nogil=True)
def fill_static(slots, i0, j0, step, D, e, active, mixed, gen=True, top_step=0):
    """Static predicate δ > e on pooled tiles, scattered into the dense flags in place.

    ``slots``: pool slot of each tile; ``i0, j0, step``: grid row/column of its first
    sample and its sample spacing. δ = inf (mixed diamond) is active and mixed.
    Only the samples new at a tile's level are read (both local indices even means
    a coarser level's vertex, read in that level's tile) unless ``step`` is
    ``top_step`` or ``top_step`` is 0.
    """
    T = D.shape[1]
    for k in range(slots.shape[0]):
        s = slots[k]
        coarse = top_step > 0 and step[k] < top_step
        for a in range(T):
            i = i0[k] + a * step[k]
            for b in range(T):
                if coarse and (a & 1) == 0 and (b & 1) == 0:
                    continue
                j = j0[k] + b * step[k]
                dl = np.float64(D[s, a, b])
                if dl > e:
                    active[i, j] = gen
                if dl == np.inf:
                    mixed[i, j] = gen


@njit(cache=True, nogil=True, inline="always")
def _grow_box(boxes, lv, i, j):
    if i < boxes[lv, 0]:
        boxes[lv, 0] = i
    if i > boxes[lv, 1]:
        boxes[lv, 1] = i
    if j < boxes[lv, 2]:
        boxes[lv, 2] = j
    if j > boxes[lv, 3]:
        boxes[lv, 3] = j

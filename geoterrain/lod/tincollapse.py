"""The greedy TIN's driver and its collapse pass (the kernels of :mod:`geoterrain.lod.tin`).

:func:`greedy_tin` runs the refinement of :mod:`geoterrain.lod.tinkernels` (insert the
worst sample of the worst triangle until every triangle is within the bound), then
:func:`_decimate`: each point merged into a neighbour wherever every triangle of the new
fan still has its error over the samples it covers within the bound (scanned, as the
refinement scans). Tried on every point, it removes 26–41 % of the triangles Delatin's
refinement alone leaves, for about a quarter more time; the caller may stop it after a
share of them (``collapse``: ``mesher="tin"`` stops at 5 %, ``"tin-full"`` does not;
docs/lab/static-mesh.md). The half-edge rows, the heap and the scans are the refinement
module's; this module only uses them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.lod.tinkernels import (
    DEAD,
    MAXDEG,
    NP,
    NT,
    QI,
    ROW,
    TRIES,
    _compact,
    _flip_to_cover,
    _next,
    _orient,
    _prev,
    _refine,
    _scan,
    _scan_plain,
    _set_triangle,
)

STRIDE = 16  # a bounded collapse pass's rows: 0, 16, 32, …, then 1, 17, …


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _within(a, b, c, z, valid, W, voids, max_error):
    if voids:
        return _scan(a, b, c, z, valid, W, True)[0] <= max_error
    return _scan_plain(a, b, c, z, W, max_error, True)[0] <= max_error


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _fan_gap(i, d, xs, ys, zn, zv):
    """The fan from neighbour i over the star of v (neighbours' x, y in ``xs``, ``ys``, v's last,
    their heights ``zn``, v's ``zv``): +inf unless every triangle is positive, else its
    error at v itself (one sample, before any triangle is scanned)."""
    vx, vy = xs[d], ys[d]
    ux, uy = xs[i], ys[i]
    gap = np.inf
    for m in range(d - 2):
        k = (i + 1 + m) % d
        k1 = (k + 1) % d
        ax, ay, bx, by = xs[k], ys[k], xs[k1], ys[k1]
        if _orient(ux, uy, ax, ay, bx, by) <= 0:
            return np.inf
        w0 = _orient(ax, ay, bx, by, vx, vy)
        w1 = _orient(bx, by, ux, uy, vx, vy)
        w2 = _orient(ux, uy, ax, ay, vx, vy)
        if w0 >= 0 and w1 >= 0 and w2 >= 0:
            zi = (zn[i] * w0 + zn[k] * w1 + zn[k1] * w2) / float(w0 + w1 + w2)
            gap = abs(zi - zv)
    return gap


@njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
def _decimate(F, nt, pts, z, valid, W, voids, max_error, budget, index, iscr, fscr):
    """Remove the points the refinement no longer needs: collapse an interior point v
    onto a neighbour u when the fan from u over v's star is a valid triangulation
    (every triangle positive) within ``max_error`` (each new triangle scanned). Two
    triangles fewer each. The greedy insertion adds a point for the worst sample of its
    day; points added later often make an early one redundant. Points are taken row by
    row, and the pass stops once it has removed ``budget`` of them. Returns the number
    of points removed.

    Compiled without numba's reference counting (``_nrt=False``: each array a loop
    touched was counted in and out, an atomic add a time), so it allocates nothing: the
    caller passes ``index`` (−1 filled, one per sample then one per point: sample →
    point, then an outgoing half-edge of each point), ``iscr`` (4·(MAXDEG + 1) int64: the
    star, its neighbours, their x and y) and ``fscr`` (2·MAXDEG float64: the fans' gaps,
    the neighbours' heights)."""
    removed = 0
    if budget <= 0:
        return removed
    where = index[:valid.size]
    out = index[valid.size:]
    for k in range(len(pts)):
        where[pts[k]] = k
    for t in range(nt):
        for k in range(3):
            out[where[F[ROW * t + k]]] = ROW * t + k
    M = MAXDEG + 1
    star = iscr[:M]
    nb = iscr[M:2 * M]
    xs = iscr[2 * M:3 * M]
    ys = iscr[3 * M:]
    gap = fscr[:MAXDEG]
    zn = fscr[MAXDEG:]
    # row by row, not a sort (the corners 0 … 3 stay); a bounded pass takes every
    # STRIDE-th row first, then the next ones, so that its collapses spread over the grid
    H = valid.size // W
    step = 1 if budget >= len(pts) else STRIDE
    for r0 in range(step):
        for r in range(r0, H, step):
            for v in range(r * W, r * W + W):
                kv = where[v]
                if kv < 4:
                    continue
                e = out[kv]
                d = 0
                interior = True
                while True:  # v's outgoing half-edges, around it
                    if d == MAXDEG:
                        interior = False
                        break
                    star[d] = e
                    nb[d] = F[_next(e)]
                    d += 1
                    e = F[_prev(e) + 3]
                    if e < 0:
                        interior = False
                        break
                    if e == star[0]:
                        break
                if not interior:
                    continue
                nb[d] = nb[0]
                # the fans that stay positive, by their error at v (a cheap first refusal);
                # the TRIES best are scanned
                for k in range(d):
                    xs[k], ys[k] = nb[k] % W, nb[k] // W
                    zn[k] = z[nb[k]]
                xs[d], ys[d] = v % W, v // W
                for i in range(d):
                    gap[i] = _fan_gap(i, d, xs, ys, zn, z[v])
                for _ in range(TRIES):
                    i = np.argmin(gap[:d])
                    if not gap[i] <= max_error:
                        break
                    gap[i] = np.inf
                    u = nb[i]
                    ok = True
                    for m in range(d - 2):
                        k = (i + 1 + m) % d
                        if not _within(np.int64(u), np.int64(nb[k]), np.int64(nb[k + 1]), z,
                                       valid, W, voids, max_error):
                            ok = False
                            break
                    if not ok:
                        continue
                    ei, em = star[i], star[(i - 1) % d]  # (v → u) and (v → nb[i − 1])
                    ep, emm = star[(i + 1) % d], star[(i - 2) % d]
                    x = F[_next(ei) + 3]  # outside (n_{i+1} → u)'s twin
                    y = F[_next(em) + 3]
                    F[ep + 3] = x
                    if x >= 0:
                        F[x + 3] = ep
                    F[_prev(emm) + 3] = y
                    if y >= 0:
                        F[y + 3] = _prev(emm)
                    for m in range(d - 2):
                        F[star[(i + 1 + m) % d]] = u
                    F[(ei & ~7) + QI] = DEAD
                    F[(em & ~7) + QI] = DEAD
                    ku = where[u]
                    out[ku] = ep
                    out[where[nb[(i + 1) % d]]] = _next(ep)
                    out[where[nb[(i - 1) % d]]] = _prev(emm)
                    out[kv] = -1
                    removed += 1
                    break
                if removed >= budget:
                    return removed
    return removed


@njit(cache=True, nogil=True, error_model="numpy")
def _grow(a, n):
    out = np.empty(n, a.dtype)
    out[:len(a)] = a
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _two_triangles(H, W, cap):
    """The TIN's arrays with room for ``cap`` triangles, holding the H × W rectangle's two
    (the half-edge rows, the heap, its keys, the pending list, the points, the counts)."""
    F = np.empty(ROW * cap, np.int32)
    heap = np.empty(cap, np.int32)
    key = np.empty(cap, np.float64)
    pending = np.empty(cap, np.int32)
    pts = np.empty(cap, np.int32)  # the points, in insertion order
    cnt = np.zeros(4, np.int64)
    p0, p1, p2, p3 = 0, W - 1, (H - 1) * W, H * W - 1
    pts[0], pts[1], pts[2], pts[3] = p0, p1, p2, p3
    cnt[NP] = 4
    t0 = _set_triangle(F, pending, cnt, 0, p3, p0, p2, -1, -1, -1)
    _set_triangle(F, pending, cnt, 1, p0, p3, p1, t0, -1, -1)
    cnt[NT] = 2
    return F, heap, key, pending, pts, cnt


@njit(cache=True, nogil=True, error_model="numpy")
def _refine_and_collapse(z, valid, W, voids, max_error, collapse, F, heap, key, pending, pts,
                         cnt):
    """The refinement (:func:`~geoterrain.lod.tinkernels._refine`, the arrays doubled
    whenever it asks), then the collapse pass, which stops once it has removed the share
    ``collapse`` of the refinement's triangles (0: no pass; 1: no limit, every point
    tried). Returns the half-edge rows, the triangle count and the points."""
    stack = np.empty(1 << 16, np.int32)
    cap = len(heap)
    while True:
        st = _refine(z, valid, W, voids, max_error, F, heap, key, pending, stack, pts, cnt)
        if st == 0:
            break
        if st < 0:
            raise RuntimeError("Delaunay flips deeper than the stack")
        cap *= 2
        F = _grow(F, ROW * cap)
        heap, key, pending = _grow(heap, cap), _grow(key, cap), _grow(pending, cap)
        pts = _grow(pts, cap)
    nt = cnt[NT]
    pts = pts[:cnt[NP]]
    # each collapse removes two triangles
    budget = len(pts) if collapse >= 1.0 else int(np.ceil(collapse * nt / 2.0))
    if budget > 0:
        _decimate(F, nt, pts, z, valid, W, voids, max_error, budget,
                  np.full(valid.size + len(pts), -1, np.int32),
                  np.empty(4 * (MAXDEG + 1), np.int64), np.empty(2 * MAXDEG, np.float64))
    return F, nt, pts


@njit(cache=True, nogil=True, error_model="numpy")
def greedy_tin(z, valid, H, W, max_error, voids, collapse):
    """The greedy TIN of the H × W heights ``z`` (flat, scene units; ``valid`` flat):
    insert the worst sample of the worst triangle until every triangle's error over the
    samples it covers is ≤ ``max_error``, then collapse points while the bound holds, until
    the share ``collapse`` of the triangles is removed (1: every point tried, 0: none;
    :func:`_refine_and_collapse`). Returns the drawn triangles (F, 3) and the
    (row, column) of the points they use (:func:`_compact`). Needs 16·H·W < 2³¹ (int32
    half-edges). The arrays are made and grown here (:func:`_two_triangles`,
    :func:`_refine_and_collapse`); the loops that use them
    (:func:`~geoterrain.lod.tinkernels._refine`, :func:`_decimate`) make none."""
    F, heap, key, pending, pts, cnt = _two_triangles(H, W, 1024)
    F, nt, pts = _refine_and_collapse(z, valid, W, voids, max_error, collapse, F, heap, key,
                                      pending, pts, cnt)
    if voids:  # (skips the triangles the collapse pass removed: their twins are stale)
        _flip_to_cover(F, nt, z, valid, W, max_error)
    return _compact(F, nt, pts, valid, voids, W)

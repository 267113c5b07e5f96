"""The greedy TIN started from given border points (a tile's edge vertices, chosen first).

:func:`greedy_tin_seeded` is :func:`geoterrain.lod.tincollapse.greedy_tin` on a grid
without voids, with the points ``seeds`` (flat sample ids on the rectangle's border)
inserted before the refinement begins, so that the mesh's border is exactly the polyline
through the corners and the seeds. It adds no other border point as long as every border
sample between two consecutive border points lies, within ``max_error``, on the segment
between them: the caller gives the border samples the heights of that polyline
(:func:`geoterrain.export.qmeshtin.tin_tile`), so their error is 0 up to rounding and the
refinement's worst sample is always an interior one. Border points are never collapsed
(the collapse pass takes interior points only).

It uses the refinement's kernels (:mod:`geoterrain.lod.tinkernels`, its loop ``_refine``)
and the collapse pass (:mod:`geoterrain.lod.tincollapse`) unchanged.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.lod.tincollapse import _refine_and_collapse, _two_triangles
from geoterrain.lod.tinkernels import (
    CAND,
    NT,
    ROW,
    _compact,
    _forget,
    _insert,
    _next,
    _orient,
)


@njit(cache=True, nogil=True, error_model="numpy")
def _border_triangle(F, nt, p, W):
    """The triangle whose border edge (twin −1) holds sample ``p`` strictly inside, or −1."""
    px, py = p % W, p // W
    for t in range(nt):
        for k in range(3):
            e = ROW * t + k
            if F[e + 3] >= 0:
                continue
            a, b = F[e], F[_next(e)]
            ax, ay, bx, by = a % W, a // W, b % W, b // W
            if _orient(ax, ay, bx, by, px, py) != 0:
                continue
            if (min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by)
                    and p != a and p != b):
                return t
    return -1


@njit(cache=True, nogil=True, error_model="numpy")
def greedy_tin_seeded(z, H, W, max_error, seeds, collapse):
    """The greedy TIN of the H × W heights ``z`` (flat) within ``max_error``, its border
    points the rectangle's corners and ``seeds`` (flat ids on the border, corners
    excluded). Returns the triangles (F, 3) and the (row, column) of their points."""
    valid = np.ones(z.size, np.bool_)
    cap = 1024
    while cap < 2 * len(seeds) + 16:
        cap *= 2
    F, heap, key, pending, pts, cnt = _two_triangles(H, W, cap)
    stack = np.empty(1 << 16, np.int32)
    for s in seeds:  # on the border: each splits one border edge (Delaunay flips after)
        t = _border_triangle(F, cnt[NT], s, W)
        if t < 0:
            raise RuntimeError("a seed is not on the rectangle's border")
        _forget(t, F, heap, key, pending, cnt)
        F[ROW * t + CAND] = s
        if _insert(t, F, W, heap, key, pending, cnt, stack, pts) < 0:
            raise RuntimeError("Delaunay flips deeper than the stack")
    F, nt, pts = _refine_and_collapse(z, valid, W, False, max_error, collapse, F, heap, key,
                                      pending, pts, cnt)
    return _compact(F, nt, pts, valid, False, W)

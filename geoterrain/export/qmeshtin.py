"""quantized-mesh tiles on the greedy TIN (``tiles --mesher tin``): the kernels.

A tile's mesh is a greedy TIN of its (2^k+1)² lattice (:mod:`geoterrain.lod.tinseeded`),
built in two steps so that neighbouring tiles of a level share their edge vertices
exactly:

1. each of the tile's four edges is simplified alone, as a 1-D polyline through its
   lattice samples (:func:`edge_keep`: Douglas–Peucker within ``tau``, splitting first at
   every change between valid and invalid samples). It reads the edge's samples and
   ``tau`` only, both identical on the two tiles that share the edge (same lon/lat, same
   bilinear heights, ``tau`` fixed per level), and always walks the edge the same way
   (west → east, north → south), so both tiles keep the same samples;
2. the interior is refined with those edge points inserted first and no other edge
   sample added later (:func:`tin_tile`).

The declared error of a TIN tile is measured, not bounded a priori: the largest
``|mesh − DEM|`` over the valid DEM samples inside the tile's rectangle, the mesh being
the tile as a client decodes it (u, v and heights dequantised), located by a bucket grid
and interpolated barycentrically (:func:`measured_error`). Samples in no triangle (in a
hole left for nodata) are not counted, as for the lattice tiles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.export.qmeshformat import QMAX
from geoterrain.lod.tinseeded import greedy_tin_seeded

#: Below max zoom an edge's polyline is simplified within this share of the level's
#: error (the interior threshold of a tile is what its resampling error leaves, and the
#: edge's must not depend on the tile).
EDGE_SHARE = 0.1
MIN_THRESHOLD = 1e-3  # metres: the edge samples' heights are the polyline's to rounding


@njit(cache=True, nogil=True, error_model="numpy")
def edge_keep(h, valid, tau):
    """Which samples of an edge (heights ``h``, ``valid``) its polyline keeps: both ends,
    both sides of every change between valid and invalid samples, and within each valid
    run the Douglas–Peucker points within ``tau`` (the first sample of largest deviation
    splits a segment). Deterministic: the same samples give the same points."""
    n = len(h)
    keep = np.zeros(n, np.bool_)
    keep[0] = keep[n - 1] = True
    stack = np.empty((2 * n + 2, 2), np.int64)
    stack[0, 0], stack[0, 1] = 0, n - 1
    top = 1
    while top > 0:
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        if b - a < 2:
            continue
        m = -1
        for k in range(a + 1, b + 1):  # the first change of validity
            if valid[k] != valid[a]:
                m = k if k < b else k - 1
                break
        if m < 0:
            if not valid[a]:
                continue
            worst = tau
            for k in range(a + 1, b):
                d = abs(h[a] + (h[b] - h[a]) * ((k - a) / (b - a)) - h[k])
                if d > worst:
                    worst, m = d, k
            if m < 0:
                continue
        keep[m] = True
        stack[top, 0], stack[top, 1] = a, m
        stack[top + 1, 0], stack[top + 1, 1] = m, b
        top += 2
    return keep


@njit(cache=True, nogil=True, error_model="numpy")
def _polyline(z, keep):
    """``z`` replaced between kept samples by the straight line through them."""
    out = z.copy()
    a = 0
    for b in range(1, len(z)):
        if keep[b]:
            for k in range(a + 1, b):
                out[k] = z[a] + (z[b] - z[a]) * ((k - a) / (b - a))
            a = b
    return out


def tin_tile(h: np.ndarray, valid: np.ndarray, thr: float, tau: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """The TIN of an M × M lattice (heights ``h``, ``valid``) within ``thr`` inside,
    its edges simplified within ``tau`` first (:func:`edge_keep`). Returns ``ij`` (V, 2)
    lattice rows and columns and ``faces`` (F, 3), only triangles with three valid
    corners; every triangle over an invalid sample is refined away (invalid samples get
    a height far above the data, so no triangle of valid corners spans one and no
    triangle with an invalid corner covers a valid sample but on its far edge)."""
    M = h.shape[0]
    thr = max(float(thr), MIN_THRESHOLD)
    hv = h[valid]
    lo, hi = float(hv.min()), float(hv.max())
    far = hi + 4.0 * (M - 1) ** 2 * (thr + (hi - lo) + 1.0)
    z = np.where(valid, h, far)
    idx = np.arange(M * M).reshape(M, M)
    seeds = []
    # the edges, each walked west → east or north → south (as the neighbour walks it)
    for sl in ((0, slice(None)), (M - 1, slice(None)), (slice(None), 0), (slice(None), M - 1)):
        keep = edge_keep(h[sl], valid[sl], float(tau))
        z[sl] = _polyline(z[sl], keep)
        seeds.append(idx[sl][keep])
    seeds = np.unique(np.concatenate(seeds))
    seeds = seeds[~np.isin(seeds, (0, M - 1, (M - 1) * M, M * M - 1))].astype(np.int64)
    faces, ij = greedy_tin_seeded(np.ascontiguousarray(z).ravel(), M, M, thr, seeds, 1.0)
    ok = valid[ij[:, 0], ij[:, 1]]
    return ij, faces[ok[faces].all(1)]


def hilbert_order(ij: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The order of ``faces`` along a Hilbert curve through their centroids (lattice
    rows, columns ``ij``): consecutive triangles are near each other, so the encoded
    u, v, height and index deltas are small and gzip packs them (the refinement's own
    order is its insertion order, scattered over the tile)."""
    c = ij[faces].sum(1).astype(np.int64)  # 3 × the centroid: integers
    n = 1 << max(int(c.max(initial=1)).bit_length(), 1)
    x, y = c[:, 1].copy(), c[:, 0].copy()
    d = np.zeros(len(c), np.int64)
    s = n >> 1
    while s > 0:
        rx = (x & s) > 0
        ry = (y & s) > 0
        d += s * s * ((3 * rx.astype(np.int64)) ^ ry.astype(np.int64))
        flip = ~ry & rx
        x = np.where(flip, n - 1 - x, x)
        y = np.where(flip, n - 1 - y, y)
        x, y = np.where(~ry, y, x), np.where(~ry, x, y)
        s >>= 1
    return np.argsort(d, kind="stable")


@njit(cache=True, nogil=True, error_model="numpy")
def _located_error(tu, tv, th, faces, pu, pv, ph, order, start, grid):
    """Largest |surface − ph| over the points in some triangle (points bucketed on a
    grid: ``grid`` = (u0, v0, cell width, cell height, columns, rows), and
    ``order[start[c]:start[c + 1]]`` are cell c's points)."""
    u0, v0, cu, cv = grid[0], grid[1], grid[2], grid[3]
    gx, gy = int(grid[4]), int(grid[5])
    worst = 0.0
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, bx, by, cx, cy = tu[a], tv[a], tu[b], tv[b], tu[c], tv[c]
        det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if det == 0:
            continue
        g0 = max(int((min(ax, bx, cx) - u0) / cu) - 1, 0)
        g1 = min(int((max(ax, bx, cx) - u0) / cu) + 1, gx - 1)
        r0 = max(int((min(ay, by, cy) - v0) / cv) - 1, 0)
        r1 = min(int((max(ay, by, cy) - v0) / cv) + 1, gy - 1)
        for r in range(r0, r1 + 1):
            for g in range(g0, g1 + 1):
                k = r * gx + g
                for q in range(start[k], start[k + 1]):
                    p = order[q]
                    x, y = pu[p], pv[p]
                    l1 = ((x - ax) * (cy - ay) - (cx - ax) * (y - ay)) / det
                    l2 = ((bx - ax) * (y - ay) - (x - ax) * (by - ay)) / det
                    l0 = 1.0 - l1 - l2
                    if l0 < -1e-9 or l1 < -1e-9 or l2 < -1e-9:
                        continue
                    d = abs(l0 * th[a] + l1 * th[b] + l2 * th[c] - ph[p])
                    if d > worst:
                        worst = d
    return worst


def measured_error(rect, vlon, vlat, hq, faces, hrange, slon, slat, sh) -> float:
    """Largest |decoded tile − DEM| at the DEM samples (``slon``, ``slat``, ``sh``: valid,
    inside ``rect``) that lie in a triangle of the tile: u, v and heights quantised and
    dequantised as :func:`geoterrain.export.qmeshformat.encode_tile` writes them."""
    if len(slon) == 0 or len(faces) == 0:
        return 0.0
    w, s, e, n = rect
    tu = np.round((vlon - w) / (e - w) * QMAX)
    tv = np.round((vlat - s) / (n - s) * QMAX)
    h0, h1 = hrange
    th = h0 + (h1 - h0) * np.asarray(hq, np.float64) / QMAX
    pu = (slon - w) / (e - w) * QMAX
    pv = (slat - s) / (n - s) * QMAX
    # a bucket grid over the samples' box, about 4 samples a cell
    g = int(np.clip(np.sqrt(len(pu) / 4.0), 1, 1024))
    u0, v0 = float(pu.min()), float(pv.min())
    cu = max((float(pu.max()) - u0) / g, 1e-6) * (1 + 1e-12)
    cv = max((float(pv.max()) - v0) / g, 1e-6) * (1 + 1e-12)
    cell = (np.minimum(((pv - v0) / cv).astype(np.int64), g - 1) * g
            + np.minimum(((pu - u0) / cu).astype(np.int64), g - 1))
    order = np.argsort(cell, kind="stable")
    start = np.searchsorted(cell[order], np.arange(g * g + 1))
    grid = np.array([u0, v0, cu, cv, g, g], np.float64)
    return float(_located_error(tu, tv, th, np.asarray(faces, np.int64), pu, pv,
                                np.asarray(sh, np.float64), order, start, grid))

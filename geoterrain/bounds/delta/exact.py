"""The whole grid's exact, saturated δ (seed 002 §2.3 with the exact diamond maximum,
saturated by §2.4, L46): the blocks' valid/invalid status, the raw δ level by level from
the sweeps of :mod:`geoterrain.bounds.delta.sweeps`, and the saturation."""

from __future__ import annotations

import numpy as np
from numba import prange

from geoterrain.bounds.delta.grid import check_grid
from geoterrain.bounds.delta.sweeps import Beside, _block_sweep, _centre1, edge_delta_nb
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import cores_for, parallel_kernel

__all__ = ["saturate", "vertex_errors"]

# Rows on every core for large grids (errors 0.54 → 0.34 s, radii 0.32 → 0.20 s on the
# quiet 4097² fBm, docs/lab/preprocess.md); small ones run on one thread, where a busy
# core made the barriers cost more than the work (geoterrain/core/threads.py: cores_for).
# Each output is written by one iteration, so the values do not depend on the threads.
# (Each prange kernel is a ParallelKernel: a fork() child runs its serial twin.)


@parallel_kernel(cache=True, nogil=True)
def _block_status_nb(vb, span):
    # bs[centre of a closed 2h block] = bit 1: holds a valid sample, bit 2: an invalid one;
    # built fine to coarse (a closed 2h block is the union of its four closed h blocks),
    # up to blocks of side ``span`` (the square's N − 1, or a root's side).
    R, C = vb.shape
    bs = np.zeros((R, C), np.uint8)
    nr = (R - 1) // 2
    nc = (C - 1) // 2
    for k in prange(nr * nc):
        bi = k // nc
        bj = k - bi * nc
        f = 0
        for di in range(3):
            for dj in range(3):
                f |= 1 if vb[2 * bi + di, 2 * bj + dj] else 2
        bs[2 * bi + 1, 2 * bj + 1] = f
    h = 2
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        q = h // 2
        for k in prange(nr * nc):
            bi = k // nc
            bj = k - bi * nc
            ci = bi * s + h
            cj = bj * s + h
            bs[ci, cj] = (bs[ci - q, cj - q] | bs[ci - q, cj + q]
                          | bs[ci + q, cj - q] | bs[ci + q, cj + q])
        h *= 2
    return bs


@parallel_kernel(cache=True, nogil=True)
def _raw_delta_nb(z, vb, bs, all_valid, span):
    """Raw exact δ, float32 rounded up (+inf for mixed diamonds); ``bs`` the blocks'
    status (:func:`_block_status_nb`; unread when ``all_valid``); vertices of half-span
    below ``span`` (the square's N − 1, or a root's side)."""
    R, C = z.shape
    out = np.zeros((R, C), np.float32)
    QL = np.empty((max((R - 1) // 4, 1), max((C - 1) // 4, 1)))
    QR = np.empty_like(QL)
    QT = np.empty_like(QL)
    QB = np.empty_like(QL)
    h = np.int64(1)  # not a literal 1: the edge sweep compiles once
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        # centres of the 2h blocks (+ quarter maxima for the edge midpoints, h >= 2)
        for bi in prange(nr):
            for bj in range(nc):
                ci = bi * s + h
                cj = bj * s + h
                f = 1 if all_valid else bs[ci, cj]
                main = main_diagonal_nb(bi, bj)
                if f == 1:
                    if h == 1:
                        m = _centre1(z, ci, cj, main)
                    else:
                        m, ml, mr, mt, mb = _block_sweep(z, bi * s, bj * s, s, main)
                        QL[bi, bj] = ml
                        QR[bi, bj] = mr
                        QT[bi, bj] = mt
                        QB[bi, bj] = mb
                    out[ci, cj] = round_up32(m)
                elif f == 3:
                    out[ci, cj] = np.inf
        # edge midpoints: hypotenuse along the rows (typ 0) or along the columns (typ 1)
        for typ in range(2):
            rows = typ == 0
            na = nr if rows else nr + 1
            nb = nc + 1 if rows else nc
            lim = C if rows else R  # the domain's size across the hypotenuse
            for a in prange(na):
                for b in range(nb):
                    ic = h + a * s if rows else a * s
                    jc = b * s if rows else h + b * s
                    # adjacent blocks (lo side, hi side) and their status
                    flo = 0
                    fhi = 0
                    if rows:
                        if jc > 0:
                            flo = 1 if all_valid else bs[ic, jc - h]
                        if jc < C - 1:
                            fhi = 1 if all_valid else bs[ic, jc + h]
                    else:
                        if ic > 0:
                            flo = 1 if all_valid else bs[ic - h, jc]
                        if ic < R - 1:
                            fhi = 1 if all_valid else bs[ic + h, jc]
                    if h >= 2 and rows:
                        qlo = QR[a, b - 1] if flo else 0.0
                        qhi = QL[a, b] if fhi else 0.0
                    elif h >= 2:
                        qlo = QB[a - 1, b] if flo else 0.0
                        qhi = QT[a, b] if fhi else 0.0
                    else:
                        qlo = qhi = 0.0
                    out[ic, jc] = edge_delta_nb(z, vb, ic, jc, h, rows, lim, 0,
                                                Beside(flo, fhi, qlo, qhi), out[ic, jc])
        h *= 2
    return out


@parallel_kernel(cache=True, nogil=True)
def _saturate_pull_nb(d, span):
    # LP §2.4 (L46), rows on every core: each vertex pulls its children's δ, depths fine
    # to coarse (one max per DAG edge; at each h a receiver never gives in the same phase,
    # so the order does not matter; δ ≥ +0.0, no NaN): the centres of h from their 4 edge
    # midpoints of h, then the edge midpoints of 2h (odd (I + J) on the 2h lattice) from
    # the centres of h around.
    R, C = d.shape
    h = 1
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        for a in prange(nr):
            i = h + a * s
            for b in range(nc):
                j = h + b * s
                v = d[i, j]
                for w in (d[i, j - h], d[i, j + h], d[i - h, j], d[i + h, j]):
                    if v < w:
                        v = w
                d[i, j] = v
        for a in prange(nr + 1):
            i = a * s
            for b in range((a + 1) % 2, nc + 1, 2):
                j = b * s
                v = d[i, j]
                for di in (-h, h):
                    for dj in (-h, h):
                        if 0 <= i + di < R and 0 <= j + dj < C and v < d[i + di, j + dj]:
                            v = d[i + di, j + dj]
                d[i, j] = v
        h *= 2
    for i in range(0, R, span):
        for j in range(0, C, span):
            d[i, j] = 0
    return d


def saturate(d: np.ndarray, span: int | None = None) -> np.ndarray:
    """Saturate per-vertex errors in place, fine to coarse, so δ(parent) ≥ δ(child) on
    every bintree edge (seed 002 §2.4, L46); the domain corners (every root's, on a root
    grid of root side ``span``) get 0. Returns ``d``.

    Examples
    --------
    >>> d = np.zeros((3, 3), np.float32); d[0, 1] = 2.0  # an edge midpoint
    >>> float(saturate(d)[1, 1])  # its parent, the centre
    2.0
    >>> d = np.zeros((3, 5), np.float32); d[1, 2] = 2.0  # the edge two roots share
    >>> saturate(d, 2)[1].tolist()  # both roots' centres, its parents
    [0.0, 2.0, 2.0, 2.0, 0.0]
    """
    with cores_for(d.size):  # small grids on one thread
        return _saturate_pull_nb(d, d.shape[0] - 1 if span is None else span)


def _raw_delta(zf: np.ndarray, valid: np.ndarray, span: int | None = None) -> np.ndarray:
    span = zf.shape[0] - 1 if span is None else span
    all_valid = bool(valid.all())
    vb = valid.view(np.uint8)
    bs = np.ones((1, 1), np.uint8) if all_valid else _block_status_nb(vb, span)
    return _raw_delta_nb(zf, vb, bs, all_valid, span)



def vertex_errors(z: np.ndarray, valid: np.ndarray, span: int | None = None) -> np.ndarray:
    """Exact, saturated per-vertex errors δ, float32 (N, N) rounded up (or of a root
    grid's extent, roots of side ``span``: see the module's docstring).

    δ(v) = max over the valid full-resolution samples of v's closed diamond of |z − S|, S
    being the two diamond triangles drawn while v is absent (seed 002 §2.3, but the exact
    maximum, not the midpoint error); +inf if the diamond mixes valid and invalid samples,
    0 if it is all invalid; then saturated so δ(parent) ≥ δ(child) (§2.4, L46). The
    domain corners get 0. Computed by a compiled kernel in O(N² log N).

    Parameters
    ----------
    z : (N, N) float64 heights in scene units, N = 2**n + 1 (invalid values ignored).
    valid : (N, N) bool.
    span : None for the square; a root grid's root side 2**n, ``z`` and ``valid`` then
        (ry·2**n + 1, rx·2**n + 1).

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> d = vertex_errors(z, np.ones((3, 3), bool))
    >>> d.dtype, float(d[1, 1]), float(d[0, 1])
    (dtype('float32'), 2.0, 0.0)
    >>> z = np.zeros((3, 5)); z[1, 3] = 2.0  # the second of 2 × 1 roots of side 2
    >>> vertex_errors(z, np.ones((3, 5), bool), span=2)[1].tolist()
    [0.0, 0.0, 0.0, 2.0, 0.0]
    """
    zf, valid, n = check_grid(z, valid, span)
    with cores_for(zf.size):  # small grids on one thread (geoterrain/core/threads.py)
        return _saturate_pull_nb(_raw_delta(zf, valid, 1 << n), 1 << n)

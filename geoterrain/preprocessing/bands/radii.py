"""The nested radii's 8-bit log codes from per-level arrays, a few rows at a time
(issue 12's streaming preprocess; the whole-grid twin is
:func:`geoterrain.bounds.tileblobs.radius_codes` with ``radius=None``).

Seed 002 §2.4 (L50–52) on the coded values: code(v) is the smallest code ≥ |p_v − p_c| +
table[code(c)] over v's children c, fine to coarse, leaves 0. The heights come from
:func:`geoterrain.preprocessing.bands.delta.band_vertex_errors` (``stand_in`` given: ``ZC{k}``,
``ZR{k}``, ``ZK{k}``); x and y from a projected or pixel frame, where x depends on the
column only and y on the row only. The codes go to ``rC{k}``, ``rR{k}``, ``rK{k}``
(uint8), the same values, bit for bit, as the whole-grid codes at those vertices.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from geoterrain.bounds.radii import code_up_nb
from geoterrain.bounds.vertexdata import log8_exponent, log8_table
from geoterrain.core.threads import parallel_kernel
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["band_radius_codes"]


@parallel_kernel(cache=True)
def _edge_codes_nb(xs, ys, h, rows, a_lo, nb, zv, pz, pc, table, out):
    """Codes of level h's edge midpoints (rows a_lo …; R-type if ``rows``, else K-type)
    from their four child centres at h/2 (``pz``, ``pc``: that level's centre heights
    and codes from row 2·a_lo − 1 on, padded)."""
    s = 2 * h
    q = h // 2
    for ar in prange(zv.shape[0]):
        a = a_lo + ar
        for b in range(zv.shape[1]):
            i = h + a * s if rows else a * s
            j = b * s if rows else h + b * s
            best = 0.0
            for k in range(4):  # child_nb's raster order: (i ∓ q, j ∓ q)
                di = 2 * (k // 2) - 1
                dj = 2 * (k % 2) - 1
                a2 = 2 * a + (k // 2) if rows else 2 * a - 1 + (k // 2)
                b2 = 2 * b - 1 + (k % 2) if rows else 2 * b + (k % 2)
                if 0 <= a2 < 2 * nb and 0 <= b2 < 2 * nb:
                    ci = i + di * q
                    cj = j + dj * q
                    zc = pz[a2 - (2 * a_lo - 1), b2]
                    d = np.sqrt((xs[j] - xs[cj]) ** 2 + (ys[i] - ys[ci]) ** 2
                                + (zv[ar, b] - zc) ** 2) + table[pc[a2 - (2 * a_lo - 1), b2]]
                    best = max(best, d)
            out[ar, b] = code_up_nb(table, best)


@parallel_kernel(cache=True)
def _centre_codes_nb(xs, ys, h, a_lo, zc, zr, zk, cr, ck, table, out):
    """Codes of level h's centres (rows a_lo …) from their block's four edge midpoints:
    up K[a], down K[a + 1], left R[b], right R[b + 1] (child_nb's order)."""
    s = 2 * h
    for ar in prange(zc.shape[0]):
        i = h + (a_lo + ar) * s
        for b in range(zc.shape[1]):
            j = h + b * s
            z = zc[ar, b]
            best = 0.0
            for k in range(4):
                if k < 2:
                    ci, cj, zz, c = i + (2 * k - 1) * h, j, zk[ar + k, b], ck[ar + k, b]
                else:
                    ci, cj, zz, c = i, j + (2 * k - 5) * h, zr[ar, b + k - 2], cr[ar, b + k - 2]
                d = np.sqrt((xs[j] - xs[cj]) ** 2 + (ys[i] - ys[ci]) ** 2
                            + (z - zz) ** 2) + table[c]
                best = max(best, d)
            out[ar, b] = code_up_nb(table, best)


def _nest_levels(sa: ScratchArrays, n: int, xs: np.ndarray, ys: np.ndarray,
                 table: np.ndarray, budget: int) -> bool:
    # one fine-to-coarse pass; True if a code reached 255 (the exponent is too small)
    full = False
    for k in range(n):
        h = 1 << k
        nb = sa.shape(f"ZC{k}")[0]
        step = max(1, budget // (48 * (nb + 1)))
        for a_lo in range(0, nb, step):
            a_hi = min(a_lo + step, nb)
            zr = sa.read(f"ZR{k}", a_lo, a_hi)
            zk = sa.read(f"ZK{k}", a_lo, a_hi + 1)
            cr = np.zeros(zr.shape, np.uint8)  # h = 1: edge midpoints are leaves
            ck = np.zeros(zk.shape, np.uint8)
            if k:
                pz = sa.read_padded(f"ZC{k - 1}", 2 * a_lo - 1, 2 * a_hi + 1)
                pc = sa.read_padded(f"rC{k - 1}", 2 * a_lo - 1, 2 * a_hi + 1)
                _edge_codes_nb(xs, ys, h, True, a_lo, nb, zr, pz, pc, table, cr)
                _edge_codes_nb(xs, ys, h, False, a_lo, nb, zk, pz, pc, table, ck)
            cc = np.empty((a_hi - a_lo, nb), np.uint8)
            _centre_codes_nb(xs, ys, h, a_lo, sa.read(f"ZC{k}", a_lo, a_hi), zr, zk, cr, ck,
                             table, cc)
            full = full or bool((cc == 255).any() or (cr == 255).any() or (ck == 255).any())
            sa.write(f"rC{k}", a_lo, cc)
            sa.write(f"rR{k}", a_lo, cr)
            sa.write(f"rK{k}", a_lo, ck)
    return full


def band_radius_codes(sa: ScratchArrays, N: int, xs: np.ndarray, ys: np.ndarray,
                      lo: float, hi: float, budget: int = 16 << 20) -> int:
    """Nest the radius codes of an (N, N) grid on its per-level arrays in ``sa`` and
    return their exponent ``e`` (log8 table, :func:`geoterrain.bounds.vertexdata.log8_table`).

    Parameters
    ----------
    sa
        Per-level heights from :func:`~geoterrain.preprocessing.bands.delta.band_vertex_errors`
        (called
        with ``heights=True``); the codes are added as ``rC{k}``, ``rR{k}``, ``rK{k}``.
    xs, ys
        Scene x of each column and y of each row (a projected or pixel frame's
        :meth:`~geoterrain.core.frame.Frame.grid_xy`, one row and one column of it).
    lo, hi
        The valid heights' range in scene units (the stand-in lies inside it).
    budget
        Bytes of rows read at a time.

    Examples
    --------
    >>> from geoterrain.preprocessing.bands.delta import band_vertex_errors, rows_of
    >>> from geoterrain.bounds.tileblobs import radius_codes
    >>> z = np.random.default_rng(2).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> d = band_vertex_errors(rows_of(z, v), 9, band=2, heights=True)
    >>> xs = ys = np.arange(9.0)
    >>> e = band_radius_codes(d.arrays, 9, xs, ys, *d.valid_range[:2])
    >>> codes, e2 = radius_codes(*np.meshgrid(xs, ys), z, v)
    >>> e == e2, bool((d.arrays.read("rC0", 0, 4) == codes[1::2, 1::2]).all())
    (True, True)
    """
    n = (N - 1).bit_length() - 1
    xs = np.ascontiguousarray(xs, np.float64)
    ys = np.ascontiguousarray(ys, np.float64)
    # the exponent of radius_codes(radius=None): the root's radius is at most the grid's
    # diagonal plus its relief, two octaves of headroom, at most the header's 127
    span = [max(c[0], c[-1]) - min(c[0], c[-1]) for c in (xs, ys)]
    peak = float(np.hypot(*span) + np.float64(hi) - np.float64(lo))
    e = min(log8_exponent(np.array([peak])) + 2, 127)
    for k in range(n):
        for x in "CRK":
            sa.create(f"r{x}{k}", sa.shape(f"Z{x}{k}"), np.uint8)
    while True:
        if not _nest_levels(sa, n, xs, ys, log8_table(e).astype(np.float64), budget) \
                or e >= 127:
            return e
        e = min(e + 4, 127)

"""The metric terms of a curvilinear grid read in row bands (issue 45: geographic rasters
streamed; the whole-grid twin is :func:`geoterrain.bounds.curvature.metric_terms`).

Each term of a vertex is a maximum (or an OR) over the samples of the (up to) two
triangles drawn while it is absent (:mod:`geoterrain.bounds.curvature`): pass 1 over the
triangle's own index box (its largest displacement from the affine map of its corners,
which sets its search margin m, and its border bulges), then pass 2 over the box ± m
(the largest error and distance). Both passes are the whole-grid kernels
(:func:`~geoterrain.bounds.curvature._tri_own`, ``_tri_search``) on a range of rows, and
a maximum over rows is exact, so the split changes no bit:

- **fine levels** (2h ≤ band): a band's window (its rows and a halo of half a band and a
  few rows) holds every triangle of the vertices on its rows and, unless its margin is
  wide, the triangle's search box: both passes run there. A triangle whose search box
  leaves the window (a sliver next to a pole, say) is *deferred*;
- **coarse levels** (h ≥ band) and deferred triangles go in a list with their corners
  (a coarse level's corners lie on rows and columns that are multiples of the band, read
  by a first pass): a sweep adds each band's rows to every listed triangle's pass 1,
  then a second sweep, once the margins are known, to its pass 2.

The terms go to per-level arrays (``dm{x}{k}``, ``rm{x}{k}`` float64, ``b{x}{k}`` uint8
for x in C, R, K: :mod:`geoterrain.preprocessing.bands.delta`'s vertex kinds), the values
of the whole-grid terms at those vertices, bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.curvature import (
    BORDER_FRACTION,
    MetricGrid,
    _grid_rows,
    _same_as_base,
    _tri_make,
    _tri_margin,
    _tri_own,
    _tri_search,
)
from geoterrain.bounds.edgepad import _reaches_data
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.threads import parallel_kernel
from geoterrain.preprocessing.bands.delta import grid_shape
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["BandTerms", "RowCache", "band_metric_terms"]

Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]
XY = Callable[[int, int], tuple[np.ndarray, np.ndarray]]

KINDS = "CRK"
HALO_EXTRA = 8  # rows of halo past half a band: a fine triangle's margin up to this fits


class VertexTerms(NamedTuple):
    """One kind of vertex's terms on a band's rows (:class:`LevelTerms`): δ_m ``dm``, r_m
    ``rm``, the bulge flag ``bulge``, and per triangle the margin of a *deferred* one
    ``defer`` (rows, cols, 2; 0 where the search ran here), and the largest margin ``m``
    met (one entry per row)."""

    dm: np.ndarray
    rm: np.ndarray
    bulge: np.ndarray
    defer: np.ndarray
    m: np.ndarray


class LevelTerms(NamedTuple):
    """A fine level's :class:`VertexTerms` per kind: block centres ``C``, edge midpoints
    ``R`` (hypotenuse along the rows) and ``K`` (along the columns)."""

    C: VertexTerms
    R: VertexTerms
    K: VertexTerms


class Span(NamedTuple):
    """Which vertices a fine kernel visits: the level's half-span ``h``, its first block
    row ``a0``, the band's core rows ``r0`` … ``r_end``, and for δ_edge's terms over a
    replicated grid the base's largest margin ``M`` (−1: none, every vertex is computed)."""

    h: int
    a0: int
    r0: int
    r_end: int
    M: int


class TriList(NamedTuple):
    """Triangles carried across bands: per triangle the vertex and corner indices ``idx``
    (vi, vj, ai, aj, bi, bj, ci, cj), the corners' and the vertex's scene positions
    ``pos`` (12 floats), the running maxima ``acc`` (displacement, displacement on the
    data window's edge, error, distance), the bulge flag and the margin ``m`` (−1 until
    pass 1 is complete)."""

    idx: np.ndarray
    pos: np.ndarray
    acc: np.ndarray
    bulge: np.ndarray
    m: np.ndarray


@njit(cache=True, inline="always")
def _vertex_tri(i, j, h, kind, k, R, C):
    """(ok, ai, aj, bi, bj, ci, cj): triangle ``k`` (0, 1) of vertex (i, j) of half-span h
    and ``kind`` (0 centre, 1 edge midpoint along the rows, 2 along the columns), in the
    corner order of :func:`geoterrain.bounds.curvature._vertex_terms` (not ok: the apex is
    outside the R × C grid: the square's N × N, or a root grid's extent)."""
    s = 2 * h
    if kind == 0:
        i0, j0 = i - h, j - h
        if main_diagonal_nb(i // s, j // s):
            # diagonal (i0, j0)–(i0+s, j0+s), apex (i0, j0+s) / (i0+s, j0)
            return True, i0, j0, i0 + s, j0 + s, i0 + k * s, j0 + (1 - k) * s
        return True, i0, j0 + s, i0 + s, j0, i0 + k * s, j0 + k * s
    if kind == 1:  # hypotenuse (i ± h, j), apex (i, j ± h)
        ci, cj = i, j + (2 * k - 1) * h
        ea, eb, fa, fb = i - h, j, i + h, j
    else:
        ci, cj = i + (2 * k - 1) * h, j
        ea, eb, fa, fb = i, j - h, i, j + h
    return (0 <= ci < R and 0 <= cj < C), ea, eb, fa, fb, ci, cj


@njit(cache=True, inline="always")
def _kind_at(h, kind, a, b):
    # grid (i, j) of vertex (a, b) of a level's kind
    s = 2 * h
    if kind == 0:
        return h + a * s, h + b * s
    if kind == 1:
        return h + a * s, b * s
    return a * s, h + b * s


@njit(cache=True)
def _fine_vertex(g, sp, kind, a, b, out):
    # one vertex of _fine_level_nb: its triangles' passes in the window, or deferred
    h, R, C = sp.h, _grid_rows(g), g.vb.shape[1]
    w0, w1 = g.w0, g.w0 + g.vb.shape[0] - 1
    i, j = _kind_at(h, kind, a, b)
    ar = a - sp.a0
    if not _reaches_data(i, j, g.wi, g.wj) or _same_as_base(i, j, h, sp.M, g.wi, g.wj):
        return  # 0, or the base's (merged after)
    vb = g.vb
    for k in range(2):
        ok, ai, aj, bi, bj, ci, cj = _vertex_tri(i, j, h, kind, k, R, C)
        if not ok or not (vb[ai - w0, aj] and vb[bi - w0, bj] and vb[ci - w0, cj]):
            continue
        X, Y, Z = g.X, g.Y, g.Z
        p = (X[ai - w0, aj], Y[ai - w0, aj], Z[ai - w0, aj], X[bi - w0, bj],
             Y[bi - w0, bj], Z[bi - w0, bj], X[ci - w0, cj], Y[ci - w0, cj], Z[ci - w0, cj],
             X[i - w0, j], Y[i - w0, j], Z[i - w0, j])
        good, T = _tri_make(i, j, ai, aj, bi, bj, ci, cj, p, g.frac)
        if not good:
            continue
        disp, dwin, bulge = _tri_own(g, T, T.i0, T.i1, True)
        m = _tri_margin(T, disp, max(R, C))
        if bulge or dwin > 0.5 * g.frac * T.smin:
            out.bulge[ar, b] = 1
        out.m[ar] = max(out.m[ar], m)
        if max(T.i0 - m, 0) < w0 or min(T.i1 + m, R - 1) > w1:
            out.defer[ar, b, k] = m  # its search box leaves the window: a later sweep
            continue
        e, r = _tri_search(g, T, m, w0, w1)
        out.dm[ar, b] = max(out.dm[ar, b], e)
        out.rm[ar, b] = max(out.rm[ar, b], r)


@parallel_kernel(cache=True)
def _fine_level_nb(g, sp, out):
    """The terms of a fine level's vertices on the band's core rows (``sp``, :class:`Span`)
    from the window ``g`` (:class:`MetricGrid` of rows ``g.w0`` …) into ``out``
    (:class:`LevelTerms`: rows from block row ``sp.a0``)."""
    # each array bound alone outside the parallel loop: a parfor takes no tuple of arrays
    c0, c1, c2, c3, c4 = out.C
    r0, r1, r2, r3, r4 = out.R
    k0, k1, k2, k3, k4 = out.K
    nC, nK = c0.shape[0], k0.shape[0]
    for ar in prange(max(nC, nK)):
        a = sp.a0 + ar
        if ar < nC:
            for b in range(c0.shape[1]):
                _fine_vertex(g, sp, 0, a, b, VertexTerms(c0, c1, c2, c3, c4))
            for b in range(r0.shape[1]):
                _fine_vertex(g, sp, 1, a, b, VertexTerms(r0, r1, r2, r3, r4))
        if ar < nK:
            for b in range(k0.shape[1]):
                _fine_vertex(g, sp, 2, a, b, VertexTerms(k0, k1, k2, k3, k4))


@njit(cache=True, inline="always")
def _listed(tl, t, frac):
    i = tl.idx[t]
    return _tri_make(i[0], i[1], i[2], i[3], i[4], i[5], i[6], i[7],
                     (tl.pos[t, 0], tl.pos[t, 1], tl.pos[t, 2], tl.pos[t, 3], tl.pos[t, 4],
                      tl.pos[t, 5], tl.pos[t, 6], tl.pos[t, 7], tl.pos[t, 8], tl.pos[t, 9],
                      tl.pos[t, 10], tl.pos[t, 11]), frac)


@parallel_kernel(cache=True)
def _list_own_nb(g, tl, r_lo, r_hi):
    """Pass 1 of the listed triangles still without a margin, on grid rows r_lo … r_hi
    of ``g``, added to their running maxima."""
    acc = tl.acc  # bound outside the parallel loop (see bounds.tileblobs._level_payloads)
    flags = tl.bulge
    for t in prange(tl.idx.shape[0]):
        if tl.m[t] >= 0:
            continue
        _, T = _listed(tl, t, g.frac)
        if T.i1 < r_lo or T.i0 > r_hi:
            continue
        disp, dwin, bulge = _tri_own(g, T, r_lo, r_hi, True)
        acc[t, 0] = max(acc[t, 0], disp)
        acc[t, 1] = max(acc[t, 1], dwin)
        if bulge:
            flags[t] = True


@njit(cache=True)
def _list_margins_nb(tl, frac, N):
    # the margins once pass 1 has seen every row (whole-grid _tri_term's m and bulge); N:
    # the grid's samples on its longer side
    for t in range(tl.idx.shape[0]):
        if tl.m[t] >= 0:
            continue
        _, T = _listed(tl, t, frac)
        tl.m[t] = _tri_margin(T, tl.acc[t, 0], N)
        if tl.acc[t, 1] > 0.5 * frac * T.smin:
            tl.bulge[t] = True


@parallel_kernel(cache=True)
def _list_search_nb(g, tl, r_lo, r_hi):
    """Pass 2 of every listed triangle on grid rows r_lo … r_hi of ``g``."""
    R = _grid_rows(g)
    acc = tl.acc
    for t in prange(tl.idx.shape[0]):
        _, T = _listed(tl, t, g.frac)
        m = tl.m[t]
        if min(T.i1 + m, R - 1) < r_lo or max(T.i0 - m, 0) > r_hi:
            continue
        e, r = _tri_search(g, T, m, r_lo, r_hi)
        acc[t, 2] = max(acc[t, 2], e)
        acc[t, 3] = max(acc[t, 3], r)


@njit(cache=True)
def _coarse_tris_nb(lat, step, h, R, C, wi, wj, M, frac):
    """The triangles of a coarse level's vertices (h ≥ ``step``) of the R × C grid whose
    corners are all valid, with their positions from the lattice ``lat`` (X, Y, Z, vb
    every ``step`` samples: :class:`MetricGrid` of the lattice); (idx, pos)."""
    s = 2 * h
    nbr = (R - 1) // s
    nbc = (C - 1) // s
    n = 0
    idx = np.zeros((6 * (nbr + 1) * (nbc + 1), 8), np.int64)
    pos = np.zeros((idx.shape[0], 12))
    for kind in range(3):
        na = nbr if kind < 2 else nbr + 1
        nc = nbc + 1 if kind == 1 else nbc
        for a in range(na):
            for b in range(nc):
                i, j = _kind_at(h, kind, a, b)
                if not _reaches_data(i, j, wi, wj) or _same_as_base(i, j, h, M, wi, wj):
                    continue
                for k in range(2):
                    ok, ai, aj, bi, bj, ci, cj = _vertex_tri(i, j, h, kind, k, R, C)
                    if not ok:
                        continue
                    q = ((ai // step, aj // step), (bi // step, bj // step),
                         (ci // step, cj // step), (i // step, j // step))
                    if not (lat.vb[q[0]] and lat.vb[q[1]] and lat.vb[q[2]]):
                        continue
                    p = np.zeros(12)
                    for c in range(4):
                        p[3 * c] = lat.X[q[c]]
                        p[3 * c + 1] = lat.Y[q[c]]
                        p[3 * c + 2] = lat.Z[q[c]]
                    good, _ = _tri_make(i, j, ai, aj, bi, bj, ci, cj,
                                        (p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8],
                                         p[9], p[10], p[11]), frac)
                    if not good:
                        continue
                    for c, v in enumerate((i, j, ai, aj, bi, bj, ci, cj)):
                        idx[n, c] = v
                    pos[n] = p
                    n += 1
    return idx[:n], pos[:n]


def _tri_list(idx: np.ndarray, pos: np.ndarray, m: np.ndarray | None = None) -> TriList:
    n = len(idx)
    return TriList(np.ascontiguousarray(idx, np.int64).reshape(n, 8),
                   np.ascontiguousarray(pos, np.float64).reshape(n, 12), np.zeros((n, 4)),
                   np.zeros(n, np.bool_),
                   np.full(n, -1, np.int64) if m is None else np.asarray(m, np.int64))


class RowCache:
    """A sliding window of grid rows (heights, validity, scene x, y) for bands read in
    order: the rows a new window shares with the last one are kept, the rest read. The
    rows live in one buffer per quantity, shifted in place, so a window costs its own
    rows once (not the last window's as well); a window handed out is valid until the
    next call. ``N``: the grid's side, or a root grid's extent (rows, cols);
    ``capacity``: the most rows a window will have (the buffers' rows at the first call;
    a larger window reallocates them)."""

    def __init__(self, rows: Rows, xy: XY, N: int | tuple[int, int], frac: float,
                 window: tuple[int, int], capacity: int = 0):
        self.R, self.N = grid_shape(N)  # rows; columns (the buffers' width)
        self.rows, self.xy, self.frac, self.window = rows, xy, frac, window
        self.capacity = min(capacity, self.R)
        self.w0, self.n = 0, 0
        self.buf: list[np.ndarray] = []  # X, Y, Z (invalid 0), valid

    def get(self, i0: int, i1: int) -> MetricGrid:
        """Rows i0 … i1 − 1 (i0 never below the last call's)."""
        n = i1 - i0
        off = i0 - self.w0
        keep = min(self.n - off, n) if self.n and 0 <= off < self.n else 0
        if not self.buf or len(self.buf[0]) < n:
            old, m = self.buf, max(n, self.capacity)
            self.buf = [np.empty((m, self.N)) for _ in range(3)] + [np.empty((m, self.N), bool)]
            for a, b in zip(self.buf, old, strict=False):
                a[:keep] = b[off:off + keep]
        elif keep and off:  # forward, in chunks of at most off rows: no chunk overlaps
            for b in self.buf:
                for c in range(0, keep, off):
                    b[c:min(c + off, keep)] = b[off + c:off + min(c + off, keep)]
        X_, Y_, Z_, V_ = self.buf
        if n > keep:
            z, v = self.rows(i0 + keep, i1)
            X, Y = self.xy(i0 + keep, i1)
            V_[keep:n] = np.asarray(v, bool) & np.isfinite(z)
            X_[keep:n] = X
            Y_[keep:n] = Y
            del X, Y, v
            np.copyto(Z_[keep:n], 0.0)  # np.where(valid, z, 0.0) without a temporary
            np.copyto(Z_[keep:n], np.asarray(z, np.float64), where=V_[keep:n])
            del z
        self.w0, self.n = i0, n
        return MetricGrid(X_[:n], Y_[:n], Z_[:n], V_[:n], float(self.frac),
                          int(self.window[0]), int(self.window[1]), int(i0), int(self.R))


class BandTerms(NamedTuple):
    """The per-level terms of :func:`band_metric_terms` in ``arrays`` (prefix ``pre``) and
    the largest search margin ``M`` (whole-grid ``metric_terms``' fourth value)."""

    arrays: ScratchArrays
    pre: str
    M: int


def band_metric_terms(rows: Rows, xy: XY, N: int | tuple[int, int], band: int,
                      scratch: ScratchArrays, pre: str = "", frac: float = BORDER_FRACTION,
                      window: tuple[int, int] | None = None,
                      base: BandTerms | None = None, span: int | None = None,
                      empty_from: int | None = None) -> BandTerms:
    """:func:`geoterrain.bounds.curvature.metric_terms` of an (N, N) grid (or a root grid's
    (R, C) extent, with ``span``) read ``band`` rows at a time, into per-level arrays of
    ``scratch`` named ``{pre}dm{x}{k}``, ``{pre}rm{x}{k}`` and ``{pre}b{x}{k}``.

    Parameters
    ----------
    rows, xy
        ``rows(i0, i1)`` → (scene heights, valid) and ``xy(i0, i1)`` → (scene X, Y) of
        grid rows i0 … i1 − 1, each (i1 − i0, N) (a root grid: (i1 − i0, C)).
    N, band
        Grid side 2**n + 1, or a root grid's extent (R, C); rows per band, a power of
        two ≥ 2 (clipped to the root's side).
    window, base
        As ``metric_terms``' (δ_edge over a replicated grid): the vertices whose every
        triangle reads data samples only take the base's terms.
    span
        A root grid's root side 2**n (``N`` then its extent, (ry·span + 1, rx·span + 1)):
        ``metric_terms`` with ``span``, the vertices of half-span below it. None: the
        square.
    empty_from
        A row from which on ``rows`` holds no valid sample (a root grid's padding below
        the raster: its rows). The bands from there on have no terms (0, as the arrays
        start: each of a vertex's triangles has a corner on its row or below), so they
        are neither computed nor read unless a listed triangle's box reaches them; the
        values are the same. None: every band is computed.

    Examples
    --------
    >>> from geoterrain.bounds.curvature import metric_terms
    >>> I, J = np.indices((17, 17)).astype(float)
    >>> X, Y = 100 * J + (I - 8) ** 2, -100 * I  # bowed rows: a curvilinear grid
    >>> Z = np.sin(I) * 5 + J; v = np.ones_like(Z, bool)
    >>> bt = band_metric_terms(lambda a, b: (Z[a:b], v[a:b]), lambda a, b: (X[a:b], Y[a:b]),
    ...                        17, 4, ScratchArrays())
    >>> dm, rm, bulge, M = metric_terms(X, Y, Z, v)
    >>> bool((bt.arrays.read("dmC0", 0, 8) == dm[1::2, 1::2]).all()), bt.M == M
    (True, True)
    >>> X2, Y2 = 100 * J[:9] + (I[:9] - 4) ** 2, -100 * I[:9]  # 2 × 1 roots of side 8
    >>> Z2, v2 = Z[:9], v[:9]
    >>> bt = band_metric_terms(lambda a, b: (Z2[a:b], v2[a:b]),
    ...                        lambda a, b: (X2[a:b], Y2[a:b]), (9, 17), 2, ScratchArrays(),
    ...                        span=8)
    >>> dm, rm, bulge, M = metric_terms(X2, Y2, Z2, v2, span=8)
    >>> bool((bt.arrays.read("rmK1", 0, 3) == rm[::4, 2::4]).all()), bt.M == M
    (True, True)
    """
    if band < 2 or band & (band - 1):
        raise ValueError(f"band must be a power of two ≥ 2, got {band}")
    R, C = grid_shape(N)
    if span is None and R != C:
        raise ValueError(f"a {R} × {C} grid needs span, its roots' side")
    S = R - 1 if span is None else int(span)
    if (R - 1) % S or (C - 1) % S:
        raise ValueError(f"a {R} × {C} grid is not square roots of side {S}")
    n = S.bit_length() - 1
    B = min(band, S)
    nbands = (R - 1) // B
    win = (R, C) if window is None else (int(window[0]), int(window[1]))
    M0 = -1 if base is None else int(base.M)
    sa = scratch
    for k in range(n):
        nbr, nbc = (R - 1) >> (k + 1), (C - 1) >> (k + 1)
        for x, shape in zip(KINDS, ((nbr, nbc), (nbr, nbc + 1), (nbr + 1, nbc)), strict=True):
            sa.create(f"{pre}dm{x}{k}", shape, np.float64)
            sa.create(f"{pre}rm{x}{k}", shape, np.float64)
            sa.create(f"{pre}b{x}{k}", shape, np.uint8)
    nfine = B.bit_length() - 1  # levels h = 1 … B/2
    # the coarse levels' corners: the grid every B samples (one row read per B rows)
    lat = [[], [], [], []]
    for i in range(0, R, B):
        z, v = rows(i, i + 1)
        X, Y = xy(i, i + 1)
        v = np.asarray(v, bool) & np.isfinite(z)
        for part, a in zip(lat, (X, Y, np.where(v, z, 0.0), v), strict=True):
            part.append(np.asarray(a)[0, ::B])
    lattice = MetricGrid(*(np.ascontiguousarray(np.stack(p)) for p in lat), float(frac),
                         win[0], win[1], 0)
    coarse = [_coarse_tris_nb(lattice, B, 1 << k, R, C, win[0], win[1], M0, float(frac))
              for k in range(nfine, n)]
    tl = _tri_list(np.concatenate([c[0] for c in coarse] + [np.zeros((0, 8), np.int64)]),
                   np.concatenate([c[1] for c in coarse] + [np.zeros((0, 12))]))
    M = 0
    deferred: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    halo = B // 2 + HALO_EXTRA
    cache = RowCache(rows, xy, (R, C), frac, win, capacity=B + 2 * halo + 1)
    own = _listed_rows(tl, 0)  # the rows pass 1 of the listed triangles reads
    for kb in range(nbands):
        r0 = kb * B
        last = kb == nbands - 1
        r_end = R - 1 if last else r0 + B - 1
        if empty_from is not None and r0 >= empty_from and not _reads(own, r0, r_end):
            # each triangle of a vertex on row i has a corner on row i or below (the ends
            # of its hypotenuse: i ± h, or i itself), invalid here: _fine_vertex gives the
            # band's vertices nothing, and no listed triangle reads its rows
            continue
        g = cache.get(max(0, r0 - halo), min(R, r_end + 1 + halo))
        for k in range(nfine):
            h = 1 << k
            s = 2 * h
            nb = (C - 1) // s  # blocks across
            nrow = B // s
            nk = nrow + (1 if last else 0)
            out = LevelTerms(*(VertexTerms(np.zeros((r, c)), np.zeros((r, c)),
                                           np.zeros((r, c), np.uint8),
                                           np.zeros((r, c, 2), np.int64),
                                           np.zeros(r, np.int64))
                               for r, c in ((nrow, nb), (nrow, nb + 1), (nk, nb))))
            _fine_level_nb(g, Span(h, r0 // s, r0, r_end, M0), out)
            for x, vt in zip(KINDS, out, strict=True):
                sa.write(f"{pre}dm{x}{k}", r0 // s, vt.dm)
                sa.write(f"{pre}rm{x}{k}", r0 // s, vt.rm)
                sa.write(f"{pre}b{x}{k}", r0 // s, vt.bulge)
                M = max(M, int(vt.m.max(initial=0)))
                if vt.defer.any():
                    deferred.append(_deferred(g, h, "CRK".index(x), r0 // s, vt.defer))
            del out, vt  # before the next level's are allocated
        if len(tl.idx):
            _list_own_nb(g, tl, r0, r_end)
    del g, cache  # the window's buffers
    _list_margins_nb(tl, float(frac), max(R, C))
    if len(tl.m):
        M = max(M, int(tl.m.max()))
    if deferred:  # their pass 1 (and bulge) ran in their band's window
        bulge = np.concatenate([tl.bulge] + [np.zeros(len(d[2]), np.bool_) for d in deferred])
        tl = _tri_list(np.concatenate([tl.idx] + [d[0] for d in deferred]),
                       np.concatenate([tl.pos] + [d[1] for d in deferred]),
                       np.concatenate([tl.m] + [d[2] for d in deferred]))._replace(bulge=bulge)
    if len(tl.idx):
        cache = RowCache(rows, xy, (R, C), frac, win, capacity=B + 1)
        search = _listed_rows(tl, 1)
        for kb in range(nbands):
            r0 = kb * B
            r_end = R - 1 if kb == nbands - 1 else r0 + B - 1
            if _reads(search, r0, r_end):  # else _list_search_nb skips every triangle
                _list_search_nb(cache.get(r0, r_end + 1), tl, r0, r_end)
        _fold(sa, pre, tl, n)
    if base is not None:
        _merge_base(sa, pre, base, n, win)
    return BandTerms(sa, pre, M)


def _listed_rows(tl: TriList, search: int) -> tuple[np.ndarray, np.ndarray]:
    # rows each listed triangle's pass reads, as bounds that hold them (lo, hi): pass 1
    # (search 0) of those still without a margin, over their corners' rows (the index box
    # of _tri_make, or its one row when degenerate); pass 2 (search 1) over that box ±
    # the margin (_list_search_nb)
    rows = tl.idx[:, 2:7:2]  # a, b and c's rows (_listed's order)
    lo, hi = rows.min(axis=1, initial=np.iinfo(np.int64).max), rows.max(axis=1, initial=-1)
    if search:
        return lo - tl.m, hi + tl.m
    todo = tl.m < 0
    return lo[todo], hi[todo]


def _reads(rows: tuple[np.ndarray, np.ndarray], r0: int, r1: int) -> bool:
    # whether a triangle's rows (_listed_rows) meet rows r0 … r1
    lo, hi = rows
    return bool(np.any((lo <= r1) & (hi >= r0)))


def _deferred(g: MetricGrid, h: int, kind: int, a0: int, defer: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # the deferred triangles of one kind's rows: their corners (in the window) and margins
    ar, b, k = np.nonzero(defer)
    idx = np.zeros((len(ar), 8), np.int64)
    pos = np.zeros((len(ar), 12))
    R, C = g.nr if g.nr >= 0 else g.vb.shape[1], g.vb.shape[1]
    for t, (a_, b_, k_) in enumerate(zip(ar.tolist(), b.tolist(), k.tolist(), strict=True)):
        i, j = _kind_at(h, kind, a0 + a_, b_)
        _, ai, aj, bi, bj, ci, cj = _vertex_tri(i, j, h, kind, k_, R, C)
        idx[t] = (i, j, ai, aj, bi, bj, ci, cj)
        for c, (pi, pj) in enumerate(((ai, aj), (bi, bj), (ci, cj), (i, j))):
            pos[t, 3 * c:3 * c + 3] = (g.X[pi - g.w0, pj], g.Y[pi - g.w0, pj],
                                       g.Z[pi - g.w0, pj])
    return idx, pos, defer[ar, b, k]


def _fold(sa: ScratchArrays, pre: str, tl: TriList, n: int) -> None:
    # each listed triangle's error, distance and bulge into its vertex's arrays (maxima)
    vi, vj = tl.idx[:, 0], tl.idx[:, 1]
    low = (vi | vj) & -(vi | vj)  # h, the lowest set bit
    for k in range(n):
        h = 1 << k
        s = 2 * h
        at = low == h
        if not at.any():
            continue
        for x in range(3):
            odd_i = (vi // h) % 2 == 1
            odd_j = (vj // h) % 2 == 1
            sel = at & ((odd_i & odd_j) if x == 0 else (odd_i & ~odd_j) if x == 1
                        else (~odd_i & odd_j))
            if not sel.any():
                continue
            a, b = vi[sel] // s, vj[sel] // s
            vals = (tl.acc[sel, 2], tl.acc[sel, 3], tl.bulge[sel].astype(np.uint8))
            for lo in np.unique(a // 256) * 256:  # a few rows of the arrays at a time
                here = (a >= lo) & (a < lo + 256)
                for arr, v in zip(("dm", "rm", "b"), vals, strict=True):
                    name = f"{pre}{arr}{KINDS[x]}{k}"
                    blk = np.array(sa.read(name, lo, lo + 256))
                    np.maximum.at(blk, (a[here] - lo, b[here]), v[here])
                    sa.write(name, int(lo), blk)


def _merge_base(sa: ScratchArrays, pre: str, base: BandTerms, n: int,
                win: tuple[int, int], step_samples: int = 1 << 18) -> None:
    # the vertices that read data samples only: the base's δ_m and bulge (metric_terms),
    # ``step_samples`` of an array at a time (rows of any width)
    wi, wj = win
    M = base.M
    for k in range(n):
        h = 1 << k
        s = 2 * h
        for kind, x in enumerate(KINDS):
            nr, nc = sa.shape(f"{pre}dm{x}{k}")
            step_rows = max(1, step_samples // max(nc, 1))
            b = np.arange(nc)
            for a0 in range(0, nr, step_rows):
                a = np.arange(a0, min(a0 + step_rows, nr))
                i = (h + a * s if kind < 2 else a * s)[:, None]
                j = (b * s if kind == 1 else h + b * s)[None, :]
                same = (M >= 0) & (i + h + M <= wi - 1) & (j + h + M <= wj - 1)
                if not same.any():
                    continue
                for arr in ("dm", "b"):
                    mine = np.array(sa.read(f"{pre}{arr}{x}{k}", a0, a0 + len(a)))
                    theirs = base.arrays.read(f"{base.pre}{arr}{x}{k}", a0, a0 + len(a))
                    sa.write(f"{pre}{arr}{x}{k}", a0, np.where(same, theirs, mine))

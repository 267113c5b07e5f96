"""δ and r that hold in the scene's metric x/y on curvilinear (geographic) grids.

:func:`geoterrain.bounds.delta.vertex_errors` bounds the vertical error of a mesh interpolated in
grid-index space. A geographic grid maps to the scene curvilinearly (pyproj, see
:mod:`geoterrain.core.frame`), while the mesh is drawn with straight edges between its
vertices' metric positions. A sample's metric position then differs from the barycentric
position its grid indices imply (by about the sagitta of the triangle's curved edges), so
a sample is interpolated by the triangle that holds it *in metres*, which may be a
neighbour, and a curved domain border may bulge outside a coarse triangle's chord.

This module makes δ bound the error as seen in metres, with the same argument as the
index-space δ (seed 002 §2.3): a drawn triangle T is a leaf whose split vertex v is
inactive, so every sample that T holds must be within δ(v) of T's plane. Per vertex v and
each of the (up to) two triangles drawn while v is absent:

- δ_m(v) = max |z_s − S_T(X_s, Y_s)| over the valid samples s whose scene (X, Y) lies in
  T's metric triangle, widened by a band of ``2 · frac`` sample spacings (S_T: T's plane,
  extended). Samples are searched in T's index box widened by the largest displacement
  |P_s − A_T(s)| of T's own samples (A_T: the affine map of T's corners), in samples,
  plus two.
- If a valid sample of T lies beyond a chord of T on the domain border by more than
  ``frac / 2`` of a sample spacing, δ(v) = +inf: the border is refined until its chords
  follow the curve to within that fraction, so no valid sample is left outside the mesh.
- r_m(v) = max |p_v − p_s| over the same samples, so the nested spheres (LP §2.4) still
  hold every sample v's triangles can be measured at.

Then δ = saturate(max(δ, δ_m)) and r = nest(max(r, r_m)), both float32 rounded up.
The extra term is computed only for geographic frames: projected and pixel grids are
affine, their δ and r are left bit-identical.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import saturate
from geoterrain.bounds.edgepad import _reaches_data
from geoterrain.bounds.radii import _proxy_positions
from geoterrain.core.bintree import child_nb, main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import cores_for, parallel_kernel

__all__ = ["BORDER_FRACTION", "metric_bounds", "metric_terms"]

#: Chords on the domain border follow the curved border to this fraction of a spacing.
BORDER_FRACTION = 0.01


class MetricGrid(NamedTuple):
    """A curvilinear grid, or a window of its rows, as the metric kernels read it: scene
    ``X``, ``Y``, heights ``Z`` (0 where invalid) and validity ``vb`` of the grid rows
    ``w0`` … (every column of the (N, N) grid, or of a root grid's (R, C) extent), the
    border fraction ``frac``, the data window ``wi × wj`` a static mesh is clipped to
    (N × N or R × C: none), and the grid's rows ``nr`` (−1: as many as its columns, the
    square)."""

    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    vb: np.ndarray
    frac: float
    wi: int
    wj: int
    w0: int = 0
    nr: int = -1


@njit(cache=True, inline="always")
def _grid_rows(g):
    # the whole grid's rows: the square's N (its columns) unless given
    return g.nr if g.nr >= 0 else g.X.shape[1]


class Tri(NamedTuple):
    """A triangle (a, b, c) drawn while vertex v is absent, as the row kernels read it:
    corner and vertex indices and scene positions, its index box ``i0 … i1 × j0 … j1``,
    and the terms of its affine maps (index space → metric plane, :func:`_tri_make`)."""

    ai: int
    aj: int
    bi: int
    bj: int
    ci: int
    cj: int
    vi: int
    vj: int
    ax: float
    ay: float
    az: float
    bx: float
    by: float
    bz: float
    cx: float
    cy: float
    cz: float
    vx: float
    vy: float
    vz: float
    m11: float
    m12: float
    m21: float
    m22: float
    smin: float
    la: float
    lb: float
    lc: float
    area2: float
    ta: float
    tb: float
    tc: float
    inv: float
    i0: int
    i1: int
    j0: int
    j1: int


@njit(cache=True, inline="always")
def _tri_make(vi, vj, ai, aj, bi, bj, ci, cj, p, frac):
    """(ok, :class:`Tri`) of triangle (a, b, c) of vertex v with scene positions ``p``
    (12 floats: a, b, c, v as x, y, z); not ok (nothing to measure) when the metric or
    index-space triangle is degenerate."""
    ax, ay, az, bx, by, bz, cx, cy, cz, vx, vy, vz = p
    det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    # index-space map: (i, j) = a + u (b − a) + w (c − a); metric A_T the same with X, Y
    dbi, dbj, dci, dcj = bi - ai, bj - aj, ci - ai, cj - aj
    idet = dbi * dcj - dci * dbj
    if det == 0.0 or idet == 0:
        z = 0.0
        return False, Tri(ai, aj, bi, bj, ci, cj, vi, vj, ax, ay, az, bx, by, bz, cx, cy, cz,
                          vx, vy, vz, z, z, z, z, z, z, z, z, z, z, z, z, z, ai, ai, aj, aj)
    # linear part of A_T: columns = metric images of the unit index steps di, dj
    m11 = ((bx - ax) * dcj - (cx - ax) * dbj) / idet  # dX/di
    m12 = ((cx - ax) * dbi - (bx - ax) * dci) / idet  # dX/dj
    m21 = ((by - ay) * dcj - (cy - ay) * dbj) / idet
    m22 = ((cy - ay) * dbi - (by - ay) * dci) / idet
    # smallest singular value: metres per index step, the local sample spacing
    pp = m11 * m11 + m12 * m12 + m21 * m21 + m22 * m22
    q = abs(m11 * m22 - m12 * m21)
    smin = q / np.sqrt(0.5 * (pp + np.sqrt(max(pp * pp - 4 * q * q, 0.0))))
    tol = 2.0 * frac * smin
    la = np.hypot(cx - bx, cy - by)
    lb = np.hypot(ax - cx, ay - cy)
    lc = np.hypot(bx - ax, by - ay)
    area2 = abs(det)
    ta, tb, tc = tol * la / area2, tol * lb / area2, tol * lc / area2
    inv = 1.0 / det
    i0, i1 = min(ai, bi, ci), max(ai, bi, ci)
    j0, j1 = min(aj, bj, cj), max(aj, bj, cj)
    return True, Tri(ai, aj, bi, bj, ci, cj, vi, vj, ax, ay, az, bx, by, bz, cx, cy, cz,
                     vx, vy, vz, m11, m12, m21, m22, smin, la, lb, lc, area2, ta, tb, tc, inv,
                     i0, i1, j0, j1)


@njit(cache=True, inline="always")
def _tri_own(g, T, r_lo, r_hi, border):
    """Pass 1 of a triangle ``T`` (:class:`Tri`) over its own samples (its index box) on
    grid rows r_lo … r_hi of ``g`` (:class:`MetricGrid`): (the largest displacement
    |P_s − A_T(s)|, the same over the samples on the data window's last row or column,
    whether a valid sample bulges beyond a border chord of T). Maxima and an OR: the
    rows may come in any split."""
    X, Y, vb, frac, wi, wj, w0 = g.X, g.Y, g.vb, g.frac, g.wi, g.wj, g.w0
    C = X.shape[1]
    R = _grid_rows(g)
    disp = 0.0
    dwin = 0.0  # the same, over T's samples on the data window's last row or column
    cross = T.i1 > wi - 1 or T.j1 > wj - 1
    bulge = False
    half = 0.5 * frac * T.smin
    on_a = border and _on_border(T.bi, T.bj, T.ci, T.cj, R, C)  # edges opposite a, b, c
    on_b = border and _on_border(T.ai, T.aj, T.ci, T.cj, R, C)
    on_c = border and _on_border(T.ai, T.aj, T.bi, T.bj, R, C)
    for i in range(max(T.i0, r_lo), min(T.i1, r_hi) + 1):
        for j in range(T.j0, T.j1 + 1):
            x, y = X[i - w0, j], Y[i - w0, j]
            ex = T.ax + T.m11 * (i - T.ai) + T.m12 * (j - T.aj) - x
            ey = T.ay + T.m21 * (i - T.ai) + T.m22 * (j - T.aj) - y
            dd = np.hypot(ex, ey)
            disp = max(disp, dd)
            if cross and ((i == wi - 1 and j <= wj - 1) or (j == wj - 1 and i <= wi - 1)):
                dwin = max(dwin, dd)
            if (on_a or on_b or on_c) and vb[i - w0, j]:
                # signed distance beyond each border edge (opposite a: b–c, etc.)
                px = x - T.ax
                py = y - T.ay
                l1 = (px * (T.cy - T.ay) - py * (T.cx - T.ax)) * T.inv
                l2 = ((T.bx - T.ax) * py - (T.by - T.ay) * px) * T.inv
                l0 = 1.0 - l1 - l2
                if on_a and -l0 * T.area2 / T.la > half:
                    bulge = True
                if on_b and -l1 * T.area2 / T.lb > half:
                    bulge = True
                if on_c and -l2 * T.area2 / T.lc > half:
                    bulge = True
    return disp, dwin, bulge


@njit(cache=True, inline="always")
def _tri_margin(T, disp, N):
    """The search margin m, in samples, from a triangle's largest displacement on a grid
    of N samples on its longer side."""
    # capped in floating point before the conversion: a triangle folded almost flat in
    # metres (a padded global grid's corners beyond a pole) has disp / smin past 2^63, and
    # converting that to an integer is undefined (it crashed a 540 × 1080 global grid); a
    # margin of N samples already reaches every sample
    mf = disp / T.smin
    return (int(np.ceil(mf)) if mf < N else N) + 2


@njit(cache=True, inline="always")
def _tri_search(g, T, m, r_lo, r_hi):
    """Pass 2 of a triangle ``T`` on grid rows r_lo … r_hi of ``g``: (max error, max
    distance to p_v) over the valid samples of T's index box ± ``m`` whose scene (X, Y)
    lies in T's metric triangle widened by 2 ``frac`` spacings (maxima: any split)."""
    X, Y, Z, vb, w0 = g.X, g.Y, g.Z, g.vb, g.w0
    C = X.shape[1]
    R = _grid_rows(g)
    emax = 0.0
    rmax = 0.0
    for i in range(max(T.i0 - m, 0, r_lo), min(T.i1 + m, R - 1, r_hi) + 1):
        for j in range(max(T.j0 - m, 0), min(T.j1 + m, C - 1) + 1):
            if not vb[i - w0, j]:
                continue
            px = X[i - w0, j] - T.ax
            py = Y[i - w0, j] - T.ay
            l1 = (px * (T.cy - T.ay) - py * (T.cx - T.ax)) * T.inv
            l2 = ((T.bx - T.ax) * py - (T.by - T.ay) * px) * T.inv
            l0 = 1.0 - l1 - l2
            if l0 < -T.ta or l1 < -T.tb or l2 < -T.tc:
                continue
            zs = Z[i - w0, j]
            if (i == T.ai and j == T.aj) or (i == T.bi and j == T.bj) or \
                    (i == T.ci and j == T.cj):
                continue  # the corners are mesh vertices (and v's ancestors)
            emax = max(emax, abs(T.az * l0 + T.bz * l1 + T.cz * l2 - zs))
            rmax = max(rmax, np.sqrt((X[i - w0, j] - T.vx) ** 2 + (Y[i - w0, j] - T.vy) ** 2
                                     + (zs - T.vz) ** 2))
    return emax, rmax


@njit(cache=True, inline="always")
def _corners(g, vi, vj, ai, aj, bi, bj, ci, cj):
    """Scene positions of a triangle's corners a, b, c and its vertex v in ``g``'s rows."""
    X, Y, Z, w0 = g.X, g.Y, g.Z, g.w0
    return (X[ai - w0, aj], Y[ai - w0, aj], Z[ai - w0, aj], X[bi - w0, bj], Y[bi - w0, bj],
            Z[bi - w0, bj], X[ci - w0, cj], Y[ci - w0, cj], Z[ci - w0, cj], X[vi - w0, vj],
            Y[vi - w0, vj], Z[vi - w0, vj])


@njit(cache=True)
def _tri_term(g, vi, vj, ai, aj, bi, bj, ci, cj, border):
    """(max error, max distance to p_v, border bulge, search margin m in samples) for
    triangle (a, b, c) of vertex v of the grid ``g`` (:class:`MetricGrid`, whole).

    ``g.wi × g.wj``: the data window a static mesh is clipped to (the grid: none). A triangle
    that crosses its last row or column bulges when a sample of T on that row or column
    is displaced from its place in T (|P_s − A_T(s)|) by more than ``frac / 2`` spacings:
    the clipped edge is T's chord of the curved data border there. The two passes are
    :func:`_tri_own` and :func:`_tri_search`, which a streamed grid runs over row bands."""
    vb = g.vb
    R, C = vb.shape
    if not (vb[ai, aj] and vb[bi, bj] and vb[ci, cj]):
        return 0.0, 0.0, False, 0
    ok, T = _tri_make(vi, vj, ai, aj, bi, bj, ci, cj,
                      _corners(g, vi, vj, ai, aj, bi, bj, ci, cj), g.frac)
    if not ok:
        return 0.0, 0.0, False, 0
    # pass 1: largest displacement |P_s − A_T(s)| of T's own samples (index box), and
    # the border chords of T (edges whose two ends lie on one side of the domain)
    disp, dwin, bulge = _tri_own(g, T, 0, R - 1, border)
    m = _tri_margin(T, disp, max(R, C))
    bulge = bulge or dwin > 0.5 * g.frac * T.smin
    emax, rmax = _tri_search(g, T, m, 0, R - 1)
    return emax, rmax, bulge, m


@njit(cache=True, inline="always")
def _on_border(ai, aj, bi, bj, R, C):
    # an edge along the grid's border (R × C: the square's N × N, or a root grid's extent)
    return ((ai == bi and (ai == 0 or ai == R - 1))
            or (aj == bj and (aj == 0 or aj == C - 1)))


@njit(cache=True, inline="always")
def _same_as_base(i, j, h, M, wi, wj):
    """Whether every sample vertex (i, j)'s triangles read, their index box ± ``M``, lies
    in the data's wi × wj, where the replicated grid equals the original one."""
    return M >= 0 and i + h + M <= wi - 1 and j + h + M <= wj - 1


@parallel_kernel(cache=True)
def _vertex_terms(g, M, dm0, bulge0, mrow, span):
    """Raw per-vertex (δ_m, r_m, bulge) over the triangles drawn while each vertex of the
    grid ``g`` (:class:`MetricGrid`) is absent (rows of blocks on every core: each vertex
    is written by its own iteration only), and in ``mrow[i]`` the largest search margin
    of row i's triangles. The vertices of half-span below ``span`` (the square's N − 1,
    or a root grid's root side: the grid is then the roots' extent, R × C).

    A vertex whose diamond misses the data's wi × wj gets nothing (with a data window,
    :mod:`geoterrain.bounds.edgepad`: its error is clipped away; without one, wi = wj = N, every
    vertex reaches it). ``M`` ≥ 0 (δ_edge over the replicated grid): a vertex that reads
    only data samples (box ± M, M the original grid's largest margin) takes ``dm0`` and
    ``bulge0`` from the original grid's run (r_m is not computed then)."""
    wi, wj = g.wi, g.wj
    R, C = g.Z.shape
    dm = np.zeros((R, C))
    rm = np.zeros((R, C))
    bulge = np.zeros((R, C), np.bool_)
    h = 1
    while h < span:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        for a in prange(nr):  # block centres: the two halves of the block
            for b in range(nc):
                i, j = h + a * s, h + b * s
                if not _reaches_data(i, j, wi, wj):
                    continue
                if _same_as_base(i, j, h, M, wi, wj):
                    dm[i, j], bulge[i, j] = dm0[i, j], bulge0[i, j]
                    continue
                i0, j0 = i - h, j - h
                main = main_diagonal_nb(a, b)
                for k in range(2):
                    if main:  # diagonal (i0, j0)–(i0+s, j0+s), apex (i0, j0+s) / (i0+s, j0)
                        t = _tri_term(g, i, j, i0, j0, i0 + s, j0 + s,
                                      i0 + k * s, j0 + (1 - k) * s, True)
                    else:
                        t = _tri_term(g, i, j, i0, j0 + s, i0 + s, j0,
                                      i0 + k * s, j0 + k * s, True)
                    dm[i, j] = max(dm[i, j], t[0])
                    rm[i, j] = max(rm[i, j], t[1])
                    bulge[i, j] |= t[2]
                    mrow[i] = max(mrow[i], t[3])
        for typ in range(2):  # edge midpoints: the two triangles on their hypotenuse
            rows = typ == 0
            na = nr if rows else nr + 1
            nb = nc + 1 if rows else nc
            for a in prange(na):
                for b in range(nb):
                    i = h + a * s if rows else a * s
                    j = b * s if rows else h + b * s
                    if not _reaches_data(i, j, wi, wj):
                        continue
                    if _same_as_base(i, j, h, M, wi, wj):
                        dm[i, j], bulge[i, j] = dm0[i, j], bulge0[i, j]
                        continue
                    for k in range(2):
                        if rows:  # hypotenuse (i ± h, j), apex (i, j ± h)
                            ci, cj = i, j + (2 * k - 1) * h
                            ea, eb, fa, fb = i - h, j, i + h, j
                        else:
                            ci, cj = i + (2 * k - 1) * h, j
                            ea, eb, fa, fb = i, j - h, i, j + h
                        if not (0 <= ci < R and 0 <= cj < C):
                            continue
                        t = _tri_term(g, i, j, ea, eb, fa, fb, ci, cj, True)
                        dm[i, j] = max(dm[i, j], t[0])
                        rm[i, j] = max(rm[i, j], t[1])
                        bulge[i, j] |= t[2]
                        mrow[i] = max(mrow[i], t[3])
        h *= 2
    return dm, rm, bulge


def metric_terms(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, valid: np.ndarray,
                 frac: float = BORDER_FRACTION, window: tuple[int, int] | None = None,
                 base: tuple | None = None, span: int | None = None) -> tuple:
    """The raw per-vertex terms (δ_m, r_m, bulge) of :func:`metric_bounds` and the largest
    search margin M, in samples.

    ``span``: None for the square (N, N) grid; a root grid's root side 2**n, the arrays
    then the roots' extent (:mod:`geoterrain.bounds.delta`).

    ``window`` and ``base`` (the terms of the original grid): the terms of δ_edge over
    the replicated grid (:mod:`geoterrain.bounds.edgepad`), computed only for the vertices that
    reach the data and read a padding sample; the others are 0 or the base's.
    """
    vb = np.ascontiguousarray(np.asarray(valid, bool) & np.isfinite(Z))
    Zf = np.ascontiguousarray(np.where(vb, Z, 0.0), np.float64)
    X = np.ascontiguousarray(X, np.float64)
    Y = np.ascontiguousarray(Y, np.float64)
    R = Zf.shape[0]
    wi, wj = window if window is not None else Zf.shape
    if base is not None:
        dm0, _, bulge0, M = base
    else:
        dm0, bulge0, M = np.zeros((1, 1)), np.zeros((1, 1), np.bool_), -1
    mrow = np.zeros(R, np.int64)
    with cores_for(Zf.size):  # small grids on one thread (geoterrain/core/threads.py)
        dm, rm, bulge = _vertex_terms(MetricGrid(X, Y, Zf, vb, float(frac), int(wi), int(wj), 0,
                                                 R),
                                      int(M), dm0, bulge0, mrow, _span(Zf, span))
    return dm, rm, bulge, int(mrow.max()) if R else 0


def _span(a: np.ndarray, span: int | None) -> int:
    # the kernels' root side: the square's N − 1 unless a root grid's is given
    return a.shape[0] - 1 if span is None else int(span)


@njit(cache=True)
def _renest_nb(X, Y, Z, r, span):
    # LP §2.4 (L50–52) again, fine to coarse, on radii already raised: r(v) ≥ |p_v − p_c| + r(c),
    # up to half-span span / 2 (the square's N − 1, or a root grid's root side)
    R, C = Z.shape
    h = 1
    while h < span:
        for pass_ in range(2):
            for i in range(0, R, h):
                for j in range(0, C, h):
                    centre = (i // h) % 2 == 1 and (j // h) % 2 == 1
                    edge = ((i // h) % 2 == 1) != ((j // h) % 2 == 1)
                    if (pass_ == 0 and not edge) or (pass_ == 1 and not centre):
                        continue
                    best = np.float64(r[i, j])
                    for k in range(4):
                        ci, cj = child_nb(i, j, h, k)
                        if 0 <= ci < R and 0 <= cj < C:
                            d = np.sqrt((X[i, j] - X[ci, cj]) ** 2 + (Y[i, j] - Y[ci, cj]) ** 2
                                        + (Z[i, j] - Z[ci, cj]) ** 2) + np.float64(r[ci, cj])
                            best = max(best, d)
                    r[i, j] = round_up32(best)
        h *= 2
    return r


def metric_bounds(delta: np.ndarray, radius: np.ndarray | None, X: np.ndarray,
                  Y: np.ndarray, Z: np.ndarray, valid: np.ndarray,
                  frac: float = BORDER_FRACTION, window: tuple[int, int] | None = None,
                  terms: tuple | None = None, span: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray | None]:
    """δ and r raised so they hold in scene x/y on a curvilinear grid (module docstring).

    Parameters
    ----------
    delta, radius : float32 (N, N), from :func:`geoterrain.bounds.delta.vertex_errors` and
        :func:`geoterrain.bounds.radii.vertex_radii` (not modified). ``radius`` None: r is
        neither raised nor returned (None).
    X, Y, Z : float64 (N, N) scene positions (Z NaN or anything where invalid).
    valid : bool (N, N).
    frac : border chords follow the curved border to within ``frac / 2`` of a sample
        spacing; samples within ``2 frac`` spacings of a triangle count as in it.
    window : (rows, cols) of the data when the mesh is clipped to it
        (:mod:`geoterrain.bounds.edgepad`): the clipped edges on its last row and column follow
        the curved border to within the same ``frac / 2`` (see :func:`_tri_term`).
    terms : the raw terms from :func:`metric_terms` (default: computed here).
    span : None for the square; a root grid's root side 2**n, every array then the
        roots' extent (ry·span + 1, rx·span + 1) (:mod:`geoterrain.bounds.delta`).

    Examples
    --------
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> from geoterrain.bounds.radii import vertex_radii
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> X, Y = 100 * J + (I - 2) ** 2, -100 * I  # rows bowed by 4 m: a curved grid
    >>> Z, ok = 0.5 * X, np.ones((5, 5), bool)
    >>> d, r = vertex_errors(Z, ok), vertex_radii(X, Y, Z, ok)
    >>> d2, r2 = metric_bounds(d, r, X, Y, Z, ok)
    >>> float(d.max()), float(d2[2, 2]) > 0, bool((d2 >= d).all() and (r2 >= r).all())
    (2.0, True, True)
    """
    if terms is None:
        terms = metric_terms(X, Y, Z, valid, frac, window, span=span)
    dm, rm, bulge, _ = terms  # 0 where a diamond misses the data window (_vertex_terms)
    d = np.maximum(delta.astype(np.float64), dm)
    d[bulge] = np.inf
    d32 = saturate(_round_up(d), _span(d, span))
    if radius is None:
        return d32, None
    vb = np.asarray(valid, bool) & np.isfinite(Z)
    r = np.maximum(radius.astype(np.float64), rm)
    xp, yp, zp = _proxy_positions(np.ascontiguousarray(X, np.float64),
                                  np.ascontiguousarray(Y, np.float64),
                                  np.where(vb, Z, np.nan), vb)
    return d32, _renest_nb(xp, yp, zp, _round_up(r), _span(d, span))


def _round_up(a: np.ndarray) -> np.ndarray:
    """float64 → float32, never rounding down."""
    f = a.astype(np.float32)
    low = f.astype(np.float64) < a
    f[low] = np.nextafter(f[low], np.float32(np.inf))
    return f

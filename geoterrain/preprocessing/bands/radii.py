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

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.log8codes import log8_exponent, log8_table
from geoterrain.bounds.radii import code_up_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import parallel_kernel
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["band_metric_radius_codes", "band_radius_codes", "level_xy"]


@parallel_kernel(cache=True)
def _edge_codes_nb(xs, ys, h, rows, a_lo, nbr, nb, zv, pz, pc, table, out):
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
                if 0 <= a2 < 2 * nbr and 0 <= b2 < 2 * nb:
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
        nbr, nb = sa.shape(f"ZC{k}")
        step = max(1, budget // (48 * (nb + 1)))
        for a_lo in range(0, nbr, step):
            a_hi = min(a_lo + step, nbr)
            zr = sa.read(f"ZR{k}", a_lo, a_hi)
            zk = sa.read(f"ZK{k}", a_lo, a_hi + 1)
            cr = np.zeros(zr.shape, np.uint8)  # h = 1: edge midpoints are leaves
            ck = np.zeros(zk.shape, np.uint8)
            if k:
                pz = sa.read_padded(f"ZC{k - 1}", 2 * a_lo - 1, 2 * a_hi + 1)
                pc = sa.read_padded(f"rC{k - 1}", 2 * a_lo - 1, 2 * a_hi + 1)
                _edge_codes_nb(xs, ys, h, True, a_lo, nbr, nb, zr, pz, pc, table, cr)
                _edge_codes_nb(xs, ys, h, False, a_lo, nbr, nb, zk, pz, pc, table, ck)
            cc = np.empty((a_hi - a_lo, nb), np.uint8)
            _centre_codes_nb(xs, ys, h, a_lo, sa.read(f"ZC{k}", a_lo, a_hi), zr, zk, cr, ck,
                             table, cc)
            full = full or bool((cc == 255).any() or (cr == 255).any() or (ck == 255).any())
            sa.write(f"rC{k}", a_lo, cc)
            sa.write(f"rR{k}", a_lo, cr)
            sa.write(f"rK{k}", a_lo, ck)
    return full


def band_radius_codes(sa: ScratchArrays, N: int | tuple[int, int], xs: np.ndarray,
                      ys: np.ndarray, lo: float, hi: float, budget: int = 16 << 20,
                      span: int | None = None) -> int:
    """Nest the radius codes of an (N, N) grid (a root grid: its (R, C) extent, roots of
    side ``span``) on its per-level arrays in ``sa`` and return their exponent ``e``
    (log8 table, :func:`geoterrain.bounds.log8codes.log8_table`).

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
    R = N[0] if isinstance(N, tuple | list) else N
    n = (R - 1 if span is None else span).bit_length() - 1
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


# ------------------------------------------------------------- curvilinear (geographic) x, y
XYRows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


def level_xy(xy: XYRows, h: int, kind: str, a0: int, a1: int, N: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """Scene X, Y of rows a0 … a1 − 1 of one kind of a level's vertices (``kind`` C, R or
    K at half-span h: :mod:`geoterrain.preprocessing.bands.delta`), from ``xy(i0, i1)`` →
    the grid rows' X, Y; ``N``: the grid's columns (the square's side, or a root grid's
    extent's).

    Examples
    --------
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> X, Y = level_xy(lambda a, b: (J[a:b], -I[a:b]), 1, "R", 0, 2, 5)
    >>> X.tolist(), Y.tolist()
    ([[0.0, 2.0, 4.0], [0.0, 2.0, 4.0]], [[-1.0, -1.0, -1.0], [-3.0, -3.0, -3.0]])
    """
    s = 2 * h
    off, c0 = {"C": (h, h), "R": (h, 0), "K": (0, h)}[kind]
    ncols = (N - 1 - c0) // s + 1
    X = np.empty((max(a1 - a0, 0), ncols))
    Y = np.empty_like(X)
    for r, a in enumerate(range(a0, a1)):
        gx, gy = xy(off + a * s, off + a * s + 1)
        X[r] = np.asarray(gx)[0, c0::s]
        Y[r] = np.asarray(gy)[0, c0::s]
    return X, Y


class NestRows(NamedTuple):
    """One chunk of a level's vertices as the curvilinear nesting kernels read it: their
    heights ``z`` and scene ``x``, ``y``, their own radii ``rin`` (float64; empty: none),
    and the children's heights, positions and values (radii, or the code table's values)
    ``cz``, ``cx``, ``cy``, ``cv``, rows from the child level's row ``c0``."""

    z: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rin: np.ndarray
    cz: np.ndarray
    cx: np.ndarray
    cy: np.ndarray
    cv: np.ndarray
    c0: int


@njit(cache=True, inline="always")
def _best(table, best):
    # a nested value: the float32 radius rounded up (no table), else its code (as float)
    if table.shape[0] == 0:
        return np.float64(round_up32(best))
    return np.float64(code_up_nb(table, best))


@parallel_kernel(cache=True)
def _geo_edges_nb(ch, h, rows, a_lo, nbr, nbc, table, out):
    """Level h's edge midpoints (rows a_lo … of R-type if ``rows``, else K-type) nested on
    their four child centres at h/2 (``ch``: :class:`NestRows`): seed 002 §2.4 (L50–52),
    r(v) = max(rin(v), |p_v − p_c| + r(c)), as radii.vertex_radii / curvature._renest_nb,
    or as codes (tileblobs.radius_codes) with a ``table``. h = 1: leaves, rin alone.
    ``nbr`` × ``nbc``: the level's blocks down and across (its children: twice as many
    centres each way)."""
    z, x, y, rin, cz, cx, cy, cv, c0 = ch
    for ar in prange(z.shape[0]):
        a = a_lo + ar
        for b in range(z.shape[1]):
            best = rin[ar, b] if rin.shape[0] else 0.0
            if h > 1:
                for k in range(4):
                    a2 = 2 * a + (k // 2) if rows else 2 * a - 1 + (k // 2)
                    b2 = 2 * b - 1 + (k % 2) if rows else 2 * b + (k % 2)
                    if 0 <= a2 < 2 * nbr and 0 <= b2 < 2 * nbc:
                        r2 = a2 - c0
                        d = np.sqrt((x[ar, b] - cx[r2, b2]) ** 2 + (y[ar, b] - cy[r2, b2]) ** 2
                                    + (z[ar, b] - cz[r2, b2]) ** 2) + cv[r2, b2]
                        best = max(best, d)
            out[ar, b] = _best(table, best)


class CentreEdges(NamedTuple):
    """A chunk's block centres' four children: the edge midpoints R (rows a_lo …, nb + 1
    columns) and K (rows a_lo … a_hi, inclusive), heights, x, y and values."""

    zr: np.ndarray
    xr: np.ndarray
    yr: np.ndarray
    vr: np.ndarray
    zk: np.ndarray
    xk: np.ndarray
    yk: np.ndarray
    vk: np.ndarray


@parallel_kernel(cache=True)
def _geo_centres_nb(ch, e, table, out):
    """Block centres (``ch``'s z, x, y, rin) nested on their block's four edge midpoints
    ``e`` (:class:`CentreEdges`): up K[a], down K[a + 1], left R[b], right R[b + 1]."""
    z, x, y, rin = ch.z, ch.x, ch.y, ch.rin
    zr, xr, yr, vr, zk, xk, yk, vk = e
    for ar in prange(z.shape[0]):
        for b in range(z.shape[1]):
            best = rin[ar, b] if rin.shape[0] else 0.0
            for k in range(4):
                if k < 2:
                    zz, xx, yy, v = zk[ar + k, b], xk[ar + k, b], yk[ar + k, b], vk[ar + k, b]
                else:
                    c = b + k - 2
                    zz, xx, yy, v = zr[ar, c], xr[ar, c], yr[ar, c], vr[ar, c]
                d = np.sqrt((x[ar, b] - xx) ** 2 + (y[ar, b] - yy) ** 2
                            + (z[ar, b] - zz) ** 2) + v
                best = max(best, d)
            out[ar, b] = _best(table, best)


def band_metric_radius_codes(sa: ScratchArrays, N: int | tuple[int, int], xy: XYRows,
                             rm: str = "rm", budget: int = 16 << 20,
                             span: int | None = None) -> int:
    """The radius codes of a curvilinear (geographic) grid, nested on its per-level arrays
    in ``sa``: the codes of :func:`geoterrain.bounds.tileblobs.radius_codes` with the radii
    :func:`geoterrain.bounds.curvature.metric_bounds` raises and renests, bit for bit.

    Three nestings of seed 002 §2.4 (L50–52), fine to coarse, a few rows at a time: the
    radii of :func:`geoterrain.bounds.radii.vertex_radii` (``fr1{x}{k}``, float32 rounded
    up), the same raised to the metric term r_m (``{rm}{x}{k}``, from
    :func:`~geoterrain.preprocessing.bands.curvature.band_metric_terms`) and nested again
    (``fr{x}{k}``), then the codes covering those (``r{x}{k}``, uint8), whose exponent is
    returned. Heights are ``Z{x}{k}`` (invalid ones at the stand-in); x, y of the grid
    rows come from ``xy(i0, i1)``. ``N``: the grid's side, or a root grid's extent (R, C)
    with ``span`` its roots' side (the vertices of half-span below it, nested across
    the roots' shared edges as the whole grid's are).

    Examples
    --------
    >>> from geoterrain.preprocessing.bands.delta import band_vertex_errors, rows_of
    >>> from geoterrain.preprocessing.bands.curvature import band_metric_terms
    >>> from geoterrain.bounds.curvature import metric_terms, metric_bounds
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> from geoterrain.bounds.radii import vertex_radii
    >>> from geoterrain.bounds.tileblobs import radius_codes
    >>> I, J = np.indices((9, 9)).astype(float)
    >>> X, Y = 50 * J + (I - 4) ** 2, -50 * I
    >>> Z = np.cos(I) * 3 + J; v = np.ones_like(Z, bool)
    >>> rows, xy = rows_of(Z, v), lambda a, b: (X[a:b], Y[a:b])
    >>> d = band_vertex_errors(rows, 9, band=2, heights=True)
    >>> _ = band_metric_terms(rows, xy, 9, 2, d.arrays)
    >>> e = band_metric_radius_codes(d.arrays, 9, xy)
    >>> _, r = metric_bounds(vertex_errors(Z, v), vertex_radii(X, Y, Z, v), X, Y, Z, v)
    >>> codes, e2 = radius_codes(X, Y, Z, v, r)
    >>> e == e2, bool((d.arrays.read("rC1", 0, 2) == codes[2::4, 2::4]).all())
    (True, True)
    """
    from geoterrain.bounds.curvature import _round_up
    from geoterrain.preprocessing.bands.delta import grid_shape

    R, N = grid_shape(N)  # N: the columns from here
    n = (R - 1 if span is None else int(span)).bit_length() - 1
    for k in range(n):
        for x in "CRK":
            shape = sa.shape(f"Z{x}{k}")
            sa.create(f"fr1{x}{k}", shape, np.float32)
            sa.create(f"fr{x}{k}", shape, np.float32)
            sa.create(f"r{x}{k}", shape, np.uint8)
    none = np.empty((0, 0))
    empty = np.empty(0)
    peak = 0.0
    # radii.vertex_radii (from leaves 0), then curvature.metric_bounds' raise and renest
    for k, h, nbr, nbc, a_lo, a_hi in _chunks(sa, n, budget):
        raw = {}
        for out in ("fr1", "fr"):
            vals = {}
            for x in ("R", "K"):
                hi = a_hi + (x == "K")
                rin = none
                if out == "fr":  # max(r, r_m) rounded up to float32: metric_bounds' input
                    r1 = raw[x].astype(np.float64)
                    rin = _round_up(np.maximum(r1, sa.read(f"{rm}{x}{k}", a_lo, hi)))
                    rin = rin.astype(np.float64)
                ch = _nest_rows(sa, xy, N, k, x, a_lo, hi, rin, out, h)
                v = np.empty(ch.z.shape)
                _geo_edges_nb(ch, h, x == "R", a_lo, nbr, nbc, empty, v)
                vals[x] = (ch, v)
                if out == "fr1":
                    raw[x] = v.astype(np.float32)
            rin = none
            if out == "fr":
                r1 = raw["C"].astype(np.float64)
                rin = _round_up(np.maximum(r1, sa.read(f"{rm}C{k}", a_lo, a_hi)))
                rin = rin.astype(np.float64)
            ch = _nest_rows(sa, xy, N, k, "C", a_lo, a_hi, rin, None, h)
            (chr_, vr), (chk, vk) = vals["R"], vals["K"]
            vc = np.empty(ch.z.shape)
            _geo_centres_nb(ch, CentreEdges(chr_.z, chr_.x, chr_.y, vr, chk.z, chk.x, chk.y,
                                            vk), empty, vc)
            if out == "fr1":
                raw["C"] = vc.astype(np.float32)
            for x, a in (("C", vc), ("R", vr), ("K", vk)):
                sa.write(f"{out}{x}{k}", a_lo, a.astype(np.float32))
                if out == "fr":
                    peak = max(peak, float(np.max(a, where=np.isfinite(a), initial=0.0)))
    e = min(log8_exponent(np.array([peak])) + 2, 127)  # tileblobs.radius_codes
    while True:
        table = log8_table(e).astype(np.float64)
        full = False
        for k, h, nbr, nbc, a_lo, a_hi in _chunks(sa, n, budget):
            vals = {}
            for x in ("R", "K"):
                hi = a_hi + (x == "K")
                rin = sa.read(f"fr{x}{k}", a_lo, hi).astype(np.float64)
                ch = _nest_rows(sa, xy, N, k, x, a_lo, hi, rin, "code", h, table)
                v = np.empty(ch.z.shape)
                _geo_edges_nb(ch, h, x == "R", a_lo, nbr, nbc, table, v)
                vals[x] = (ch, v)
            rin = sa.read(f"frC{k}", a_lo, a_hi).astype(np.float64)
            ch = _nest_rows(sa, xy, N, k, "C", a_lo, a_hi, rin, None, h)
            (chr_, vr), (chk, vk) = vals["R"], vals["K"]
            vc = np.empty(ch.z.shape)
            _geo_centres_nb(ch, CentreEdges(chr_.z, chr_.x, chr_.y, table[vr.astype(np.int64)],
                                            chk.z, chk.x, chk.y, table[vk.astype(np.int64)]),
                            table, vc)
            for x, a in (("C", vc), ("R", vr), ("K", vk)):
                c = a.astype(np.uint8)
                full = full or bool((c == 255).any())
                sa.write(f"r{x}{k}", a_lo, c)
        if not full or e >= 127:
            return e
        e = min(e + 4, 127)


# bytes a chunk holds per vertex of its level (the three kinds at once, each with its
# height, x, y, radii in and out, and float32 copies), and per vertex above the leaves
# (its four child centres' height, x, y and value): 96 a vertex for all, as before,
# put a 4097-wide grid's chunks above the leaves at about 100 MB for a 16 MB budget
CHUNK_BYTES = 3 * 7 * 8
CHUNK_CHILD_BYTES = 3 * 4 * 4 * 8


def _chunks(sa: ScratchArrays, n: int, budget: int):
    # (k, h, nbr, nbc, a_lo, a_hi) of every level fine to coarse (its blocks down and
    # across), a few block rows at a time: about ``budget`` bytes a chunk
    for k in range(n):
        nbr, nbc = sa.shape(f"ZC{k}")
        per = CHUNK_BYTES + (CHUNK_CHILD_BYTES if k else 0)
        step = max(1, budget // (per * (nbc + 1)))
        for a_lo in range(0, nbr, step):
            yield k, 1 << k, nbr, nbc, a_lo, min(a_lo + step, nbr)


def _nest_rows(sa: ScratchArrays, xy: XYRows, N: int, k: int, x: str, a0: int, a1: int,
               rin: np.ndarray, out: str | None, h: int,
               table: np.ndarray | None = None) -> NestRows:
    # a chunk's vertices and, for edge midpoints above the leaves, their child centres at
    # h/2 with the values nested before (out: "fr1", "fr" radii, or "code" for r codes)
    X, Y = level_xy(xy, h, x, a0, a1, N)
    z = sa.read(f"Z{x}{k}", a0, a1)
    none = np.zeros((0, 0))
    if out is None or k == 0:
        return NestRows(z, X, Y, rin, none, none, none, none, 0)
    c0 = max(2 * a0 - 1, 0)
    c1 = min(2 * a1 + 1, sa.shape(f"ZC{k - 1}")[0])
    cz = sa.read(f"ZC{k - 1}", c0, c1)
    cx, cy = level_xy(xy, h // 2, "C", c0, c1, N)
    if out == "code":
        cv = table[sa.read(f"rC{k - 1}", c0, c1).astype(np.int64)]
    else:
        cv = sa.read(f"{out}C{k - 1}", c0, c1).astype(np.float64)
    return NestRows(z, X, Y, rin, cz, cx, cy, cv, c0)

"""Nested bounding-sphere radii (seed 002 §2.4, L50–52), as float radii and as the
8-bit log codes they are stored as.

The radii nest, r(v) ≥ |p_v − p_c| + r(c) on every edge of the vertex DAG, so that with
δ saturated (:mod:`geoterrain.bounds.delta`) the screen-space error of LP eq. 2,
ρ = λ δ / (|p − o| − r), is monotone along it. :func:`vertex_radii` computes them in
float32 rounded up; ``_radii_nb`` with a log8 table nests the stored codes themselves
(:func:`geoterrain.bounds.tileblobs.radius_codes`), so the stored values nest exactly.

The sphere of every vertex must contain those of its children, valid or not, so invalid
positions are replaced by finite *proxy* positions before nesting: z by the midpoint of
the valid height range (so a valid vertex's radius grows by at most about half the
relief near nodata), and non-finite x or y by an affine fit of the finite ones in
(i, j). Nesting then holds on every DAG edge, and radii of valid vertices stay finite.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import grid_order
from geoterrain.core.bintree import child_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import cores_for, parallel_kernel, serial_for

__all__ = ["numpy_range", "stand_in_z", "valid_range", "vertex_radii", "zero_signs"]

def stand_in_z(z: np.ndarray, valid: np.ndarray) -> float:
    """The height standing in for invalid samples in the nested spheres: the middle of
    the valid height range (0 when nothing is valid). Stored with the store, so that the
    view-dependent predicate places invalid vertices where the radii did.

    Examples
    --------
    >>> stand_in_z(np.array([[1.0, np.nan], [5.0, 100.0]]), np.array([[1, 0], [1, 0]], bool))
    3.0
    """
    lo, hi, n = valid_range(z, valid)
    return float(0.5 * (lo + hi)) if n else 0.0


def valid_range(z: np.ndarray, valid: np.ndarray) -> tuple[float, float, int]:
    """(min, max, count) of the finite valid samples of a 2-D grid, one compiled pass
    without copying them ((inf, -inf, 0) when there are none).

    Examples
    --------
    >>> valid_range(np.array([[1.0, np.nan], [5.0, -2.0]]), np.array([[1, 1], [1, 0]], bool))
    (1.0, 5.0, 2)
    """
    z, valid = np.asarray(z, dtype=np.float64), np.asarray(valid, bool)
    # a whole grid's rows on every core, a tile's on this thread (core/threads.py)
    run = _valid_range_nb.serial if serial_for(z.size) else _valid_range_nb.parallel
    lo, hi, n = run(z, valid)
    return float(lo), float(hi), int(n)


def numpy_range(z: np.ndarray, valid: np.ndarray) -> tuple[float, float]:
    """``z[valid].min()`` and ``.max()`` of a 2-D grid whose valid samples are finite, bit
    for bit (which zero, ±0.0, too: a store records them), mostly without their copy: one
    compiled pass (:func:`valid_range`), and where an end is a zero a second
    (:func:`zero_signs`); the copy only where both zeros occur (numpy's choice then).

    Examples
    --------
    >>> numpy_range(np.array([[-0.0, 3.0], [5.0, np.nan]]), np.array([[1, 1], [1, 0]], bool))
    (-0.0, 5.0)
    """
    lo, hi, _ = valid_range(z, valid)
    if lo == 0.0 or hi == 0.0:
        pos, neg = zero_signs(z, valid)
        if (pos > 0) != (neg > 0):  # one sign: that zero, whichever numpy picks
            z0 = 0.0 if pos else -0.0
            return (z0 if lo == 0.0 else lo), (z0 if hi == 0.0 else hi)
        hv = z[valid]  # both zeros (or none valid: numpy's error)
        return float(hv.min()), float(hv.max())
    return lo, hi


def zero_signs(z: np.ndarray, valid: np.ndarray) -> tuple[int, int]:
    """How many valid samples of a 2-D grid are +0.0 and how many −0.0 (one compiled pass,
    no copy): when a valid range's end is a zero and only one sign occurs, that zero is
    the one numpy's ``min`` or ``max`` of the valid samples gives.

    Examples
    --------
    >>> zero_signs(np.array([[0.0, -0.0], [5.0, 0.0]]), np.array([[1, 1], [1, 1]], bool))
    (2, 1)
    """
    pos, neg = _zero_signs_nb(np.asarray(z, dtype=np.float64), np.asarray(valid, bool))
    return int(pos), int(neg)


@njit(cache=True, nogil=True)
def _zero_signs_nb(z, valid):
    pos = neg = 0
    for i in range(z.shape[0]):
        for j in range(z.shape[1]):
            if valid[i, j] and z[i, j] == 0.0:
                if np.signbit(z[i, j]):
                    neg += 1
                else:
                    pos += 1
    return pos, neg


@parallel_kernel(cache=True, nogil=True)
def _valid_range_nb(z, valid):
    # min, max and count of the finite valid samples, one pass, no copy: each row's,
    # then the rows' in order (a min or max keeps the first of equal values, ±0 too,
    # either way)
    rows = z.shape[0]
    los, his, ns = np.full(rows, np.inf), np.full(rows, -np.inf), np.zeros(rows, np.int64)
    for i in prange(rows):
        lo, hi, n = np.inf, -np.inf, 0
        for j in range(z.shape[1]):
            v = z[i, j]
            if valid[i, j] and np.isfinite(v):
                lo = min(lo, v)
                hi = max(hi, v)
                n += 1
        los[i], his[i], ns[i] = lo, hi, n
    lo, hi, n = np.inf, -np.inf, 0
    for i in range(rows):
        lo = min(lo, los[i])
        hi = max(hi, his[i])
        n += ns[i]
    return lo, hi, n


def _proxy_positions(x, y, z, valid):
    z = np.ascontiguousarray(z, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if valid.all() and np.isfinite(z).all():
        zp = z
    else:
        zp = np.where(valid & np.isfinite(z), z, stand_in_z(z, valid))
    out = [zp]
    for c in (x, y):
        c = np.asarray(c, dtype=np.float64)  # no copy of a broadcast view (grid_xy)
        if not np.isfinite(c).all():
            ok = np.isfinite(c)
            ii, jj = np.nonzero(ok)
            if ii.size:
                A = np.stack([ii, jj, np.ones_like(ii)], 1).astype(np.float64)
                coef = np.linalg.lstsq(A, c[ok], rcond=None)[0]
            else:
                coef = np.zeros(3)
            ii_, jj_ = np.indices(c.shape)
            c = np.where(ok, c, coef[0] * ii_ + coef[1] * jj_ + coef[2])
        out.append(c)
    return out[1], out[2], out[0]


def vertex_radii(x: np.ndarray, y: np.ndarray, z: np.ndarray, valid: np.ndarray,
                 span: int | None = None) -> np.ndarray:
    """Nested bounding-sphere radii (seed 002 §2.4, L50–52), float32 (N, N) rounded up;
    or of a root grid's extent, roots of side ``span`` (:mod:`geoterrain.bounds.delta`).

    r = 0 for the finest vertices (and the 4 corners); otherwise
    r(v) = max over children c of |p_v − p_c| + r(c) with p = (x, y, z) in 3-D scene
    coordinates (curvilinear x, y are fine), computed coarse-from-fine. Each level is
    rounded up to float32 before its parents use it, so r32(v) ≥ |p_v − p_c| + r32(c)
    holds for the stored values. Invalid positions are replaced by finite proxies (see the
    module docstring), so nesting holds on every DAG edge.

    Examples
    --------
    >>> I, J = np.indices((3, 3)).astype(float)
    >>> r = vertex_radii(J, -I, np.zeros((3, 3)), np.ones((3, 3), bool))
    >>> float(r[1, 1]), float(r[0, 1])
    (1.0, 0.0)
    >>> I, J = np.indices((3, 5)).astype(float)  # 2 × 1 roots of side 2
    >>> vertex_radii(J, -I, np.zeros((3, 5)), np.ones((3, 5), bool), span=2)[1].tolist()
    [0.0, 1.0, 0.0, 1.0, 0.0]
    """
    x, y, z = _proxy_positions(x, y, z, valid)
    if span is None:
        span = z.shape[0] - 1
        grid_order(z.shape[0])
    elif any((k - 1) % span or k < 3 for k in z.shape):
        raise ValueError(f"a root grid's arrays are whole roots of side {span}, got {z.shape}")
    none = np.empty((0, 0), np.float32)
    with cores_for(z.size):
        return _radii_nb(x, y, z, none, np.empty(0), np.empty(0, np.uint8),
                         np.empty((0, 0), np.uint8),
                         grid_order(span + 1))


@njit(cache=True, inline="always")
def _nest(x, y, z, r, i, j, h):
    # max over the children c of |p_v − p_c| + r(c) (children outside the grid: none)
    R, C = z.shape
    best = 0.0
    for k in range(4):
        ci, cj = child_nb(i, j, h, k)
        if 0 <= ci < R and 0 <= cj < C:
            d = np.sqrt((x[i, j] - x[ci, cj]) ** 2 + (y[i, j] - y[ci, cj]) ** 2
                        + (z[i, j] - z[ci, cj]) ** 2) + np.float64(r[ci, cj])
            best = max(best, d)
    return best


@njit(cache=True, nogil=True, inline="always")
def code_up_nb(table, x):
    """The smallest log8 code whose value is ≥ x (:func:`log8_codes`; ``table`` float64,
    increasing, ending with +inf): a binary search, compiled, inlined."""
    lo, hi = 0, table.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if table[mid] >= x:
            hi = mid
        else:
            lo = mid + 1
    return lo


def prefix_codes(table: np.ndarray) -> np.ndarray:
    """For each 16-bit prefix p of a float32 bit pattern, the log8 code (the first index
    i with ``table[i]`` ≥ x; ``table`` float64, increasing, ending with +inf) of the
    smallest value x with that prefix: a lower bound of the code of every value whose
    nearest float32 has the prefix (codes grow with the value, a non-negative float32's
    pattern with its value, and no float32, so no table entry, lies between a value and
    its nearest float32 above it); 0 for the negative prefixes. A prefix spans 1/128 of
    an octave and a code 1/16 (``LOG_STEPS``), so the exact code is at most one step
    above: :func:`code_lut_nb`.

    Examples
    --------
    >>> from geoterrain.bounds.log8codes import log8_table
    >>> p = prefix_codes(log8_table(0).astype(np.float64))
    >>> int(p[np.float32(1.0).view(np.uint32) >> 16]), int(p[0x7F80]), int(p[0x8000])
    (1, 255, 0)
    """
    lo = (np.arange(1 << 16, dtype=np.uint32) << np.uint32(16)).view(np.float32)
    with np.errstate(invalid="ignore"):  # the NaN prefixes: past the end, then the last
        c = np.minimum(np.searchsorted(table, lo.astype(np.float64), side="left"),
                       len(table) - 1)
    c[1 << 15:] = 0  # sign bit set: -0.0 and below (NaN: code_lut_nb's own test)
    return c.astype(np.uint8)


@njit(cache=True, nogil=True, inline="always")
def code_lut_nb(table, lut, x):
    """:func:`code_up_nb`'s code (the first entry ≥ x; NaN: the last), from the code of
    the 16-bit prefix of x's nearest float32 (``lut``: :func:`prefix_codes` of
    ``table``) walked up to the first entry ≥ x (a step at most): a table look-up and
    a compare or two, where the binary search took eight unpredictable branches."""
    if x != x:
        return table.shape[0] - 1
    return _walk_up(table, np.int64(lut[np.float32(x).view(np.uint32) >> 16]), x)


@njit(cache=True, nogil=True, inline="always")
def _walk_up(table, c, x):
    # from a prefix's code c (a lower bound) to the first entry ≥ x: a step at most
    while table[c] < x:  # table[-1] = +inf: never past it
        c += 1
    return c


@njit(cache=True, nogil=True, inline="always")
def nest_code_nb(x, y, z, r, codes, table, lut, i, j, h):
    """The code of vertex (i, j) of half-span h with the nesting of seed 002 §2.4
    (L50–52) on the coded values: the smallest code ≥ its radius and ≥ |p_v − p_c| +
    table[code(c)] for each child c (children outside the grid: none); ``lut`` the
    table's :func:`prefix_codes`."""
    R, C = z.shape
    best = np.float64(r[i, j]) if r.shape[0] else 0.0
    for k in range(4):
        ci, cj = child_nb(i, j, h, k)
        if 0 <= ci < R and 0 <= cj < C:
            d = np.sqrt((x[i, j] - x[ci, cj]) ** 2 + (y[i, j] - y[ci, cj]) ** 2
                        + (z[i, j] - z[ci, cj]) ** 2) + table[codes[ci, cj]]
            best = max(best, d)
    return code_lut_nb(table, lut, best)


@njit(cache=True, inline="always")
def _visit(x, y, z, r, rin, table, lut, codes, i, j, h):
    # one vertex of _radii_nb: its float32 radius, or its code nested on the codes
    if table.shape[0] == 0:
        r[i, j] = round_up32(_nest(x, y, z, r, i, j, h))
    else:
        codes[i, j] = nest_code_nb(x, y, z, rin, codes, table, lut, i, j, h)


@parallel_kernel(cache=True, nogil=True)
def _radii_nb(x, y, z, rin, table, lut, codes, n):
    # LP §2.4 (L50–52): r(v) = max over children c of |p_v − p_c| + r(c), fine to coarse;
    # each level is rounded up to float32 before its parents read it. With a log8
    # ``table``: ``codes`` instead, nested on the coded values (tileblobs.radius_codes),
    # covering ``rin`` too where given (``lut``: the table's prefix_codes); the float
    # radii are then not made. The vertices
    # of half-span below 2**n (the square's N − 1, or a root grid's root side).
    R, C = z.shape
    coded = table.shape[0] > 0
    r = np.zeros((0, 0) if coded else (R, C), np.float32)
    if coded:
        for i in prange(R):
            for j in range(C):  # leaves keep their own (0 without radii)
                codes[i, j] = code_lut_nb(table, lut, np.float64(rin[i, j])) if rin.shape[0] \
                    else 0
    h = 1
    while h < 1 << n:
        s = 2 * h
        nr = (R - 1) // s
        nc = (C - 1) // s
        if h >= 2:  # edge midpoints (those of h = 1 are leaves: r = 0)
            for typ in range(2):
                rows = typ == 0
                na = nr if rows else nr + 1
                nb = nc + 1 if rows else nc
                for a in prange(na):
                    for b in range(nb):
                        i = h + a * s if rows else a * s
                        j = b * s if rows else h + b * s
                        _visit(x, y, z, r, rin, table, lut, codes, i, j, h)
        for a in prange(nr):  # centres
            for b in range(nc):
                i = h + a * s
                j = h + b * s
                _visit(x, y, z, r, rin, table, lut, codes, i, j, h)
        h *= 2
    return r

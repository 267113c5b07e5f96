"""The prediction U(.) of the height codec (seed 000 §2.9, Losasso & Hoppe): the new
samples of a level from the coarser level's decoded codes.

One rule, three forms that give the same integers:

- :func:`predict`: numpy on a whole coarse grid (the codec's choice of predictor);
- :func:`fill_level` and ``_pred``: compiled, a whole level at a time (the encoder's
  void fill; :func:`geoterrain.codec.entropy.encode_level` takes its residuals from ``_pred``);
- :func:`cubic_child` and :func:`linear_child`: compiled, one child tile from its parent
  tile (the decoder).

Row midpoints (A) and column midpoints (B) come from the coarse samples; cell centres
(C) from the decoded A samples above and below them and the decoded B samples beside
them: the mean of the midpoint along the column and the one along the row, 16 times
each, rounded (SZ3 interpolates one direction after the other; both directions take
srtm1_japan's heights from 279.6 to 267.9 kB, docs/lab/store-size.md). Linear:
floor-means of the 2 neighbours for A and B; for C the rounded mean of the 4. Cubic:
4-point interpolatory weights (−1, 9, 9, −1)/16, falling back to linear next to a
parent-tile border for A and B and next to a child-tile border for each of C's lines
(so a tile never reads outside its parent, nor a centre outside its own tile).
Arithmetic is int64 modulo 2**64.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["cubic_child", "fill_edges_first", "fill_level", "fill_outward", "linear_child",
           "predict"]


def _mean2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """floor((a + b) / 2) for int64 without overflow."""
    return (a >> 1) + (b >> 1) + (a & b & 1)


def predict(f: np.ndarray, period: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predictions of the new samples of a level grid ``f`` ((2M - 1)², last two axes)
    from its coarse samples ``f[::2, ::2]`` and, for the cell centres, its row midpoints.

    Returns class A (row midpoints, (M, M-1)), B (column midpoints, (M-1, M)) and C (cell
    centres, (M-1, M-1)): the U(.) operator of seed 000 section 2.9, from decoded
    values: A and B from the coarse samples, C from the A samples above and below it
    and the B samples beside it (the decoder has them before C), the mean of the two
    directions.

    ``period=None``: linear, floor-means of the 2 neighbours. ``period=P``: 4-point
    interpolatory (Kobbelt / Dyn-Levin-Gregory) weights (-1, 9, 9, -1)/16, rounded; a
    midpoint between coarse k and k+1 falls back to linear (0, 8, 8, 0)/16 when k-1 or
    k+2 lies outside the parent tile for A and B (k % P == 0 or (k + 1) % P == 0, P =
    parent tile intervals), outside the child tile for each of C's two lines (the same
    with P / 2).

    Examples
    --------
    >>> pa, pb, pc = predict(np.array([[0, 9, 4], [9, 9, 9], [8, 6, 13]], np.int64))
    >>> pa.tolist(), pb.tolist(), pc.tolist()  # C: the rounded mean of 9, 6, 9 and 9
    ([[2], [10]], [[4, 8]], [[8]])
    """
    c = f[..., ::2, ::2]
    a = f[..., ::2, 1::2]
    b = f[..., 1::2, ::2]
    if period is None:
        pa = _mean2(c[..., :, :-1], c[..., :, 1:])
        pb = _mean2(c[..., :-1, :], c[..., 1:, :])
    else:
        pa = (_interp16(c, -1, period) + 8) >> 4
        pb = (_interp16(c, -2, period) + 8) >> 4
    qv, rv = _parts32(a, -2, period and period // 2)
    qw, rw = _parts32(b, -1, period and period // 2)
    return pa, pb, qv + qw + ((rv + rw + 16) >> 5)


def _parts32(c: np.ndarray, axis: int, period: int | None) -> tuple[np.ndarray, np.ndarray]:
    """2 × 16 × the midpoints along ``axis`` (the weights of :func:`_interp16`; linear
    without a period) as q, r with 32 q + r their value: whole multiples of 32 from
    each sample's own ``x >> 5`` and the small rest from its ``x & 31`` (as
    :func:`_centre` computes a cell centre, without a sum that wraps)."""
    c = np.moveaxis(c, axis, -1)
    m = c.shape[-1]
    near = np.full(m - 1, 8, np.int64)
    far = np.zeros(m - 1, np.int64)
    if period is not None and m >= 4:
        k = np.arange(1, m - 2)
        ok = (k % period != 0) & ((k + 1) % period != 0)
        near[1:-1] = np.where(ok, 9, 8)
        far[1:-1] = np.where(ok, -1, 0)
    hi, lo = c >> 5, c & 31
    q = near * (hi[..., :-1] + hi[..., 1:])
    r = near * (lo[..., :-1] + lo[..., 1:])
    if m >= 4:
        q[..., 1:-1] += far[1:-1] * (hi[..., :-3] + hi[..., 3:])
        r[..., 1:-1] += far[1:-1] * (lo[..., :-3] + lo[..., 3:])
    return np.moveaxis(q, -1, axis), np.moveaxis(r, -1, axis)


def _interp16(c: np.ndarray, axis: int, period: int) -> np.ndarray:
    """16 x the midpoint interpolation along ``axis`` (cubic inside tiles, else linear)."""
    c = np.moveaxis(c, axis, -1)
    m = c.shape[-1]
    out = 8 * (c[..., :-1] + c[..., 1:])
    if m >= 4:
        k = np.arange(1, m - 2)
        ok = (k % period != 0) & ((k + 1) % period != 0)
        cub = 9 * (c[..., 1:-2] + c[..., 2:-1]) - c[..., :-3] - c[..., 3:]
        out[..., 1:-1] = np.where(ok, cub, out[..., 1:-1])
    return np.moveaxis(out, -1, axis)


@njit(cache=True, nogil=True)
def _mid16(p, i0, j0, di, dj, k, m):
    """16 × the midpoint between samples k and k + 1 of the line (i0 + di·s, j0 + dj·s) of
    ``p``: cubic (−1, 9, 9, −1) where k − 1 and k + 2 exist in the tile, else linear."""
    a = p[i0 + di * k, j0 + dj * k]
    b = p[i0 + di * (k + 1), j0 + dj * (k + 1)]
    if 1 <= k <= m - 3:
        return 9 * (a + b) - p[i0 + di * (k - 1), j0 + dj * (k - 1)] \
            - p[i0 + di * (k + 2), j0 + dj * (k + 2)]
    return 8 * (a + b)


@njit(cache=True, nogil=True)
def cubic_child(parent, oy, ox, h, r, out):
    """One child quadrant (rows oy.., columns ox.. of ``parent``) from the cubic
    predictions of :func:`predict` (``period`` = the parent's intervals) plus the
    residuals ``r`` (classes A, B, C in raster order), computed only where needed.

    Examples
    --------
    >>> parent = np.arange(25, dtype=np.int64).reshape(5, 5) * 16  # a plane
    >>> out = np.empty((5, 5), np.int64)
    >>> cubic_child(parent, 0, 0, 2, np.zeros(16, np.int64), out)
    >>> out[1].tolist()  # midway between rows 0 and 1 of the parent
    [40, 48, 56, 64, 72]
    """
    m = parent.shape[0]
    z, u = np.int64(0), np.int64(1)  # _mid16's steps as int64: one signature (not literals)
    for a in range(h + 1):
        for b in range(h + 1):
            out[2 * a, 2 * b] = parent[oy + a, ox + b]
    n = 0
    for a in range(h + 1):  # A: row midpoints
        for b in range(h):
            out[2 * a, 2 * b + 1] = ((_mid16(parent, oy + a, z, z, u, ox + b, m) + 8) >> 4) + r[n]
            n += 1
    for a in range(h):  # B: column midpoints
        for b in range(h + 1):
            out[2 * a + 1, 2 * b] = ((_mid16(parent, z, ox + b, u, z, oy + a, m) + 8) >> 4) + r[n]
            n += 1
    for a in range(h):  # C: from the decoded A samples above and B samples beside
        for b in range(h):
            i, j = 2 * a + 1, 2 * b + 1
            out[i, j] = _centre16(out, i, j, a, b, h, True) + r[n]
            n += 1


@njit(cache=True, nogil=True, inline="always")
def _centre(a0, a1, a2, a3, cv, b0, b1, b2, b3, cw):
    """A cell centre's prediction from its A samples above and below (a0, a1; the next
    ones out a2, a3, read when ``cv``: cubic along the column) and its B samples beside
    (b0 … b3, ``cw``: cubic along the row): the rounded mean of the two lines'
    midpoints, ``(v + w + 16) >> 5`` for v, w 16 times each, and ``(v + w) & 31`` (the
    phase's). Computed from each sample's ``x >> 5`` and ``x & 31``: on float bit
    patterns v and w wrap int64, and a shift of a wrapped sum is not kept by the
    compiler (``(v + w + 16) >> 5`` decoded other codes than it encoded)."""
    n, f = (9, -1) if cv else (8, 0)
    m, g = (9, -1) if cw else (8, 0)
    q = n * ((a0 >> 5) + (a1 >> 5)) + m * ((b0 >> 5) + (b1 >> 5))
    r = n * ((a0 & 31) + (a1 & 31)) + m * ((b0 & 31) + (b1 & 31))
    if cv:
        q += f * ((a2 >> 5) + (a3 >> 5))
        r += f * ((a2 & 31) + (a3 & 31))
    if cw:
        q += g * ((b2 >> 5) + (b3 >> 5))
        r += g * ((b2 & 31) + (b3 & 31))
    return q + ((r + 16) >> 5), r & 31


@njit(cache=True, nogil=True, inline="always")
def _centre16(out, i, j, a, b, h, cubic):
    """The prediction of the cell centre (i, j) = (2a + 1, 2b + 1) of a child tile of
    2h + 1 from its decoded A samples above and below and B samples beside
    (:func:`_centre`; cubic along a line where the tile holds both outer samples)."""
    cv = cubic and 1 <= a <= h - 2
    cw = cubic and 1 <= b <= h - 2
    a0, a1, b0, b1 = out[i - 1, j], out[i + 1, j], out[i, j - 1], out[i, j + 1]
    return _centre(a0, a1, out[i - 3, j] if cv else a0, out[i + 3, j] if cv else a1, cv,
                   b0, b1, out[i, j - 3] if cw else b0, out[i, j + 3] if cw else b1, cw)[0]


@njit(cache=True, nogil=True, inline="always")
def _fmean(a, b):
    return (a >> 1) + (b >> 1) + (a & b & 1)  # floor((a + b) / 2), as _mean2


@njit(cache=True, nogil=True)
def linear_child(c, h, r, out):
    """:func:`cubic_child` for the linear predictions of :func:`predict` on the
    quadrant ``c`` ((h + 1)², the parent's samples the child holds).

    Examples
    --------
    >>> out = np.empty((3, 3), np.int64)
    >>> linear_child(np.array([[0, 4], [8, 13]], np.int64), 1, np.zeros(5, np.int64), out)
    >>> out.tolist()
    [[0, 2, 4], [4, 6, 8], [8, 10, 13]]
    """
    for a in range(h + 1):
        for b in range(h + 1):
            out[2 * a, 2 * b] = c[a, b]
    n = 0
    for a in range(h + 1):
        for b in range(h):
            out[2 * a, 2 * b + 1] = _fmean(c[a, b], c[a, b + 1]) + r[n]
            n += 1
    for a in range(h):
        for b in range(h + 1):
            out[2 * a + 1, 2 * b] = _fmean(c[a, b], c[a + 1, b]) + r[n]
            n += 1
    for a in range(h):
        for b in range(h):
            i, j = 2 * a + 1, 2 * b + 1
            out[i, j] = _centre16(out, i, j, a, b, h, False) + r[n]
            n += 1


@njit(cache=True, nogil=True, inline="always")
def _c16(d, s2, i0, j0, di, dj, k, mc, P):
    """16 × the midpoint of coarse samples k, k + 1 on the coarse line (i0 + di·k,
    j0 + dj·k) of the level whose coarse samples are ``d[::s2, ::s2]`` (``mc`` a side):
    the rule of :func:`_interp16` (cubic away from parent-tile borders, else linear)."""
    a = d[(i0 + di * k) * s2, (j0 + dj * k) * s2]
    b = d[(i0 + di * (k + 1)) * s2, (j0 + dj * (k + 1)) * s2]
    if mc >= 4 and 1 <= k <= mc - 3 and k % P != 0 and (k + 1) % P != 0:
        return 9 * (a + b) - d[(i0 + di * (k - 1)) * s2, (j0 + dj * (k - 1)) * s2] \
            - d[(i0 + di * (k + 2)) * s2, (j0 + dj * (k + 2)) * s2]
    return 8 * (a + b)


@njit(cache=True, nogil=True)
def _pred(d, s, i, j, P):
    """The prediction U(.) of :func:`predict` at sample (i, j) (one of i, j odd) of the
    level ``d[::s, ::s]`` from its coarse samples (a cell centre from the A samples of
    its column); ``P`` = 0: linear floor-means, else cubic with period ``P`` (seed 000
    §2.9). A cell centre: the mean of its column's and its row's midpoints."""
    s2 = 2 * s
    ci, cj = i >> 1, j >> 1
    if P == 0:
        if i & 1 == 0:  # A: row midpoint
            return _fmean(d[ci * s2, cj * s2], d[ci * s2, (cj + 1) * s2])
        if j & 1 == 0:  # B: column midpoint
            return _fmean(d[ci * s2, cj * s2], d[(ci + 1) * s2, cj * s2])
        # C: the A samples above and below and the B samples beside (same level)
        return _centre(d[(i - 1) * s, j * s], d[(i + 1) * s, j * s], 0, 0, False,
                       d[i * s, (j - 1) * s], d[i * s, (j + 1) * s], 0, 0, False)[0]
    mr, mc = (d.shape[0] - 1) // s2 + 1, (d.shape[1] - 1) // s2 + 1  # coarse rows, cols
    if i & 1 == 0:  # along a row: the coarse columns
        return (_c16(d, s2, ci, 0, 0, 1, cj, mc, P) + 8) >> 4
    if j & 1 == 0:  # along a column: the coarse rows
        return (_c16(d, s2, 0, cj, 1, 0, ci, mr, P) + 8) >> 4
    # C: the mean of the midpoints along the column through the A samples (rows 2k,
    # 2k + 2 of the level) and along the row through the B samples, each cubic inside
    # the child tile (period P / 2 in coarse rows or columns)
    h = P >> 1
    cv = mr >= 4 and 1 <= ci <= mr - 3 and ci % h != 0 and (ci + 1) % h != 0
    cw = mc >= 4 and 1 <= cj <= mc - 3 and cj % h != 0 and (cj + 1) % h != 0
    a0, a1 = d[(i - 1) * s, j * s], d[(i + 1) * s, j * s]
    b0, b1 = d[i * s, (j - 1) * s], d[i * s, (j + 1) * s]
    return _centre(a0, a1, d[(i - 3) * s, j * s] if cv else a0,
                   d[(i + 3) * s, j * s] if cv else a1, cv,
                   b0, b1, d[i * s, (j - 3) * s] if cw else b0,
                   d[i * s, (j + 3) * s] if cw else b1, cw)[0]


@njit(cache=True, nogil=True)
def fill_level(d, valid, s, P, W=1):
    """In place, the decoded codes of level ``d[::s, ::s]``'s new samples: an invalid
    one takes its prediction (``P`` = 0: linear, else cubic with period ``P``), a valid
    one (``W`` > 1, the residual bins) its prediction plus ``W`` times its residual
    rounded to bins, ``p + W · round((d - p) / W)`` (SZ3's linear quantisation, the
    prediction from decoded codes); the row and column midpoints, then the cell
    centres (predicted from the decoded row midpoints).

    Examples
    --------
    >>> d = np.array([[0, 9, 4], [9, 9, 9], [8, 9, 13]], np.int64)
    >>> fill_level(d, np.eye(3, dtype=bool) | np.eye(3, dtype=bool)[::-1], 1, 0)
    >>> d.tolist()
    [[0, 2, 4], [4, 9, 8], [8, 10, 13]]
    >>> d = np.array([[0, 9, 4], [9, 9, 9], [8, 9, 13]], np.int64)
    >>> fill_level(d, np.ones((3, 3), bool), 1, 0, 3)  # within 1 of each code
    >>> d.tolist()
    [[0, 8, 4], [10, 9, 8], [8, 10, 13]]
    """
    m0, m1 = (d.shape[0] - 1) // s + 1, (d.shape[1] - 1) // s + 1  # a rectangle too
    h = W >> 1
    for centres in (False, True):
        for i in range(m0):
            for j in range(m1):
                if (i & 1 or j & 1) and bool(i & 1 and j & 1) == centres:
                    if not valid[i * s, j * s]:
                        d[i * s, j * s] = _pred(d, s, i, j, P)
                    elif W > 1:
                        p = _pred(d, s, i, j, P)
                        d[i * s, j * s] = p + W * ((d[i * s, j * s] - p + h) // W)


@njit(cache=True, nogil=True)
def fill_outward(f, known):
    """In place on ``f`` (2-D int64): every sample not ``known`` is filled from the known
    ones, ring by ring outward (breadth first from all of them, so the order inside a
    ring does not matter): next to a known sample, the mean of the linear
    extrapolations ``2a - b`` from the known pairs (a, b) that lead to it along a row or
    column (else of its known neighbours a); further out, the floor-mean of its
    neighbours one ring nearer. Nothing changes when no sample is known.

    The codec's fill of a top tile's invalid samples (:mod:`geoterrain.codec.pyramid`): an
    invalid sample's interpolated prediction can land far from the terrain beside it,
    and the finer levels predict the valid samples next to a void or the padding from
    it. SZ3 extrapolates linearly at an array's border for the same reason; past the
    first ring the fill is flat, so it stays within a slope of the data's range.

    Examples
    --------
    >>> f = np.array([[5, 0, 0], [0, 0, 0], [0, 0, 9]], np.int64)
    >>> fill_outward(f, np.eye(3, dtype=np.bool_) & (f > 0))
    >>> f.tolist()
    [[5, 5, 7], [5, 7, 9], [7, 9, 9]]
    >>> f = np.array([[1, 4, 0, 0]], np.int64)  # a slope of 3, then flat
    >>> fill_outward(f, f > 0)
    >>> f.tolist()
    [[1, 4, 7, 7]]
    """
    n0, n1 = f.shape
    dist = np.full((n0, n1), -1, np.int64)
    queue = np.empty(n0 * n1, np.int64)
    tail = 0
    for i in range(n0):
        for j in range(n1):
            if known[i, j]:
                dist[i, j] = 0
                queue[tail] = i * n1 + j
                tail += 1
    head = 0
    while head < tail:  # breadth first: each sample's ring, in ring order
        i, j = divmod(queue[head], n1)
        head += 1
        r = dist[i, j]
        if r > 0:
            base, acc, c = np.int64(0), np.int64(0), 0  # the copies (offsets: no overflow)
            ebase, eacc, ec = np.int64(0), np.int64(0), 0  # the extrapolations
            for di, dj in ((-1, 0), (0, -1), (0, 1), (1, 0)):
                y, x = i + di, j + dj
                if 0 <= y < n0 and 0 <= x < n1 and 0 <= dist[y, x] < r:
                    if c == 0:
                        base = f[y, x]
                    acc += f[y, x] - base
                    c += 1
                    yy, xx = y + di, x + dj
                    if r == 1 and 0 <= yy < n0 and 0 <= xx < n1 and dist[yy, xx] == 0:
                        e = 2 * f[y, x] - f[yy, xx]
                        if ec == 0:
                            ebase = e
                        eacc += e - ebase
                        ec += 1
            f[i, j] = ebase + eacc // ec if ec else base + acc // c
        for di, dj in ((-1, 0), (0, -1), (0, 1), (1, 0)):
            y, x = i + di, j + dj
            if 0 <= y < n0 and 0 <= x < n1 and dist[y, x] < 0:
                dist[y, x] = r + 1
                queue[tail] = y * n1 + x
                tail += 1


@njit(cache=True, nogil=True)
def fill_edges_first(f, known):
    """:func:`fill_outward` for a root of a root grid, whose edges it shares with its
    neighbours: each of the four edges that holds a known sample is filled first along
    itself alone (a root's corners are always known: coded), then the rest with those
    edges known. So an edge's fill depends on that edge's samples only, and two roots
    that share an edge decode the same codes on it.

    Examples
    --------
    >>> f = np.array([[5, 0, 1], [0, 9, 0], [3, 0, 7]], np.int64)
    >>> known = f != 0
    >>> fill_edges_first(f, known)
    >>> f.tolist()  # each edge from its own corners, not from the centre's 9
    [[5, 3, 1], [4, 9, 4], [3, 5, 7]]
    """
    n0, n1 = f.shape
    k = known.copy()
    for e in range(4):  # top, bottom rows; left, right columns
        i = 0 if e == 0 else n0 - 1
        j = 0 if e == 2 else n1 - 1
        row = e < 2
        line = f[i:i + 1, :].copy() if row else f[:, j:j + 1].copy()
        lk = known[i:i + 1, :].copy() if row else known[:, j:j + 1].copy()
        if not lk.any():
            continue  # left to the fill of the rest
        fill_outward(line, lk)
        if row:  # the line back in place, as a loop (see entropy._top)
            for q in range(n1):
                f[i, q] = line[0, q]
            k[i, :] = True
        else:
            for q in range(n0):
                f[q, j] = line[q, 0]
            k[:, j] = True
    fill_outward(f, k)

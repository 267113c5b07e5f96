"""Compiled kernels of ROAM (seed 000 §2.2): the triangle-bintree pool with its split and
merge queues, and the leaves as a mesh (the wedgie thicknesses they read are computed
once per terrain by :mod:`geoterrain.lod.roamwedgies`).

Triangles follow the project's bintree (docs/conventions.md): ``(a, b, c)`` with
hypotenuse a–b and apex c, children ``(c, a, m)`` and ``(b, c, m)``, m the midpoint of
a–b; vertices are flat sample ids ``i·N + j``. A triangle's neighbours are kept as in
McNally's split code: ``left`` across c–a, ``right`` across b–c, ``base`` across a–b.
A triangle with hypotenuse midpoint m is one of the (one or) two halves of m's diamond,
told apart by its apex: ``side`` 0 for the first parent of :func:`parents_nb`, 1 for the
second. Per-triangle tables are indexed ``2·m + side``.

A pool slot's numbers are packed in two rows, ``iv[T]`` (integers, columns ``A`` …
``KF``) and ``fv[T]`` (floats, ``E`` … ``PRIO``): the helpers take these arrays, not the
named tuples, which numba would reference-count member by member on every call.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.lod.roamwedgies import diamond_side

NEED_SPACE = 1  # a kernel stopped: the pool needs more slots (grow, then call again)
# iv columns: vertices a, b, c; neighbours left (c–a), right (b–c), base (a–b); children;
# parent; bintree depth; alive; tile-table slot (−1: none); frame of the last score
A, B, C, LEFT, RIGHT, BASE, K0, K1, PAR, DEP, ALIVE, TS, KF = range(13)
NI = 13
# fv columns: wedgie thickness e; the wedgie's box (lo x, y, z, hi x, y, z); the deferral
# slacks of the last score (distance, frustum margin, farthest corner); the priority
E, BOX, SD, SM, RF, PRIO = 0, 1, 7, 8, 9, 10
NF = 11


class RoamTables(NamedTuple):
    """What the kernels read of a terrain: ``Z`` (N², scene z, NaN = no data), ``wedge``
    and ``var`` (2N², float32: eq. 4-1's wedgie thickness and eq. 4-2's variance per
    triangle), ``aff`` (9: an affine frame's geotransform, origin and unit; empty for
    a curvilinear frame, whose ``XY`` (2, N²) holds every sample's x, y), ``zr`` (global
    zmin, zmax, the xy margin of a curvilinear frame), ``hid`` (per dense tile-table
    slot, 1 = hidden this frame; empty: none), ``tile`` (the dense table's level offsets,
    each level's tiles across, then down, then t, top and N), ``size`` (N, n): N the
    stride of the flat sample ids (a root grid's extent columns), ``roots`` (K, 6): the
    depth-0 triangles' a, b, c and left, right, base neighbours (−1: none), two per root
    tile (:func:`geoterrain.lod.roam.base_triangles`)."""

    Z: np.ndarray
    wedge: np.ndarray
    var: np.ndarray
    aff: np.ndarray
    XY: np.ndarray
    zr: np.ndarray
    hid: np.ndarray
    tile: np.ndarray
    size: np.ndarray
    roots: np.ndarray


class Pool(NamedTuple):
    """The triangle pool, one slot per triangle (leaves and inner ones): ``iv`` (cap, NI)
    and ``fv`` (cap, NF) (see the column names), the ``free`` slot stack, ``meta`` =
    [slots used, free count, splits, merges, scores], and the queue arrays ``hk`` (keys)
    and ``hv`` (triangles), shared by the split and merge queues."""

    iv: np.ndarray
    fv: np.ndarray
    free: np.ndarray
    meta: np.ndarray
    hk: np.ndarray
    hv: np.ndarray


class Motion(NamedTuple):
    """The camera's motion for deferred re-scoring: ``cum`` and ``ang`` (per frame number,
    the eye's path length and the frustum's turn in radians, cumulated), ``hidk`` (per
    tile-table slot, the last frame its horizon culling changed) and ``now`` = [frame
    number, cumulated path, cumulated turn, 1 to re-score everything]."""

    cum: np.ndarray
    ang: np.ndarray
    hidk: np.ndarray
    now: np.ndarray


def new_pool(cap: int) -> Pool:
    """An empty pool of ``cap`` slots (:func:`reset` puts the base triangles in)."""
    iv = np.full((cap, NI), -1, np.int64)
    iv[:, ALIVE] = 0
    return Pool(iv, np.zeros((cap, NF)), np.zeros(cap, np.int64), np.zeros(8, np.int64),
                np.zeros(cap), np.zeros(cap, np.int64))


def grow_pool(p: Pool) -> Pool:
    """The same pool with twice the slots."""
    cap = len(p.iv)
    out = new_pool(2 * cap)
    out.iv[:cap], out.fv[:cap], out.free[:cap] = p.iv, p.fv, p.free
    out.meta[:] = p.meta
    return out


# ------------------------------------------------------------------ geometry, priorities
@njit(cache=True)
def _xy(aff, XY, N, v):
    if aff.shape[0] == 0:
        return XY[0, v], XY[1, v]
    i, j = v // N, v % N
    jj, ii = j + 0.5, i + 0.5
    x = aff[0] * jj + aff[1] * ii + aff[2]
    y = aff[3] * jj + aff[4] * ii + aff[5]
    return (x - aff[6]) * aff[8], (y - aff[7]) * aff[8]


@njit(cache=True)
def _wedge_index(N, va, vb, vc):
    """The per-triangle table index 2·m + side of triangle (va, vb, vc), and m."""
    mi = (va // N + vb // N) // 2
    mj = (va % N + vb % N) // 2
    return 2 * (mi * N + mj) + diamond_side(mi, mj, vc // N, vc % N), mi * N + mj


@njit(cache=True)
def _tile_slot(tile, N, va, vb, vc):
    """The dense tile-table slot of the smallest tile footprint holding the triangle
    (``tile``: the level offsets, each level's tiles across, then down, then t and top);
    −1 where none of the grid's tiles holds it."""
    ia, ib, ic = va // N, vb // N, vc // N
    ja, jb, jc = va % N, vb % N, vc % N
    i0, i1 = min(ia, ib, ic), max(ia, ib, ic)
    j0, j1 = min(ja, jb, jc), max(ja, jb, jc)
    nb = (tile.shape[0] - 3) // 3
    t, top = tile[3 * nb], tile[3 * nb + 1]
    for L in range(top + 1):
        S = 1 << (t + L)
        across, down = tile[nb + L], tile[2 * nb + L]
        y, x = i0 // S, j0 // S
        if y == down:
            y -= 1
        if x == across:
            x -= 1
        if y < down and x < across and i1 <= (y + 1) * S and j1 <= (x + 1) * S:
            return tile[L] + y * across + x
    return -1


@njit(cache=True)
def _static(iv, fv, T, Z, wedge, aff, XY, zr, tile, N, n):
    """What T's geometry fixes, set once when it is made: its wedgie thickness e (0 for a
    finest triangle), the wedgie's box (the corners' x, y, grown by a curvilinear frame's
    margin; their heights ± e within the terrain's range) and its tile slot."""
    va, vb, vc = iv[T, A], iv[T, B], iv[T, C]
    e = 0.0
    if iv[T, DEP] < 2 * n:
        q, _ = _wedge_index(N, va, vb, vc)
        e = np.float64(wedge[q])
    fv[T, E] = e
    xa, ya = _xy(aff, XY, N, va)
    xb, yb = _xy(aff, XY, N, vb)
    xc, yc = _xy(aff, XY, N, vc)
    g = zr[2]
    fv[T, BOX + 0] = min(xa, xb, xc) - g
    fv[T, BOX + 1] = min(ya, yb, yc) - g
    fv[T, BOX + 3] = max(xa, xb, xc) + g
    fv[T, BOX + 4] = max(ya, yb, yc) + g
    za, zb, zc = Z[va], Z[vb], Z[vc]
    if np.isfinite(za) and np.isfinite(zb) and np.isfinite(zc) and np.isfinite(e):
        fv[T, BOX + 2] = max(min(za, zb, zc) - e, zr[0])
        fv[T, BOX + 5] = min(max(za, zb, zc) + e, zr[1])
    else:
        fv[T, BOX + 2], fv[T, BOX + 5] = zr[0], zr[1]
    iv[T, TS] = _tile_slot(tile, N, va, vb, vc)


@njit(cache=True)
def _outside(planes, fv, T):
    for q in range(planes.shape[0]):
        a0, a1, a2, a3 = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
        x = fv[T, BOX + 3] if a0 >= 0 else fv[T, BOX + 0]
        y = fv[T, BOX + 4] if a1 >= 0 else fv[T, BOX + 1]
        z = fv[T, BOX + 5] if a2 >= 0 else fv[T, BOX + 2]
        if a0 * x + a1 * y + a2 * z + a3 < 0:
            return True
    return False


@njit(cache=True)
def _hidden(hid, ts):
    return hid.shape[0] > 0 and ts >= 0 and hid[ts] != 0


@njit(cache=True)
def _score(iv, fv, T, k, planes, eye, lam, tau, hid):
    """ROAM's priority of triangle T (seed 000 L1381): λ·e_T / D_min(wedgie box), eq. 4-1's
    thickness projected at its nearest point, so a leaf with priority ≤ τ has ρ ≤ τ; 0
    for a finest triangle, outside the frustum or hidden. Monotone: a child's wedgie and
    box lie inside its parent's. Records, for frame ``k``, how far the camera may move
    before the priority can cross τ (the deferral slacks). Returns the priority and
    D_min (inf when 0 for another reason)."""
    iv[T, KF] = k
    inf = np.inf
    e = fv[T, E]
    if e == 0.0:
        fv[T, SD], fv[T, SM] = inf, inf
        return 0.0, inf
    # frustum: outside when one plane has the whole box behind it; the margin is how far
    # the nearest decision is from flipping
    worst_out = -inf  # outside: the largest depth behind a plane
    least_in = inf  # not outside: the smallest reach of the farthest corner
    for q in range(planes.shape[0]):
        a0, a1, a2, a3 = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
        if a0 == 0.0 and a1 == 0.0 and a2 == 0.0:
            continue  # no plane (no far plane): nothing can flip
        x = fv[T, BOX + 3] if a0 >= 0 else fv[T, BOX + 0]
        y = fv[T, BOX + 4] if a1 >= 0 else fv[T, BOX + 1]
        z = fv[T, BOX + 5] if a2 >= 0 else fv[T, BOX + 2]
        dq = a0 * x + a1 * y + a2 * z + a3
        if dq < 0:
            worst_out = max(worst_out, -dq)
        else:
            least_in = min(least_in, dq)
    lx, ly, lz = fv[T, BOX + 0] - eye[0], fv[T, BOX + 1] - eye[1], fv[T, BOX + 2] - eye[2]
    hx, hy, hz = fv[T, BOX + 3] - eye[0], fv[T, BOX + 4] - eye[1], fv[T, BOX + 5] - eye[2]
    fx, fy, fz = max(-lx, hx), max(-ly, hy), max(-lz, hz)
    fv[T, RF] = np.sqrt(fx * fx + fy * fy + fz * fz)
    if worst_out > -inf:
        fv[T, SM], fv[T, SD] = worst_out, inf
        return 0.0, inf
    if _hidden(hid, iv[T, TS]):
        fv[T, SM], fv[T, SD] = inf, inf
        return 0.0, inf
    fv[T, SM] = least_in
    dx, dy, dz = max(lx, 0.0, -hx), max(ly, 0.0, -hy), max(lz, 0.0, -hz)
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    fv[T, SD] = abs(d - lam * e / tau)  # D may move by this much before p crosses τ
    return (inf if d == 0 else lam * e / d), d


@njit(cache=True)
def _mcnally(iv, fv, T, var, Z, aff, XY, N, eye, lam):
    """McNally's priority (eq. 4-2): λ·variance / distance to the split vertex."""
    va, vb, vc = iv[T, A], iv[T, B], iv[T, C]
    q, m = _wedge_index(N, va, vb, vc)
    xm, ym = _xy(aff, XY, N, m)
    zm = Z[m]
    if not np.isfinite(zm):
        zm = 0.5 * (fv[T, BOX + 2] + fv[T, BOX + 5])
    d = np.sqrt((xm - eye[0]) ** 2 + (ym - eye[1]) ** 2 + (zm - eye[2]) ** 2)
    return np.inf if d == 0 else lam * np.float64(var[q]) / d


# ------------------------------------------------------------------ queues
@njit(cache=True)
def _push(hk, hv, n, key, val):
    """Push onto the min-heap hk/hv of size n; returns the new size."""
    k = n
    hk[k], hv[k] = key, val
    while k > 0:
        up = (k - 1) // 2
        if hk[up] <= hk[k]:
            break
        hk[up], hk[k] = hk[k], hk[up]
        hv[up], hv[k] = hv[k], hv[up]
        k = up
    return n + 1


@njit(cache=True)
def _pop(hk, hv, n):
    """Pop the least key of the min-heap of size n: (value, new size)."""
    val = hv[0]
    n -= 1
    hk[0], hv[0] = hk[n], hv[n]
    k = 0
    while True:
        a = 2 * k + 1
        if a >= n:
            break
        b = a + 1
        c = b if b < n and hk[b] < hk[a] else a
        if hk[k] <= hk[c]:
            break
        hk[c], hk[k] = hk[k], hk[c]
        hv[c], hv[k] = hv[k], hv[c]
        k = c
    return val, n


# ------------------------------------------------------------------ split / merge
@njit(cache=True)
def _alloc(iv, free, meta):
    if meta[1] > 0:
        meta[1] -= 1
        s = free[meta[1]]
    else:
        s = meta[0]
        meta[0] += 1
    for c in range(NI):
        iv[s, c] = -1
    iv[s, ALIVE] = 1
    return s


@njit(cache=True)
def _release(iv, free, meta, s):
    iv[s, ALIVE] = 0
    free[meta[1]] = s
    meta[1] += 1


@njit(cache=True)
def _repoint(iv, X, old, new):
    """Neighbour X's pointer to ``old`` now points to ``new``."""
    if X < 0:
        return
    for c in (LEFT, RIGHT, BASE):
        if iv[X, c] == old:
            iv[X, c] = new
            return


@njit(cache=True)
def _children(iv, free, meta, X, N):
    """Make X's children (c, a, m) and (b, c, m) and link them inside X's place."""
    va, vb, vc = iv[X, A], iv[X, B], iv[X, C]
    m = ((va // N + vb // N) // 2) * N + (va % N + vb % N) // 2
    c0 = _alloc(iv, free, meta)
    c1 = _alloc(iv, free, meta)
    iv[c0, A], iv[c0, B], iv[c0, C] = vc, va, m
    iv[c1, A], iv[c1, B], iv[c1, C] = vb, vc, m
    iv[c0, PAR], iv[c1, PAR] = X, X
    iv[c0, DEP] = iv[X, DEP] + 1
    iv[c1, DEP] = iv[X, DEP] + 1
    iv[X, K0], iv[X, K1] = c0, c1
    iv[c0, LEFT], iv[c1, RIGHT] = c1, c0
    iv[c0, BASE], iv[c1, BASE] = iv[X, LEFT], iv[X, RIGHT]
    _repoint(iv, iv[X, LEFT], X, c0)
    _repoint(iv, iv[X, RIGHT], X, c1)
    return c0, c1


@njit(cache=True)
def _split(iv, free, meta, X, stack, N):
    """Split X with its diamond, forcing the splits it needs first (seed 000 L1279–1287):
    a base neighbour one level coarser is split first, recursively (an explicit stack).
    Returns the number of triangles split."""
    stack[0] = X
    top = 1
    count = 0
    while top > 0:
        T = stack[top - 1]
        if iv[T, K0] >= 0:
            top -= 1
            continue
        Bn = iv[T, BASE]
        if Bn >= 0 and iv[Bn, BASE] != T:
            stack[top] = Bn  # forced split of the coarser base neighbour
            top += 1
            continue
        t0, t1 = _children(iv, free, meta, T, N)
        count += 1
        if Bn >= 0:
            b0, b1 = _children(iv, free, meta, Bn, N)
            count += 1
            iv[t0, RIGHT], iv[t1, LEFT] = b1, b0
            iv[b0, RIGHT], iv[b1, LEFT] = t1, t0
        top -= 1
    return count


@njit(cache=True)
def _leaf_kids(iv, X):
    a = iv[X, K0]
    return a >= 0 and iv[a, K0] < 0 and iv[iv[X, K1], K0] < 0


@njit(cache=True)
def _mergeable(iv, X):
    """X's diamond can merge: X and its base (if any) are split, into leaves."""
    if not _leaf_kids(iv, X):
        return False
    Bn = iv[X, BASE]
    return Bn < 0 or (iv[Bn, BASE] == X and _leaf_kids(iv, Bn))


@njit(cache=True)
def _merge_one(iv, free, meta, X):
    c0, c1 = iv[X, K0], iv[X, K1]
    iv[X, LEFT] = iv[c0, BASE]
    iv[X, RIGHT] = iv[c1, BASE]
    _repoint(iv, iv[c0, BASE], c0, X)
    _repoint(iv, iv[c1, BASE], c1, X)
    _release(iv, free, meta, c0)
    _release(iv, free, meta, c1)
    iv[X, K0] = -1
    iv[X, K1] = -1


@njit(cache=True)
def _diamond_prio(iv, fv, X):
    Bn = iv[X, BASE]
    return fv[X, PRIO] if Bn < 0 else max(fv[X, PRIO], fv[Bn, PRIO])


@njit(cache=True, nogil=True)
def update(p, tb, vt, mode, incremental, stack, mo):
    """One frame of ROAM (seed 000 Listing 4-2): re-score the mesh of the last frame,
    then split every leaf whose priority exceeds τ, highest first (split queue, forced
    splits included), then merge every mergeable diamond whose priority max(p(T), p(T_B))
    is ≤ τ, lowest first (merge queue; a merge may make the parent's diamond mergeable).
    With monotone priorities the result is the coarsest conforming mesh whose leaves all
    have priority ≤ τ, whatever the last frame was, and the work follows the triangles
    that change. ``incremental=False``: split only, from the base triangles
    (Listing 4-1; McNally). ``mode`` 0: wedgie priorities; 1: McNally's. Returns 0, or
    NEED_SPACE when the pool must grow first (call again: the mesh is consistent
    between operations).

    Re-scoring is deferred (seed 000 L1392, lazy priority recomputation by camera-speed
    bounds): a triangle scored at frame k keeps its priority while the eye's path since
    then (dC) and the frustum's turn (dA) cannot have flipped either decision: its
    distance D moves by at most dC, a frustum plane's distance to its box by at most
    dC + dA·(rfar + dC); and while its horizon culling has not changed (``mo.hidk``).
    Only which side of τ a priority lies on decides the mesh, so the result is the same."""
    iv, fv, free, meta, hk, hv = p
    Z, wedge, var, aff, XY, zr, hid, tile, size, _ = tb
    N, nlev = size[0], size[1]
    eye, planes, lam, tau = vt.eye, vt.planes, vt.lam, vt.tau
    cum, ang, hidk, now = mo
    k = np.int64(now[0])
    Cn, An = now[1], now[2]
    full = now[3] != 0
    used = meta[0]
    for T in range(used):
        if iv[T, ALIVE] == 0:
            continue
        if iv[T, KF] < 0:  # made since the last score (reset): its geometry first
            _static(iv, fv, T, Z, wedge, aff, XY, zr, tile, N, nlev)
        elif not full:
            kt = iv[T, KF]
            dC = Cn - cum[kt]
            mu = dC + (An - ang[kt]) * (fv[T, RF] + dC)
            ts = iv[T, TS]
            if mu < fv[T, SM] and dC < fv[T, SD] and (ts < 0 or hidk[ts] <= kt):
                continue  # deferred: its side of τ cannot have changed
        pr, d = _score(iv, fv, T, k, planes, eye, lam, tau, hid)
        if mode == 1 and d < np.inf:
            fv[T, SD] = 0.0  # (McNally's frames are never deferred)
            pr = _mcnally(iv, fv, T, var, Z, aff, XY, N, eye, lam)
        fv[T, PRIO] = pr
        meta[4] += 1
    reserve = 4 * (2 * nlev + 2)
    # split queue: a max-heap as a min-heap on −priority
    n = 0
    for T in range(used):
        if iv[T, ALIVE] == 1 and iv[T, K0] < 0 and fv[T, PRIO] > tau:
            n = _push(hk, hv, n, -fv[T, PRIO], T)
    while n > 0:
        if meta[1] + (iv.shape[0] - meta[0]) < reserve:
            return NEED_SPACE
        T, n = _pop(hk, hv, n)
        if iv[T, ALIVE] == 0 or iv[T, K0] >= 0 or not (fv[T, PRIO] > tau):
            continue
        before, nfree = meta[0], meta[1]
        meta[2] += _split(iv, free, meta, T, stack, N)
        # the new triangles, in fresh slots and in slots reused from the free stack
        for r in range(2):
            lo_, hi_ = (before, meta[0]) if r == 0 else (meta[1], nfree)
            for q in range(lo_, hi_):
                S = q if r == 0 else free[q]
                if iv[S, ALIVE] == 0 or iv[S, KF] >= 0:
                    continue
                _static(iv, fv, S, Z, wedge, aff, XY, zr, tile, N, nlev)
                pr, d = _score(iv, fv, S, k, planes, eye, lam, tau, hid)
                if mode == 1 and d < np.inf:
                    fv[S, SD] = 0.0
                    pr = _mcnally(iv, fv, S, var, Z, aff, XY, N, eye, lam)
                fv[S, PRIO] = pr
                meta[4] += 1
                if iv[S, K0] < 0 and pr > tau:
                    n = _push(hk, hv, n, -pr, S)
    if not incremental:
        return 0
    # merge queue: diamonds (each named by one of its triangles) lowest priority first
    n = 0
    for T in range(meta[0]):
        if iv[T, ALIVE] == 1 and _mergeable(iv, T):
            Bn = iv[T, BASE]
            if 0 <= Bn < T:
                continue  # the diamond is queued once, by its lower slot
            pr = _diamond_prio(iv, fv, T)
            if pr <= tau:
                n = _push(hk, hv, n, pr, T)
    while n > 0:
        T, n = _pop(hk, hv, n)
        if iv[T, ALIVE] == 0 or not _mergeable(iv, T):
            continue
        Bn = iv[T, BASE]
        _merge_one(iv, free, meta, T)
        if Bn >= 0:
            _merge_one(iv, free, meta, Bn)
        meta[3] += 1
        for r in range(2):  # T's and B's parents: their diamonds may merge now
            P = iv[T, PAR] if r == 0 else (iv[Bn, PAR] if Bn >= 0 else -1)
            if P >= 0 and iv[P, ALIVE] == 1 and _mergeable(iv, P):
                pr = _diamond_prio(iv, fv, P)
                if pr <= tau:
                    n = _push(hk, hv, n, pr, P)
    return 0


# ------------------------------------------------------------------ the mesh
@njit(cache=True, nogil=True)
def emit(p, tb, planes, vmap, verts, faces, depth):
    """The drawn leaves: each leaf in the frustum ``planes``, not hidden, with three valid
    corners, as local faces (counter-clockwise) into ``verts`` (flat sample ids, first
    use order; 3× the rows of ``faces``); ``vmap`` (N², int32, all −1) numbers them and
    is left all −1. Returns (V, F)."""
    iv, fv = p.iv, p.fv
    Z, hid = tb.Z, tb.hid
    V = 0
    F = 0
    for T in range(p.meta[0]):
        if iv[T, ALIVE] == 0 or iv[T, K0] >= 0:
            continue
        va, vb, vc = iv[T, A], iv[T, B], iv[T, C]
        if not (np.isfinite(Z[va]) and np.isfinite(Z[vb]) and np.isfinite(Z[vc])):
            continue
        if _outside(planes, fv, T) or _hidden(hid, iv[T, TS]):
            continue
        for q in range(3):
            w = iv[T, q]
            if vmap[w] < 0:
                verts[V] = w
                vmap[w] = V
                V += 1
            faces[F, q] = vmap[w]
        depth[F] = iv[T, DEP]
        F += 1
    for q in range(V):
        vmap[verts[q]] = -1
    return V, F


@njit(cache=True, nogil=True)
def reset(p, tb):
    """Empty the pool in place back to the base triangles, two per root tile (a
    from-scratch frame)."""
    iv, meta = p.iv, p.meta
    for T in range(meta[0]):
        for c in range(NI):
            iv[T, c] = -1
        iv[T, ALIVE] = 0
    roots = tb.roots
    for T in range(roots.shape[0]):
        iv[T, A], iv[T, B], iv[T, C] = roots[T, 0], roots[T, 1], roots[T, 2]
        iv[T, LEFT], iv[T, RIGHT], iv[T, BASE] = roots[T, 3], roots[T, 4], roots[T, 5]
        iv[T, ALIVE] = 1
        iv[T, DEP] = 0  # (KF = −1: update() sets its geometry and scores it)
    meta[0] = roots.shape[0]
    meta[1] = 0

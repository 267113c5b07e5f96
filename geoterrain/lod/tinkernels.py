"""Compiled kernels of the greedy-insertion TIN (Garland & Heckbert's refinement on a
Delaunay triangulation, the algorithm of Fogleman's hmm and Mapbox's Delatin).

The triangulation starts from the two triangles of the data rectangle and inserts, one
at a time, the sample of largest error of the triangle of largest error; each new
triangle's error is found by scanning every grid sample it covers (closed: edges and
corners included), so the bound is exact over the samples, not estimated. Triangles
are kept with half-edges (``tri[3t + k]`` the vertex, ``half[3t + k]`` the opposite
half-edge of edge k, −1 on the rectangle's border); a max-heap orders them by error.

Nodata: a triangle whose corners are all valid and which covers an invalid sample, or a
triangle with an invalid corner that covers a valid sample other than its corners, has
error +∞ and inserts that sample; so a drawn triangle (three valid corners) never spans
a void, and voids are refined to their border, as rtin's mixed diamonds (δ = ∞) are.

Vertices are flat sample ids ``i·W + j`` (row i, column j); x = j, y = i below.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# cnt slots: points, triangles, heap length, pending length
NP, NT, NH, NPEND = 0, 1, 2, 3


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _orient(ax, ay, bx, by, cx, cy):
    return (bx - cx) * (ay - cy) - (by - cy) * (ax - cx)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _in_circle(ax, ay, bx, by, cx, cy, px, py):
    dx, dy = ax - px, ay - py
    ex, ey = bx - px, by - py
    fx, fy = cx - px, cy - py
    ap = dx * dx + dy * dy
    bp = ex * ex + ey * ey
    cp = fx * fx + fy * fy
    return dx * (ey * cp - bp * fy) - dy * (ex * cp - bp * fx) + ap * (ex * fy - ey * fx) < 0


# ------------------------------------------------------------------ the priority queue
# qi[t]: t's heap position (≥ 0), −1 when t is nowhere, −2 − k when t is pending[k]

@njit(cache=True, nogil=True, error_model="numpy")
def _heap_up(heap, qi, err, k):
    t = heap[k]
    while k > 0:
        p = (k - 1) >> 1
        if err[heap[p]] >= err[t]:
            break
        heap[k] = heap[p]
        qi[heap[k]] = k
        k = p
    heap[k] = t
    qi[t] = k


@njit(cache=True, nogil=True, error_model="numpy")
def _heap_down(heap, qi, err, k, n):
    t = heap[k]
    while True:
        c = 2 * k + 1
        if c >= n:
            break
        if c + 1 < n and err[heap[c + 1]] > err[heap[c]]:
            c += 1
        if err[heap[c]] <= err[t]:
            break
        heap[k] = heap[c]
        qi[heap[k]] = k
        k = c
    heap[k] = t
    qi[t] = k


@njit(cache=True, nogil=True, error_model="numpy")
def _forget(t, heap, qi, err, pending, cnt):
    """Take triangle ``t`` out of the heap or the pending list (its slot is rewritten)."""
    k = qi[t]
    if k >= 0:
        n = cnt[NH] - 1
        cnt[NH] = n
        if k != n:
            moved = heap[n]
            heap[k] = moved
            qi[moved] = k
            _heap_down(heap, qi, err, k, n)
            _heap_up(heap, qi, err, qi[moved])
    elif k <= -2:
        p = -2 - k
        n = cnt[NPEND] - 1
        cnt[NPEND] = n
        if p != n:
            pending[p] = pending[n]
            qi[pending[p]] = -2 - p
    qi[t] = -1


@njit(cache=True, nogil=True, error_model="numpy")
def _set_triangle(tri, half, qi, pending, cnt, e, a, b, c, ab, bc, ca):
    """Write triangle slot ``e // 3`` with corners a, b, c and the half-edges opposite its
    edges ab, bc, ca (linking them back), and mark it pending (scanned at the next flush)."""
    tri[e], tri[e + 1], tri[e + 2] = a, b, c
    half[e], half[e + 1], half[e + 2] = ab, bc, ca
    if ab >= 0:
        half[ab] = e
    if bc >= 0:
        half[bc] = e + 1
    if ca >= 0:
        half[ca] = e + 2
    t = e // 3
    p = cnt[NPEND]
    pending[p] = t
    qi[t] = -2 - p
    cnt[NPEND] = p + 1
    return e


# ------------------------------------------------------------------------ the scan

@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _start(w, a, ra):
    """A column offset at or before the first at which edge function ``w`` (step ``a``
    a column, ``ra`` = 1 / a) is ≥ 0: by a multiplication, not a division per row (one
    sample early at most, which the inside test then skips)."""
    if w < 0 and a > 0:
        return max(int(-w * ra) - 1, 0)
    return 0


@njit(cache=True, nogil=True, error_model="numpy")
def _scan(t, tri, z, valid, W, voids, cand, err):
    """Triangle ``t``'s largest error over the samples it covers, and that sample
    (hmm's rasterisation: incremental integer edge functions, exact on the grid)."""
    a, b, c = np.int64(tri[3 * t]), np.int64(tri[3 * t + 1]), np.int64(tri[3 * t + 2])
    p0y, p0x = divmod(a, W)
    p1y, p1x = divmod(b, W)
    p2y, p2x = divmod(c, W)
    minx, miny = min(p0x, p1x, p2x), min(p0y, p1y, p2y)
    maxx, maxy = max(p0x, p1x, p2x), max(p0y, p1y, p2y)
    w00 = _orient(p1x, p1y, p2x, p2y, minx, miny)
    w01 = _orient(p2x, p2y, p0x, p0y, minx, miny)
    w02 = _orient(p0x, p0y, p1x, p1y, minx, miny)
    a01, b01 = p1y - p0y, p0x - p1x
    a12, b12 = p2y - p1y, p1x - p2x
    a20, b20 = p0y - p2y, p2x - p0x
    area = float(_orient(p0x, p0y, p1x, p1y, p2x, p2y))
    r12 = 1.0 / a12 if a12 > 0 else 0.0
    r20 = 1.0 / a20 if a20 > 0 else 0.0
    r01 = 1.0 / a01 if a01 > 0 else 0.0
    if voids and not (valid[a] and valid[b] and valid[c]):
        arg = _scan_cut(a, b, c, valid, W, minx, miny, maxx, maxy, (w00, w01, w02),
                        (a01, b01, a12, b12, a20, b20), (r01, r12, r20))
        err[t] = np.inf if arg >= 0 else 0.0
        cand[t] = arg if arg >= 0 else a
        return
    z0, z1, z2 = z[a] / area, z[b] / area, z[c] / area
    best = 0.0
    arg = a
    for y in range(miny, maxy + 1):
        dx = max(_start(w00, a12, r12), _start(w01, a20, r20), _start(w02, a01, r01))
        w0 = w00 + a12 * dx
        w1 = w01 + a20 * dx
        w2 = w02 + a01 * dx
        inside = False
        row = y * W
        for x in range(minx + dx, maxx + 1):
            if w0 >= 0 and w1 >= 0 and w2 >= 0:
                inside = True
                s = row + x
                if voids and not valid[s]:  # a drawn triangle must not span a void
                    err[t] = np.inf
                    cand[t] = s
                    return
                d = abs(z0 * w0 + z1 * w1 + z2 * w2 - z[s])
                if d > best:
                    best = d
                    arg = s
            elif inside:
                break
            w0 += a12
            w1 += a20
            w2 += a01
        w00 += b12
        w01 += b20
        w02 += b01
    if arg == a or arg == b or arg == c:
        best = 0.0
    cand[t] = arg
    err[t] = best


@njit(cache=True, nogil=True, error_model="numpy")
def _scan_cut(a, b, c, valid, W, minx, miny, maxx, maxy, w, ab, r):
    """A triangle with an invalid corner (never drawn): a valid sample it covers other
    than its corners, or −1."""
    w00, w01, w02 = w
    a01, b01, a12, b12, a20, b20 = ab
    r01, r12, r20 = r
    for y in range(miny, maxy + 1):
        dx = max(_start(w00, a12, r12), _start(w01, a20, r20), _start(w02, a01, r01))
        w0 = w00 + a12 * dx
        w1 = w01 + a20 * dx
        w2 = w02 + a01 * dx
        inside = False
        for x in range(minx + dx, maxx + 1):
            if w0 >= 0 and w1 >= 0 and w2 >= 0:
                inside = True
                s = y * W + x
                if valid[s] and s != a and s != b and s != c:
                    return s
            elif inside:
                break
            w0 += a12
            w1 += a20
            w2 += a01
        w00 += b12
        w01 += b20
        w02 += b01
    return -1


@njit(cache=True, nogil=True, error_model="numpy")
def _flush(tri, z, valid, W, voids, cand, err, heap, qi, pending, cnt, max_error):
    """Scan every pending triangle and push it on the heap if its error exceeds
    ``max_error`` (one that does not is never split: the heap holds only the triangles
    still to refine, a fraction of the mesh, which keeps its operations in cache)."""
    for k in range(cnt[NPEND]):
        t = pending[k]
        _scan(t, tri, z, valid, W, voids, cand, err)
        if not err[t] > max_error:
            qi[t] = -1
            continue
        n = cnt[NH]
        heap[n] = t
        qi[t] = n
        cnt[NH] = n + 1
        _heap_up(heap, qi, err, n)
    cnt[NPEND] = 0


# ------------------------------------------------------------------- insertion

@njit(cache=True, nogil=True, error_model="numpy")
def _legalize(a0, tri, half, W, heap, qi, err, pending, cnt, stack):
    """Lawson flips from half-edge ``a0`` until every edge is locally Delaunay."""
    stack[0] = a0
    top = 1
    while top > 0:
        top -= 1
        a = stack[top]
        b = half[a]
        if b < 0:
            continue
        ta, tb = a - a % 3, b - b % 3
        al, ar = ta + (a + 1) % 3, ta + (a + 2) % 3
        bl, br = tb + (b + 2) % 3, tb + (b + 1) % 3
        p0, pr, pl, p1 = tri[ar], tri[a], tri[al], tri[bl]
        if not _in_circle(float(p0 % W), float(p0 // W), float(pr % W), float(pr // W),
                          float(pl % W), float(pl // W), float(p1 % W), float(p1 // W)):
            continue
        hal, har, hbl, hbr = half[al], half[ar], half[bl], half[br]
        _forget(ta // 3, heap, qi, err, pending, cnt)
        _forget(tb // 3, heap, qi, err, pending, cnt)
        t0 = _set_triangle(tri, half, qi, pending, cnt, ta, p0, p1, pl, -1, hbl, hal)
        t1 = _set_triangle(tri, half, qi, pending, cnt, tb, p1, p0, pr, t0, har, hbr)
        if top + 2 > len(stack):
            return -1  # the caller grows the stack and calls again (never seen)
        stack[top] = t1 + 2  # the recursion's order: t0 + 1 first, then t1 + 2
        stack[top + 1] = t0 + 1
        top += 2
    return 0


@njit(cache=True, nogil=True, error_model="numpy")
def _insert(t, tri, half, W, cand, heap, qi, err, pending, cnt, stack):
    """Split triangle ``t`` at its candidate sample (on an edge: split the edge's two
    triangles), then restore the Delaunay property."""
    e0, e1, e2 = 3 * t, 3 * t + 1, 3 * t + 2
    p0, p1, p2 = tri[e0], tri[e1], tri[e2]
    pn = cand[t]
    cnt[NP] += 1
    px, py = float(pn % W), float(pn // W)
    ax, ay = float(p0 % W), float(p0 // W)
    bx, by = float(p1 % W), float(p1 // W)
    cx, cy = float(p2 % W), float(p2 // W)
    if _orient(ax, ay, bx, by, px, py) == 0:
        edge = e0
    elif _orient(bx, by, cx, cy, px, py) == 0:
        edge = e1
    elif _orient(cx, cy, ax, ay, px, py) == 0:
        edge = e2
    else:
        edge = -1
    nt = cnt[NT]
    if edge < 0:
        h0, h1, h2 = half[e0], half[e1], half[e2]
        t0 = _set_triangle(tri, half, qi, pending, cnt, e0, p0, p1, pn, h0, -1, -1)
        t1 = _set_triangle(tri, half, qi, pending, cnt, 3 * nt, p1, p2, pn, h1, -1, t0 + 1)
        t2 = _set_triangle(tri, half, qi, pending, cnt, 3 * nt + 3, p2, p0, pn, h2, t0 + 2, t1 + 1)
        cnt[NT] = nt + 2
        for s in (t0, t1, t2):
            if _legalize(s, tri, half, W, heap, qi, err, pending, cnt, stack) < 0:
                return -1
        return 0
    # the candidate lies on edge ``edge`` (hmm's handleCollinear)
    a = edge
    ta = a - a % 3
    al, ar = ta + (a + 1) % 3, ta + (a + 2) % 3
    q0, qr, ql = tri[ar], tri[a], tri[al]
    hal, har = half[al], half[ar]
    b = half[a]
    if b < 0:
        t0 = _set_triangle(tri, half, qi, pending, cnt, ta, pn, q0, qr, -1, har, -1)
        t1 = _set_triangle(tri, half, qi, pending, cnt, 3 * nt, q0, pn, ql, t0, -1, hal)
        cnt[NT] = nt + 1
        for s in (t0 + 1, t1 + 2):
            if _legalize(s, tri, half, W, heap, qi, err, pending, cnt, stack) < 0:
                return -1
        return 0
    tb = b - b % 3
    bl, br = tb + (b + 2) % 3, tb + (b + 1) % 3
    q1 = tri[bl]
    hbl, hbr = half[bl], half[br]
    _forget(tb // 3, heap, qi, err, pending, cnt)
    t0 = _set_triangle(tri, half, qi, pending, cnt, ta, q0, qr, pn, har, -1, -1)
    t1 = _set_triangle(tri, half, qi, pending, cnt, tb, qr, q1, pn, hbr, -1, t0 + 1)
    t2 = _set_triangle(tri, half, qi, pending, cnt, 3 * nt, q1, ql, pn, hbl, -1, t1 + 1)
    t3 = _set_triangle(tri, half, qi, pending, cnt, 3 * nt + 3, ql, q0, pn, hal, t0 + 2, t2 + 1)
    cnt[NT] = nt + 2
    for s in (t0, t1, t2, t3):
        if _legalize(s, tri, half, W, heap, qi, err, pending, cnt, stack) < 0:
            return -1
    return 0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _drawn(tri, t, valid):
    return valid[tri[3 * t]] and valid[tri[3 * t + 1]] and valid[tri[3 * t + 2]]


@njit(cache=True, nogil=True, error_model="numpy")
def _flip_to_cover(tri, half, nt, z, valid, W, max_error):
    """Along voids: flip an edge where the other diagonal of its quad draws more
    triangles (say a cell with one invalid corner cut through that corner), if the new
    pair is convex and within ``max_error`` (scanned again) and spans no void. Returns
    the number of flips."""
    cand = np.empty(nt, np.int32)
    err = np.empty(nt, np.float64)
    flips = 0
    for _ in range(16):  # passes, until none flips
        changed = 0
        for a in range(3 * nt):
            b = half[a]
            if b < a:  # each edge once, and not the border
                continue
            ta, tb = a // 3, b // 3
            if _drawn(tri, ta, valid) and _drawn(tri, tb, valid):
                continue
            a0, b0 = 3 * ta, 3 * tb
            al, ar = a0 + (a + 1) % 3, a0 + (a + 2) % 3
            bl, br = b0 + (b + 2) % 3, b0 + (b + 1) % 3
            p0, pr, pl, p1 = tri[ar], tri[a], tri[al], tri[bl]
            if (_orient(p0 % W, p0 // W, p1 % W, p1 // W, pl % W, pl // W) <= 0
                    or _orient(p1 % W, p1 // W, p0 % W, p0 // W, pr % W, pr // W) <= 0):
                continue
            before = int(_drawn(tri, ta, valid)) + int(_drawn(tri, tb, valid))
            old = (tri[a0], tri[a0 + 1], tri[a0 + 2], tri[b0], tri[b0 + 1], tri[b0 + 2])
            tri[a0], tri[a0 + 1], tri[a0 + 2] = p0, p1, pl
            tri[b0], tri[b0 + 1], tri[b0 + 2] = p1, p0, pr
            after = int(_drawn(tri, ta, valid)) + int(_drawn(tri, tb, valid))
            ok = after > before
            if ok:
                _scan(ta, tri, z, valid, W, True, cand, err)
                _scan(tb, tri, z, valid, W, True, cand, err)
                ok = err[ta] <= max_error and err[tb] <= max_error
            if not ok:
                tri[a0], tri[a0 + 1], tri[a0 + 2] = old[0], old[1], old[2]
                tri[b0], tri[b0 + 1], tri[b0 + 2] = old[3], old[4], old[5]
                continue
            hal, har, hbl, hbr = half[al], half[ar], half[bl], half[br]
            # the new edges in the slots' order, as _legalize links them
            half[a0], half[a0 + 1], half[a0 + 2] = b0, hbl, hal
            half[b0], half[b0 + 1], half[b0 + 2] = a0, har, hbr
            for e, h in ((a0 + 1, hbl), (a0 + 2, hal), (b0 + 1, har), (b0 + 2, hbr)):
                if h >= 0:
                    half[h] = e
            changed += 1
        flips += changed
        if changed == 0:
            break
    return flips


@njit(cache=True, nogil=True, error_model="numpy")
def _grow(a, n):
    out = np.empty(n, a.dtype)
    out[:len(a)] = a
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def greedy_tin(z, valid, H, W, max_error, voids):
    """The greedy TIN of the H × W heights ``z`` (flat, scene units; ``valid`` flat):
    insert the worst sample of the worst triangle until every triangle's error over the
    samples it covers is ≤ ``max_error``. Returns (triangles (F, 3) of flat sample ids,
    the number of points)."""
    cap = 1024
    tri = np.empty(3 * cap, np.int32)  # 32-bit: half the cache lines of 64
    half = np.empty(3 * cap, np.int32)
    cand = np.empty(cap, np.int32)
    err = np.empty(cap, np.float64)
    heap = np.empty(cap, np.int32)
    qi = np.empty(cap, np.int32)
    pending = np.empty(cap, np.int32)
    stack = np.empty(1 << 16, np.int64)
    cnt = np.zeros(4, np.int64)
    p0, p1, p2, p3 = 0, W - 1, (H - 1) * W, H * W - 1
    cnt[NP] = 4
    t0 = _set_triangle(tri, half, qi, pending, cnt, 0, p3, p0, p2, -1, -1, -1)
    _set_triangle(tri, half, qi, pending, cnt, 3, p0, p3, p1, t0, -1, -1)
    cnt[NT] = 2
    _flush(tri, z, valid, W, voids, cand, err, heap, qi, pending, cnt, max_error)
    while cnt[NH] > 0 and err[heap[0]] > max_error:
        if cnt[NT] + 2 > cap:
            cap *= 2
            tri, half = _grow(tri, 3 * cap), _grow(half, 3 * cap)
            cand, err, heap = _grow(cand, cap), _grow(err, cap), _grow(heap, cap)
            qi, pending = _grow(qi, cap), _grow(pending, cap)
        t = heap[0]
        _forget(t, heap, qi, err, pending, cnt)
        if _insert(t, tri, half, W, cand, heap, qi, err, pending, cnt, stack) < 0:
            raise RuntimeError("Delaunay flips deeper than the stack")
        _flush(tri, z, valid, W, voids, cand, err, heap, qi, pending, cnt, max_error)
    nt = cnt[NT]
    if voids:
        _flip_to_cover(tri, half, nt, z, valid, W, max_error)
    return tri[:3 * nt].reshape(nt, 3).copy(), cnt[NP]

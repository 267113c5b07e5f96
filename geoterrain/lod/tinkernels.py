"""Compiled kernels of the greedy-insertion TIN (Garland & Heckbert's refinement on a
Delaunay triangulation, the algorithm of Fogleman's hmm and Mapbox's Delatin).

The triangulation starts from the two triangles of the data rectangle and inserts, one
at a time, the sample of largest error of the triangle of largest error; each new
triangle's error is found by scanning every grid sample it covers (closed: edges and
corners included), so the bound is exact over the samples, not estimated.

A triangle t is one row of 8 int32 in ``F``: its corners (``F[8t + k]``, k = 0, 1, 2),
the half-edges opposite its edges k → k+1 (``F[8t + 3 + k]``, −1 on the rectangle's
border), its candidate sample (``F[8t + 6]``) and where it is queued (``F[8t + 7]``: a
heap position ≥ 0, −1 nowhere, −2 − p at ``pending[p]``). A half-edge is ``8t + k``, so
``F[e]`` is its origin and ``F[e + 3]`` its twin: one row, one or two cache lines, holds
all a flip reads of a triangle. The max-heap holds triangle ids with their errors beside
them (``key``), and only the triangles whose error exceeds the bound: the others are
never split, and most of the mesh is among them.

Nodata: a triangle whose corners are all valid and which covers an invalid sample, or a
triangle with an invalid corner that covers a valid sample other than its corners, has
error +∞ and inserts that sample; so a drawn triangle (three valid corners) never spans
a void, and voids are refined to their border, as rtin's mixed diamonds (δ = ∞) are.

Vertices are flat sample ids ``i·W + j`` (row i, column j); x = j, y = i below.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir as llir
from numba import njit
from numba.core import cgutils, types
from numba.extending import intrinsic

# cnt slots: points, triangles, heap length, pending length
NP, NT, NH, NPEND = 0, 1, 2, 3
CAND, QI = 6, 7  # a triangle row's candidate sample and queue position
ROW = 8
DEAD = -9  # the queue slot of a triangle a collapse removed
MAXDEG = 64  # vertices of higher degree are kept
TRIES = 2  # collapses scanned per point, the best at the point first


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


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _next(e):
    """The next half-edge of e's triangle (k → k + 1 mod 3)."""
    k = e & 7
    return e - k + (k + 1 if k < 2 else 0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _prev(e):
    k = e & 7
    return e - k + (k - 1 if k > 0 else 2)


# ------------------------------------------------------------------ the priority queue

@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _heap_up(F, heap, key, k):
    t, v = heap[k], key[k]
    while k > 0:
        p = (k - 1) >> 1
        if key[p] >= v:
            break
        heap[k], key[k] = heap[p], key[p]
        F[ROW * heap[k] + QI] = k
        k = p
    heap[k], key[k] = t, v
    F[ROW * t + QI] = k


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _heap_down(F, heap, key, k, n):
    t, v = heap[k], key[k]
    while True:
        c = 2 * k + 1
        if c >= n:
            break
        if c + 1 < n and key[c + 1] > key[c]:
            c += 1
        if key[c] <= v:
            break
        heap[k], key[k] = heap[c], key[c]
        F[ROW * heap[k] + QI] = k
        k = c
    heap[k], key[k] = t, v
    F[ROW * t + QI] = k


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _forget(t, F, heap, key, pending, cnt):
    """Take triangle ``t`` out of the heap or the pending list (its row is rewritten)."""
    k = F[ROW * t + QI]
    if k >= 0:
        n = cnt[NH] - 1
        cnt[NH] = n
        if k != n:
            moved = heap[n]
            heap[k], key[k] = moved, key[n]
            F[ROW * moved + QI] = k
            _heap_down(F, heap, key, k, n)
            _heap_up(F, heap, key, F[ROW * moved + QI])
    elif k <= -2:
        p = -2 - k
        n = cnt[NPEND] - 1
        cnt[NPEND] = n
        if p != n:
            pending[p] = pending[n]
            F[ROW * pending[p] + QI] = -2 - p
    F[ROW * t + QI] = -1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _set_triangle(F, pending, cnt, t, a, b, c, ab, bc, ca):
    """Write row ``t`` with corners a, b, c and the half-edges opposite its edges ab, bc,
    ca (linking them back), and mark it pending (scanned at the next flush)."""
    e = ROW * t
    F[e], F[e + 1], F[e + 2] = a, b, c
    F[e + 3], F[e + 4], F[e + 5] = ab, bc, ca
    if ab >= 0:
        F[ab + 3] = e
    if bc >= 0:
        F[bc + 3] = e + 1
    if ca >= 0:
        F[ca + 3] = e + 2
    p = cnt[NPEND]
    pending[p] = t
    F[e + QI] = -2 - p
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
def _scan(a, b, c, z, valid, W, voids):
    """The largest error of triangle (a, b, c) over the samples it covers, and that
    sample (hmm's rasterisation: incremental integer edge functions, exact on the
    grid). +inf where it must be refined for a void (see the module's docstring)."""
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
    r12 = 1.0 / a12 if a12 > 0 else 0.0
    r20 = 1.0 / a20 if a20 > 0 else 0.0
    r01 = 1.0 / a01 if a01 > 0 else 0.0
    cut = voids and not (valid[a] and valid[b] and valid[c])
    area = float(_orient(p0x, p0y, p1x, p1y, p2x, p2y))
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
                if voids:
                    if cut:  # never drawn: it must hold no valid sample but its corners
                        if valid[s] and s != a and s != b and s != c:
                            return np.inf, s
                    elif not valid[s]:  # a drawn triangle must not span a void
                        return np.inf, s
                if not cut:
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
    return best, arg


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _span(w, a, r, lo, hi):
    """Narrow the columns [lo, hi] (offsets) of a row to those where the edge function
    ``w + a·dx`` is ≥ 0 (``r`` = 1 / a): exact, as w and a are integers held in floats
    (< 2⁵³) and the estimate from the reciprocal is corrected by the integer test."""
    if a > 0:  # the edge bounds the row on the left
        q = np.ceil(-w * r)
        if w + a * (q - 1) >= 0:
            q -= 1
        elif w + a * q < 0:
            q += 1
        return max(lo, q), hi
    if a < 0:  # on the right
        q = np.floor(-w * r)
        if w + a * (q + 1) >= 0:
            q += 1
        elif w + a * q < 0:
            q -= 1
        return lo, min(hi, q)
    return (lo, hi) if w >= 0 else (1.0, 0.0)


@intrinsic
def _maxnum(typingctx, a, b):
    """LLVM's maxnum: a maximum the loop vectorizer turns into vector maxima (numba's
    ``max`` and a compare-and-select stay scalar). Flagged no-NaN: the heights of a grid
    without voids are finite."""
    def codegen(context, builder, signature, args):
        d = llir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, llir.FunctionType(d, [d, d]),
                                            "llvm.maxnum.f64")
        return builder.call(fn, args, fastmath=("nnan", "nsz"))
    return types.float64(types.float64, types.float64), codegen


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _row_max(zr, n, z0, z1, z2, w0, w1, w2, a0, a1, a2):
    m = 0.0
    for k in range(n):
        f = float(k)
        m = _maxnum(m, abs(z0 * (w0 + a0 * f) + z1 * (w1 + a1 * f) + z2 * (w2 + a2 * f) - zr[k]))
    return m


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _row_arg(zr, n, z0, z1, z2, w0, w1, w2, a0, a1, a2, m):
    for k in range(n):
        f = float(k)
        if abs(z0 * (w0 + a0 * f) + z1 * (w1 + a1 * f) + z2 * (w2 + a2 * f) - zr[k]) == m:
            return k
    return 0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _scan_plain(a, b, c, z, W, limit, stop):
    """:func:`_scan` on a grid without voids: each row's covered columns found from the
    three edges first, then each row's largest error alone (a loop of vector maxima);
    the sample is looked for in the first row that holds the largest, only if it exceeds
    ``limit``. With ``stop``, returns as soon as a row exceeds it (the sample is then
    not sought)."""
    p0y, p0x = divmod(a, W)
    p1y, p1x = divmod(b, W)
    p2y, p2x = divmod(c, W)
    minx, miny = min(p0x, p1x, p2x), min(p0y, p1y, p2y)
    maxx, maxy = max(p0x, p1x, p2x), max(p0y, p1y, p2y)
    w00 = float(_orient(p1x, p1y, p2x, p2y, minx, miny))
    w01 = float(_orient(p2x, p2y, p0x, p0y, minx, miny))
    w02 = float(_orient(p0x, p0y, p1x, p1y, minx, miny))
    a01, b01 = float(p1y - p0y), float(p0x - p1x)
    a12, b12 = float(p2y - p1y), float(p1x - p2x)
    a20, b20 = float(p0y - p2y), float(p2x - p0x)
    r01 = 1.0 / a01 if a01 != 0 else 0.0
    r12 = 1.0 / a12 if a12 != 0 else 0.0
    r20 = 1.0 / a20 if a20 != 0 else 0.0
    area = float(_orient(p0x, p0y, p1x, p1y, p2x, p2y))
    z0, z1, z2 = z[a] / area, z[b] / area, z[c] / area
    best = 0.0
    bs, bn, bw0, bw1, bw2 = a, 0, 0.0, 0.0, 0.0
    width = float(maxx - minx)
    for y in range(miny, maxy + 1):
        lo, hi = _span(w00, a12, r12, 0.0, width)
        lo, hi = _span(w01, a20, r20, lo, hi)
        lo, hi = _span(w02, a01, r01, lo, hi)
        if lo <= hi:
            w0 = w00 + a12 * lo
            w1 = w01 + a20 * lo
            w2 = w02 + a01 * lo
            s = y * W + minx + int(lo)
            n = int(hi - lo) + 1
            m = _row_max(z[s:s + n], n, z0, z1, z2, w0, w1, w2, a12, a20, a01)
            if m > best:
                best = m
                if stop and m > limit:  # the caller only asks whether it is within limit
                    return m, s
                bs, bn, bw0, bw1, bw2 = s, n, w0, w1, w2
        w00 += b12
        w01 += b20
        w02 += b01
    if not best > limit:
        return best, a
    arg = bs + _row_arg(z[bs:bs + bn], bn, z0, z1, z2, bw0, bw1, bw2, a12, a20, a01, best)
    if arg == a or arg == b or arg == c:
        best = 0.0
    return best, arg


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _flush(F, z, valid, W, voids, heap, key, pending, cnt, max_error):
    """Scan every pending triangle; push it on the heap if its error exceeds
    ``max_error``."""
    for k in range(cnt[NPEND]):
        t = pending[k]
        r = ROW * t
        if voids:
            err, arg = _scan(np.int64(F[r]), np.int64(F[r + 1]), np.int64(F[r + 2]), z, valid,
                             W, True)
        else:
            err, arg = _scan_plain(np.int64(F[r]), np.int64(F[r + 1]), np.int64(F[r + 2]), z, W,
                                   max_error, False)
        F[r + CAND] = arg
        if not err > max_error:
            F[r + QI] = -1
            continue
        n = cnt[NH]
        heap[n], key[n] = t, err
        cnt[NH] = n + 1
        _heap_up(F, heap, key, n)
    cnt[NPEND] = 0


# ------------------------------------------------------------------- insertion

@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _legalize(a0, F, W, heap, key, pending, cnt, stack):
    """Lawson flips from half-edge ``a0`` until every edge is locally Delaunay (in the
    order of Delatin's recursion). Returns −1 if ``stack`` is too short."""
    stack[0] = a0
    top = 1
    while top > 0:
        top -= 1
        a = stack[top]
        b = F[a + 3]
        if b < 0:
            continue
        al, ar = _next(a), _prev(a)
        bl, br = _prev(b), _next(b)
        p0, pr, pl, p1 = F[ar], F[a], F[al], F[bl]
        if not _in_circle(float(p0 % W), float(p0 // W), float(pr % W), float(pr // W),
                          float(pl % W), float(pl // W), float(p1 % W), float(p1 // W)):
            continue
        hal, har, hbl, hbr = F[al + 3], F[ar + 3], F[bl + 3], F[br + 3]
        ta, tb = a >> 3, b >> 3
        _forget(ta, F, heap, key, pending, cnt)
        _forget(tb, F, heap, key, pending, cnt)
        t0 = _set_triangle(F, pending, cnt, ta, p0, p1, pl, -1, hbl, hal)
        t1 = _set_triangle(F, pending, cnt, tb, p1, p0, pr, t0, har, hbr)
        if top + 2 > len(stack):
            return -1
        stack[top] = t1 + 2  # the recursion's order: t0 + 1 first, then t1 + 2
        stack[top + 1] = t0 + 1
        top += 2
    return 0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _legalize_all(F, W, heap, key, pending, cnt, stack, s0, s1, s2, s3):
    """:func:`_legalize` from each of the half-edges s0 … s3 (−1: none) in turn: one
    call site (it is inlined, with the heap's sifts, wherever it is called)."""
    for j in range(4):
        s = s0 if j == 0 else (s1 if j == 1 else (s2 if j == 2 else s3))
        if s < 0:
            break
        if _legalize(s, F, W, heap, key, pending, cnt, stack) < 0:
            return -1
    return 0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _insert(t, F, W, heap, key, pending, cnt, stack, pts):
    """Split triangle ``t`` at its candidate sample (on an edge: split the edge's two
    triangles), then restore the Delaunay property."""
    e0 = ROW * t
    e1, e2 = e0 + 1, e0 + 2
    p0, p1, p2 = F[e0], F[e1], F[e2]
    pn = F[e0 + CAND]
    pts[cnt[NP]] = pn
    cnt[NP] += 1
    px, py = pn % W, pn // W
    ax, ay = p0 % W, p0 // W
    bx, by = p1 % W, p1 // W
    cx, cy = p2 % W, p2 // W
    if _orient(ax, ay, bx, by, px, py) == 0:
        edge = e0
    elif _orient(bx, by, cx, cy, px, py) == 0:
        edge = e1
    elif _orient(cx, cy, ax, ay, px, py) == 0:
        edge = e2
    else:
        edge = -1
    nt = cnt[NT]
    s3 = -1
    if edge < 0:
        h0, h1, h2 = F[e0 + 3], F[e1 + 3], F[e2 + 3]
        t0 = _set_triangle(F, pending, cnt, t, p0, p1, pn, h0, -1, -1)
        t1 = _set_triangle(F, pending, cnt, nt, p1, p2, pn, h1, -1, t0 + 1)
        t2 = _set_triangle(F, pending, cnt, nt + 1, p2, p0, pn, h2, t0 + 2, t1 + 1)
        cnt[NT] = nt + 2
        s0, s1, s2 = t0, t1, t2
    else:  # the candidate lies on edge ``edge`` (hmm's handleCollinear)
        a = edge
        al, ar = _next(a), _prev(a)
        q0, qr, ql = F[ar], F[a], F[al]
        hal, har = F[al + 3], F[ar + 3]
        b = F[a + 3]
        if b < 0:
            t0 = _set_triangle(F, pending, cnt, t, pn, q0, qr, -1, har, -1)
            t1 = _set_triangle(F, pending, cnt, nt, q0, pn, ql, t0, -1, hal)
            cnt[NT] = nt + 1
            s0, s1, s2 = t0 + 1, t1 + 2, -1
        else:
            bl, br = _prev(b), _next(b)
            q1 = F[bl]
            hbl, hbr = F[bl + 3], F[br + 3]
            tb = b >> 3
            _forget(tb, F, heap, key, pending, cnt)
            t0 = _set_triangle(F, pending, cnt, t, q0, qr, pn, har, -1, -1)
            t1 = _set_triangle(F, pending, cnt, tb, qr, q1, pn, hbr, -1, t0 + 1)
            t2 = _set_triangle(F, pending, cnt, nt, q1, ql, pn, hbl, -1, t1 + 1)
            t3 = _set_triangle(F, pending, cnt, nt + 1, ql, q0, pn, hal, t0 + 2, t2 + 1)
            cnt[NT] = nt + 2
            s0, s1, s2, s3 = t0, t1, t2, t3
    return _legalize_all(F, W, heap, key, pending, cnt, stack, s0, s1, s2, s3)


@njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
def _refine(z, valid, W, voids, max_error, F, heap, key, pending, stack, pts, cnt):
    """The refinement: scan the pending triangles, then split the worst, until none
    exceeds ``max_error``. Returns 0 when done, 1 when the arrays must grow first (the
    caller grows them and calls again), −1 if the flips overflow ``stack``.

    Compiled without numba's reference counting (``_nrt=False``): it makes no array, and
    the helpers inlined here (each a few times) otherwise counted every array they take
    in and out, an atomic add each. ``_flush`` and ``_legalize`` are each inlined once
    (one call site each) to keep the compilation short."""
    cap = len(heap)
    while True:
        _flush(F, z, valid, W, voids, heap, key, pending, cnt, max_error)
        if not (cnt[NH] > 0 and key[0] > max_error):
            return 0
        if cnt[NT] + 2 > cap:
            return 1
        t = heap[0]
        _forget(t, F, heap, key, pending, cnt)
        if _insert(t, F, W, heap, key, pending, cnt, stack, pts) < 0:
            return -1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _drawn(F, t, valid):
    r = ROW * t
    return valid[F[r]] and valid[F[r + 1]] and valid[F[r + 2]]


@njit(cache=True, nogil=True, error_model="numpy")
def _flip_to_cover(F, nt, z, valid, W, max_error):
    """Along voids: flip an edge where the other diagonal of its quad draws more
    triangles (say a cell with one invalid corner cut through that corner), if the new
    pair is convex, within ``max_error`` (scanned again) and spans no void. Returns the
    number of flips."""
    flips = 0
    for _ in range(16):  # passes, until none flips
        changed = 0
        for t in range(nt):
            if F[ROW * t + QI] == DEAD:  # removed by the collapse pass: its twins are stale
                continue
            for k in range(3):
                a = ROW * t + k
                b = F[a + 3]
                if b < a:  # each edge once, and not the border
                    continue
                ta, tb = a >> 3, b >> 3
                before = int(_drawn(F, ta, valid)) + int(_drawn(F, tb, valid))
                if before == 2:
                    continue
                al, ar = _next(a), _prev(a)
                bl, br = _prev(b), _next(b)
                p0, pr, pl, p1 = F[ar], F[a], F[al], F[bl]
                if (_orient(p0 % W, p0 // W, p1 % W, p1 // W, pl % W, pl // W) <= 0
                        or _orient(p1 % W, p1 // W, p0 % W, p0 // W, pr % W, pr // W) <= 0):
                    continue
                after = (int(valid[p0] and valid[p1] and valid[pl])
                         + int(valid[p1] and valid[p0] and valid[pr]))
                if after <= before:
                    continue
                ea, _ = _scan(np.int64(p0), np.int64(p1), np.int64(pl), z, valid, W, True)
                eb, _ = _scan(np.int64(p1), np.int64(p0), np.int64(pr), z, valid, W, True)
                if ea > max_error or eb > max_error:
                    continue
                hal, har, hbl, hbr = F[al + 3], F[ar + 3], F[bl + 3], F[br + 3]
                a0, b0 = ROW * ta, ROW * tb
                F[a0], F[a0 + 1], F[a0 + 2] = p0, p1, pl
                F[b0], F[b0 + 1], F[b0 + 2] = p1, p0, pr
                F[a0 + 3], F[a0 + 4], F[a0 + 5] = b0, hbl, hal
                F[b0 + 3], F[b0 + 4], F[b0 + 5] = a0, har, hbr
                for e, h in ((a0 + 1, hbl), (a0 + 2, hal), (b0 + 1, har), (b0 + 2, hbr)):
                    if h >= 0:
                        F[h + 3] = e
                changed += 1
        flips += changed
        if changed == 0:
            break
    return flips


@njit(cache=True, nogil=True, error_model="numpy")
def _compact(F, nt, pts, valid, voids, W):
    """The drawn triangles (three valid corners) as (F, 3) int64 indices into the points
    they use, counter-clockwise seen from above (x = column, y = −row) as the kernels
    keep them (``_orient`` > 0), and those points' (row, column)."""
    where = np.empty(valid.size, np.int32)  # sample → point: only the points' entries set
    for k in range(len(pts)):
        where[pts[k]] = k
    used = np.zeros(len(pts), np.int32)  # 0: unused, else its new number + 1
    keep = np.zeros(nt, np.bool_)
    nf = 0
    for t in range(nt):
        r = ROW * t
        if F[r + QI] == DEAD or (voids and not (valid[F[r]] and valid[F[r + 1]]
                                                 and valid[F[r + 2]])):
            continue
        keep[t] = True
        nf += 1
    nv = 0
    faces = np.empty((nf, 3), np.int64)
    f = 0
    for t in range(nt):
        if not keep[t]:
            continue
        r = ROW * t
        for m in range(3):
            k = where[F[r + m]]
            if used[k] == 0:
                nv += 1
                used[k] = nv
            faces[f, m] = used[k] - 1
        f += 1
    ij = np.empty((nv, 2), np.int64)
    for k in range(len(pts)):
        if used[k]:
            ij[used[k] - 1, 0] = pts[k] // W
            ij[used[k] - 1, 1] = pts[k] % W
    return faces, ij

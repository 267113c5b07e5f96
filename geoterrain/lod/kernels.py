"""Compiled bintree extraction (numba): one resumable stack-based walk, vertices numbered in order.

Benchmarked against the level-by-level numpy bisection it replaced; today's figures come
from ``benchmarks/bench_lod.py`` (docs/benchmarks.md; history in docs/lab/lod-flight.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.core.bintree import parents_nb


class ActiveFlags(NamedTuple):
    """The dense per-sample flags a selection fills and walks: ``active`` and ``mixed``
    (N, N), bools or generation stamps where ``== gen`` means set, and ``boxes``
    (levels, 4): rows i0, i1 and columns j0, j1 of the active vertices per pyramid level
    (what the closure scans)."""

    active: np.ndarray
    mixed: np.ndarray
    gen: bool | int
    boxes: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def sample_xy(X, Y, aff, s, a, b, i, j):
    """Scene x, y of sample (i, j), sample (a, b) of pool slot ``s``: from the slabs
    ``X``, ``Y``, or for an affine frame (``aff`` = a, b, c, d, e, f of the geotransform,
    the origin x, y and the unit in metres, then 1; all 0 for a curvilinear frame) by
    ``Frame.xy``'s formula, in its order."""
    if aff[9] == 0.0:
        return X[s, a, b], Y[s, a, b]
    jj, ii = j + 0.5, i + 0.5
    x = aff[0] * jj + aff[1] * ii + aff[2]
    y = aff[3] * jj + aff[4] * ii + aff[5]
    return (x - aff[6]) * aff[8], (y - aff[7]) * aff[8]


def walk_start(N: int, roots: tuple[int, int] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """The stack and state (stack pointer) of a walk over an N × N grid: the two
    base triangles, both counter-clockwise; with ``roots`` (across, down), over a root
    grid of roots of side N − 1: two triangles per root
    (:func:`geoterrain.core.bintree.root_triangles`).

    Examples
    --------
    >>> stack, state = walk_start(5, (2, 1))
    >>> int(state[0]), stack[:4].tolist()
    (4, [[0, 0, 4, 4, 0, 4], [4, 4, 0, 0, 4, 0], [4, 4, 0, 8, 0, 4], [0, 8, 4, 4, 4, 8]])
    """
    s = N - 1
    if roots is None or tuple(roots) == (1, 1):
        stack = np.empty((256, 6), np.int64)
        stack[0] = (0, 0, s, s, 0, s)
        stack[1] = (s, s, 0, 0, s, 0)
        return stack, np.array([2], np.int64)
    from geoterrain.core.bintree import root_triangles

    a, b, c = root_triangles(int(s).bit_length() - 1, roots)
    stack = np.empty((256 + len(a), 6), np.int64)
    stack[:len(a)] = np.concatenate([a, b, c], axis=1)
    return stack, np.array([len(a)], np.int64)


@njit(cache=True, nogil=True)
def walk_leaves(active, mixed, gen, stack, state, out):
    """Resumable depth-first longest-edge bisection (seed 002): up to ``len(out)`` leaf
    triangles as flat sample indices (i·N + j); returns how many, 0 once done.

    A triangle (a, b, c) splits at m = (a + b) / 2 when ``active[m] == gen``; leaves
    over a mixed diamond (``mixed[m] == gen``) are skipped. ``stack``/``state`` (from
    :func:`walk_start`) carry the walk between calls.
    """
    N = active.shape[1]  # a row's samples (a root grid's extent is wider than tall)
    sp = state[0]
    nf = 0
    cap = out.shape[0]
    while sp > 0 and nf < cap:
        sp -= 1
        ai, aj, bi, bj, ci, cj = stack[sp]
        si, sj = ai + bi, aj + bj
        if (si & 1) == 0 and (sj & 1) == 0:
            mi, mj = si >> 1, sj >> 1
            if active[mi, mj] == gen:
                # LP bisection: children (c, a, m) and (b, c, m)
                stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = ci, cj, ai, aj
                stack[sp, 4], stack[sp, 5] = mi, mj
                sp += 1
                stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = bi, bj, ci, cj
                stack[sp, 4], stack[sp, 5] = mi, mj
                sp += 1
                continue
            if mixed[mi, mj] == gen:
                continue
        out[nf, 0] = ai * N + aj
        out[nf, 1] = bi * N + bj
        out[nf, 2] = ci * N + cj
        nf += 1
    state[0] = sp
    return nf


@njit(cache=True, nogil=True)
def _walk(active, mixed, gen, stack, state, vid, tris, verts):
    """The whole walk, numbering vertices in order of first use: faces go to ``tris``
    and first-seen sample indices to ``verts``; when ``tris`` is too small the walk
    stops and returns -1 triangles (``vid`` is reset either way)."""
    cap = tris.shape[0]
    buf = np.empty((4096, 3), np.int64)  # leaves pass through a cache-sized buffer
    nf, nv = 0, 0
    while True:
        n = walk_leaves(active, mixed, gen, stack, state, buf)
        if n == 0:
            break
        if nf + n > cap:
            nf = -1
            break
        for f in range(n):
            for k in range(3):
                idx = buf[f, k]
                v = vid[idx]
                if v < 0:
                    v = nv
                    vid[idx] = nv
                    verts[nv] = idx
                    nv += 1
                tris[nf + f, k] = v
        nf += n
    for k in range(nv):
        vid[verts[k]] = -1
    return nf, nv


def extract(active: np.ndarray, mixed: np.ndarray, vid: np.ndarray, gen=True,
            capacity: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Leaf triangles of the refinement: faces (F, 3) and flat sample indices (V,).

    ``active``/``mixed`` are bool flags, or generation stamps compared with ``gen``.
    ``vid`` is a scratch (N*N,) int32 array filled with -1; it is left that way.
    ``capacity`` is a first guess of the triangle count (grown on demand).

    Examples
    --------
    >>> a = np.zeros((3, 3), bool)
    >>> f, v = extract(a, a, np.full(9, -1, np.int32))
    >>> f.shape, sorted(v.tolist())
    ((2, 3), [0, 2, 6, 8])
    """
    cap = max(int(capacity), 1024)
    while True:
        tris = np.empty((cap, 3), np.int32)
        verts = np.empty(3 * cap, np.int64)
        stack, state = walk_start(*walk_shape(active.shape))
        nf, nv = _walk(active, mixed, gen, stack, state, vid, tris, verts)
        if nf >= 0:
            return tris[:nf], verts[:nv]
        cap *= 4


def walk_shape(shape: tuple[int, int]) -> tuple[int, tuple[int, int] | None]:
    """:func:`walk_start`'s arguments for flags of ``shape``: a square N × N, or a root
    grid's extent (2 × 1 or 1 × 2 roots, :data:`geoterrain.core.grid.MAX_ROOTS`).

    Examples
    --------
    >>> walk_shape((5, 5)), walk_shape((5, 9)), walk_shape((9, 5))
    ((5, None), (5, (2, 1)), (5, (1, 2)))
    """
    R, C = shape
    if R == C:
        return R, None
    s = min(R, C) - 1
    return s + 1, ((C - 1) // s, (R - 1) // s)


@njit(cache=True, nogil=True)
def _set_parents(active, i, j, h, gen):
    R, C = active.shape
    p0i, p0j, p1i, p1j = parents_nb(i, j, h)  # the bintree's rule (seed 002 §2.3)
    if 0 <= p0i < R and 0 <= p0j < C:
        active[p0i, p0j] = gen
    if 0 <= p1i < R and 0 <= p1j < C:
        active[p1i, p1j] = gen


@njit(cache=True, nogil=True)
def close_upward_boxes(active, boxes, gen=True):
    """Activate both parents of every active vertex, finest depth first, in place.

    Depth order: for h = 1, 2, 4, ...: the edge midpoints of half-size h, then the
    block centres of half-size h (the edges' parents), then the next h. Only a
    box is scanned at each h: the union of ``boxes[L]`` (rows i0, i1, columns
    j0, j1 of the tiles filled at pyramid level L = log2 h, capped at the last
    row of ``boxes``) and the previous box grown by h (parents lie h away).
    ``active`` holds bools, or generation stamps where ``== gen`` means active; N × N,
    or a root grid's extent (its roots' side the shorter one less 1: the roots' centres
    are the last vertices with parents).
    """
    R, C = active.shape
    top = boxes.shape[0] - 1
    i0, i1, j0, j1 = R, -1, C, -1
    h, L = np.int64(1), 0  # not a literal 1: _set_parents compiles once
    while h < min(R, C) - 1:
        b = boxes[min(L, top)]
        i0, i1, j0, j1 = min(i0, b[0]), max(i1, b[1]), min(j0, b[2]), max(j1, b[3])
        if i1 >= 0:
            ia, ja = (i0 // h) * h, (j0 // h) * h
            for i in range(ia, i1 + 1, h):  # edge midpoints: i/h + j/h odd
                jb = ja if ((i // h) + (ja // h)) % 2 == 1 else ja + h
                for j in range(jb, j1 + 1, 2 * h):
                    if active[i, j] == gen:
                        _set_parents(active, i, j, h, gen)
            i0, j0 = max(0, i0 - h), max(0, j0 - h)  # their parents lie h away
            i1, j1 = min(R - 1, i1 + h), min(C - 1, j1 + h)
            ia, ja = (i0 // h) * h, (j0 // h) * h
            ib = ia if (ia // h) % 2 == 1 else ia + h  # block centres: i/h, j/h odd
            jb = ja if (ja // h) % 2 == 1 else ja + h
            for i in range(ib, i1 + 1, 2 * h):
                for j in range(jb, j1 + 1, 2 * h):
                    if active[i, j] == gen:
                        _set_parents(active, i, j, h, gen)
            i0, j0 = max(0, i0 - h), max(0, j0 - h)
            i1, j1 = min(R - 1, i1 + h), min(C - 1, j1 + h)
        h *= 2
        L += 1


def close_upward(active: np.ndarray) -> None:
    """:func:`close_upward_boxes` over the whole grid.

    Examples
    --------
    >>> a = np.zeros((5, 5), bool); a[1, 0] = True
    >>> close_upward(a); [tuple(map(int, p)) for p in np.argwhere(a)]
    [(0, 2), (0, 4), (1, 0), (1, 1), (2, 0), (2, 2), (4, 0)]
    """
    R, C = active.shape
    close_upward_boxes(active, np.array([[0, R - 1, 0, C - 1]], np.int64))


@njit(cache=True, nogil=True)
def fill_static(slots, i0, j0, step, D, e, active, mixed, gen=True, top_step=0):
    """Static predicate δ > e on pooled tiles, scattered into the dense flags in place.

    ``slots``: pool slot of each tile; ``i0, j0, step``: grid row/column of its first
    sample and its sample spacing. δ = inf (mixed diamond) is active and mixed.
    Only the samples new at a tile's level are read (both local indices even means
    a coarser level's vertex, read in that level's tile) unless ``step`` is
    ``top_step`` or ``top_step`` is 0.
    """
    T = D.shape[1]
    for k in range(slots.shape[0]):
        s = slots[k]
        coarse = top_step > 0 and step[k] < top_step
        for a in range(T):
            i = i0[k] + a * step[k]
            for b in range(T):
                if coarse and (a & 1) == 0 and (b & 1) == 0:
                    continue
                j = j0[k] + b * step[k]
                dl = np.float64(D[s, a, b])
                if dl > e:
                    active[i, j] = gen
                if dl == np.inf:
                    mixed[i, j] = gen


@njit(cache=True, nogil=True, inline="always")
def _grow_box(boxes, lv, i, j):
    if i < boxes[lv, 0]:
        boxes[lv, 0] = i
    if i > boxes[lv, 1]:
        boxes[lv, 1] = i
    if j < boxes[lv, 2]:
        boxes[lv, 2] = j
    if j > boxes[lv, 3]:
        boxes[lv, 3] = j


#: Samples per side of the blocks whose bounds :func:`fill_lp` tests before their samples.
BLOCK = 8


@njit(cache=True, nogil=True)
def block_bounds(D, R, H, X, Y, aff, s, i0, j0, step, coarse, out):
    """Per block of ``BLOCK``² samples of pool slot ``s`` (the last block of a row or
    column also holds the tile's last sample), over the samples new at the tile's level
    (all of them unless ``coarse``): largest δ and r, the x, y box (as
    :func:`sample_xy` computes them), the height range (NaN left out) and whether a
    height is NaN. ``out`` (nb, nb, 9); an empty block gets δ = r = 0."""
    T = D.shape[1]
    nb = out.shape[0]
    for p in range(nb):
        a1 = T if p == nb - 1 else (p + 1) * BLOCK
        for q in range(nb):
            b1 = T if q == nb - 1 else (q + 1) * BLOCK
            dm, rm = 0.0, 0.0
            xl, yl, hl = np.inf, np.inf, np.inf
            xh, yh, hh = -np.inf, -np.inf, -np.inf
            nan = 0.0
            for a in range(p * BLOCK, a1):
                i = i0 + a * step
                for b in range(q * BLOCK, b1):
                    if coarse and (a & 1) == 0 and (b & 1) == 0:
                        continue
                    j = j0 + b * step
                    dm = max(dm, np.float64(D[s, a, b]))
                    rm = max(rm, np.float64(R[s, a, b]))
                    x, y = sample_xy(X, Y, aff, s, a, b, i, j)
                    xl, xh, yl, yh = min(xl, x), max(xh, x), min(yl, y), max(yh, y)
                    h = H[s, a, b]
                    if h == h:
                        hl, hh = min(hl, h), max(hh, h)
                    else:
                        nan = 1.0
            o = out[p, q]
            o[0], o[1], o[2], o[3], o[4] = dm, rm, xl, yl, hl
            o[5], o[6], o[7], o[8] = xh, yh, hh, nan


@njit(cache=True, nogil=True, inline="always")
def _point_reach(view, px, py, pz):
    """What eq. 2 divides by at point p, before − r: the depth f·(p − eye) when ``view``
    (:class:`~geoterrain.core.view.ViewTerms`) carries the eye plane ``axis`` (the
    picture's bound, :meth:`~geoterrain.core.view.View.terms`), else the distance
    ‖p − eye‖ (LP)."""
    ax, eye = view.axis, view.eye
    if ax.shape[0] == 4:
        return ax[0] * px + ax[1] * py + ax[2] * pz + ax[3]
    dx, dy, dz = px - eye[0], py - eye[1], pz - eye[2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True, inline="always")
def _box_reach(view, xl, yl, zl, xh, yh, zh):
    """:func:`_point_reach`'s least value over the box [xl, xh] × [yl, yh] × [zl, zh]:
    the depth of its corner nearest the eye plane, or its distance to the eye (0
    inside)."""
    ax, eye = view.axis, view.eye
    if ax.shape[0] == 4:
        # the point's sum in the point's order: rounding keeps box ≤ point (fill_lp's floor)
        return (min(ax[0] * xl, ax[0] * xh) + min(ax[1] * yl, ax[1] * yh)
                + min(ax[2] * zl, ax[2] * zh) + ax[3])
    dx = max(xl - eye[0], 0.0, eye[0] - xh)
    dy = max(yl - eye[1], 0.0, eye[1] - yh)
    dz = max(zl - eye[2], 0.0, eye[2] - zh)
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True, inline="always")
def _block_floor(bk, zfac, zproxy, view, P):
    """LP eq. 2 on a block's bounds, as :func:`lp_tiles` on a tile's: −2 when no vertex
    of the block can be active, else a floor τ(D_box − r_max) (−1: none); the first
    ``P`` of the ``view``'s planes (:class:`~geoterrain.core.view.ViewTerms`) tested."""
    planes, lam, tau = view.planes, view.lam, view.tau
    dm, rm = bk[0], bk[1]
    if dm == np.inf:
        return -1.0  # a mixed vertex is always active (see fill_lp)
    if not dm > 0.0:
        return -2.0
    zl, zh = bk[4] * zfac, bk[7] * zfac
    if zl > zh:
        zl, zh = zh, zl
    if bk[8] > 0.0:
        zl, zh = min(zl, zproxy), max(zh, zproxy)
    d = _box_reach(view, bk[2], bk[3], zl, bk[5], bk[6], zh)
    if not (d <= rm or lam * dm > tau * (d - rm)):
        return -2.0
    for q in range(P):
        a, b, c, w = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
        fx = bk[5] + rm if a >= 0 else bk[2] - rm
        fy = bk[6] + rm if b >= 0 else bk[3] - rm
        fz = zh + rm + dm if c >= 0 else zl - rm - dm  # drawn up to δ off (_sphere_out)
        if a * fx + b * fy + c * fz + w < 0:
            return -2.0
    return tau * (d - rm) if d > rm else -1.0


@njit(cache=True, nogil=True)
def fill_lp(tiles, inside, floor, slabs, zproxy, view, flags, top_step, blocks=True):
    """LP eq. 2 with sphere culling on pooled ``tiles`` (:class:`~geoterrain.lod.pool.PooledTiles`,
    read from the pool's ``slabs``, :class:`~geoterrain.lod.pool.PoolSlabs`), for ``view``
    (:class:`~geoterrain.core.view.ViewTerms`), scattered into the dense ``flags``
    (:class:`ActiveFlags`).

    A vertex is active iff its sphere (p, r), moved up or down by δ, is not outside any
    frustum plane (:func:`_sphere_out`: what is drawn for its samples may lie δ off), δ > 0,
    and λδ > τ(d − r) or the eye is inside the sphere (d ≤ r); d = ‖p − eye‖, or with
    the view's eye plane the depth f·(p − eye) (the picture's bound: the sphere crossing
    the eye plane, d ≤ r, refines; :func:`_point_reach`), and
    p = (x, y, height · zfac), invalid heights (NaN) placed at ``zproxy``. A mixed
    diamond (δ = inf) is always active (and mixed): culling it by its own sphere
    (which bounds its descendants, not its corners) could drop every triangle around
    a visible corner. Tiles flagged ``inside`` (their padded box is inside the
    frustum) skip the plane tests. Flags are set to the stamp ``gen``. Only the
    samples new at a tile's level are evaluated (see :func:`fill_static`): the tile
    holding a coarser vertex passes the tile test whenever that vertex can be active.
    A vertex with λδ ≤ ``floor[k]`` (τ times the tile's least d − r, from
    :func:`lp_tiles`) is inactive and skipped before its sphere is read: d and r are
    computed by the same monotone float operations, so the result is unchanged.
    Each vertex made active grows ``flags.boxes[L]`` (L the tile's level), so the
    closure scans where vertices are active, not the whole of a coarse tile that only a
    corner of the view touches.
    With ``blocks``, each ``BLOCK``² block's bounds (``BK[slot]``, from
    :func:`block_bounds`) are tested first, as the tiles' are, and a block that can
    hold no active vertex is skipped (a mixed vertex makes its block's δ infinite, so
    it is never skipped); a block's floor replaces the tile's where it is higher. The
    flags are the same as without blocks: the tests are conservative, with the same
    monotone float operations.
    Serial on purpose: on a shared 2-core machine, a parallel region waiting on a
    descheduled thread made frames 3× slower than one thread."""
    BK = slabs.BK
    T = slabs.D.shape[1]
    nb = BK.shape[1] if blocks else 1
    for k in range(tiles.slots.shape[0]):
        s = tiles.slots[k]
        P = 0 if inside[k] else view.planes.shape[0]
        coarse = tiles.step[k] < top_step
        for p in range(nb):
            rows = (p * BLOCK, T if p == nb - 1 else (p + 1) * BLOCK) if blocks else (0, T)
            for q in range(nb):
                cols = (q * BLOCK, T if q == nb - 1 else (q + 1) * BLOCK) if blocks else (0, T)
                fl = floor[k]
                if blocks:
                    fb = _block_floor(BK[s, p, q], slabs.zfac, zproxy, view, P)
                    if fb == -2.0:
                        continue
                    fl = max(fl, fb)
                _fill_block(tiles, k, coarse, P, rows, cols, fl, slabs, zproxy, view, flags)


@njit(cache=True, nogil=True, inline="always")
def _sphere_out(planes, P, px, py, pz, r, dl):
    """Whether a vertex is culled: its sphere (p, r), moved up or down by its error δ
    (``dl``), lies outside one of the first ``P`` frustum ``planes`` (unit normals).

    The drawn surface over the vertex's samples lies within δ of them vertically, so
    nothing it draws can enter the picture; a sphere merely outside (LP) let samples
    just outside the frustum be drawn just inside, δ off. Nesting holds as for the
    sphere alone: n·p_c + r_c ≤ n·p_p + r_p for a child's sphere in its parent's, and
    δ_c ≤ δ_p (saturated), so a child is culled wherever its parent is."""
    for q in range(P):
        c = planes[q, 2]
        if planes[q, 0] * px + planes[q, 1] * py + c * pz + planes[q, 3] + r \
                + abs(c) * dl < 0.0:
            return True
    return False


@njit(cache=True, nogil=True, inline="always")
def _fill_block(tiles, k, coarse, P, rows, cols, fl, slabs, zproxy, view, flags):
    """:func:`fill_lp`'s test on the samples ``rows`` × ``cols`` ([a0, a1) × [b0, b1))
    of tile k, the first ``P`` planes tested, vertices with λδ ≤ ``fl`` skipped."""
    s, i0, j0, step = tiles.slots[k], tiles.i0[k], tiles.j0[k], tiles.step[k]
    lv = tiles.level[k]
    D, R, H, X, Y, aff, zfac = slabs.D, slabs.R, slabs.H, slabs.X, slabs.Y, slabs.aff, slabs.zfac
    planes, lam, tau = view.planes, view.lam, view.tau
    active, mixed, gen, boxes = flags
    a0, a1 = rows
    b0, b1 = cols
    for a in range(a0, a1):
        i = i0 + a * step
        for b in range(b0, b1):
            if coarse and (a & 1) == 0 and (b & 1) == 0:
                continue
            j = j0 + b * step
            dl = np.float64(D[s, a, b])
            if dl == np.inf:
                active[i, j] = gen
                mixed[i, j] = gen
                _grow_box(boxes, lv, i, j)
                continue
            if not dl > 0.0 or lam * dl <= fl:
                continue
            r = np.float64(R[s, a, b])
            px, py = sample_xy(X, Y, aff, s, a, b, i, j)
            h = H[s, a, b]
            pz = h * zfac if h == h else zproxy
            if _sphere_out(planes, P, px, py, pz, r, dl):
                continue
            d = _point_reach(view, px, py, pz)
            if d <= r or lam * dl > tau * (d - r):
                active[i, j] = gen
                _grow_box(boxes, lv, i, j)


@njit(cache=True, nogil=True)
def lp_tiles(lo, hi, dmax, rmax, grow, view, floor):
    """The tiles that can hold an LP-active vertex (seed 002 eq. 2, tested with tile
    bounds only, for ``view``: :class:`~geoterrain.core.view.ViewTerms`), as a status per
    tile: 0 no, 1 yes, 2 yes and inside the frustum.

    Conservative: a vertex of the tile lies in its box, so d − r ≥ D_box − r_max (d the
    distance or the depth, :func:`_box_reach`); its
    sphere lies in the box grown by r_max, and what is drawn of it within ``grow`` (the
    largest finite δ of its vertices, :func:`_sphere_out`) of that vertically, tested
    against each plane as a box.
    ``floor[k]`` receives τ·(D_box − r_max): a vertex with λδ ≤ it is not active
    (:func:`fill_lp` skips it without reading its sphere).
    """
    planes, lam, tau = view.planes, view.lam, view.tau
    n = lo.shape[0]
    out = np.zeros(n, np.uint8)
    for k in range(n):
        floor[k] = -1.0
        dm = dmax[k]
        if not dm > 0.0:
            continue
        r = rmax[k]
        d = _box_reach(view, lo[k, 0], lo[k, 1], lo[k, 2], hi[k, 0], hi[k, 1], hi[k, 2])
        if not (d <= r or lam * dm > tau * (d - r)):
            continue
        if d > r:
            floor[k] = tau * (d - r)
        status = 2
        for q in range(planes.shape[0]):
            a, b, c, w = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
            # the box corner farthest along / against the plane normal
            fx = hi[k, 0] + r if a >= 0 else lo[k, 0] - r
            fy = hi[k, 1] + r if b >= 0 else lo[k, 1] - r
            fz = hi[k, 2] + r + grow[k] if c >= 0 else lo[k, 2] - r - grow[k]
            if a * fx + b * fy + c * fz + w < 0:
                status = 0
                break
            nx = lo[k, 0] - r if a >= 0 else hi[k, 0] + r
            ny = lo[k, 1] - r if b >= 0 else hi[k, 1] + r
            nz = lo[k, 2] - r if c >= 0 else hi[k, 2] + r
            if a * nx + b * ny + c * nz + w < 0:
                status = 1
        out[k] = status
    return out


@njit(cache=True, nogil=True)
def level_boxes(L, i0, i1, j0, j1, boxes):
    """Grow ``boxes[L]`` (rows i0, i1, columns j0, j1) to hold each tile's samples."""
    for k in range(L.shape[0]):
        b = boxes[L[k]]
        b[0] = min(b[0], i0[k])
        b[1] = max(b[1], i1[k])
        b[2] = min(b[2], j0[k])
        b[3] = max(b[3], j1[k])


@njit(cache=True, nogil=True)
def gather_pooled(flat, N, slabs, xyz, ij, level):
    """Scene positions ``xyz`` (x, y, height · zfac), grid ``ij`` and pyramid level of
    full-resolution samples ``flat`` (i·N + j), read from the coarsest tile holding
    each in the pool's ``slabs`` (:class:`~geoterrain.lod.pool.PoolSlabs`; unstored
    tiles: NaN height, x = y = 0)."""
    top, t, base, slot_of = slabs.top, slabs.t, slabs.base, slabs.slot_of
    H, X, Y, aff, zfac = slabs.H, slabs.X, slabs.Y, slabs.aff, slabs.zfac
    for k in range(flat.shape[0]):
        i, j = flat[k] // N, flat[k] % N
        L, idx, a, b = _coarsest_tile(i, j, top, t, base)
        s = slot_of[idx] if idx >= 0 else -1
        level[k] = L
        ij[k, 0], ij[k, 1] = i, j
        if s < 0:
            xyz[k, 0], xyz[k, 1], xyz[k, 2] = 0.0, 0.0, np.nan
        else:
            x, y = sample_xy(X, Y, aff, s, a, b, i, j)
            xyz[k, 0], xyz[k, 1], xyz[k, 2] = x, y, H[s, a, b] * zfac


@njit(cache=True, nogil=True, inline="always")
def tree_roots(base, top):
    """(across, down) top tiles of a tile walk's ``base``
    (:meth:`geoterrain.core.grid.Grid.walk_table`): a root grid's, or (1, 1)."""
    if base.shape[0] > top + 2:
        return base[2 * top + 2], base[3 * top + 3]
    return np.int64(1), np.int64(1)


@njit(cache=True, nogil=True, inline="always")
def tree_row(table, base, top, L, x, y):
    """The row of tile (L, x, y) in a tile walk's dense ``table`` (−1: not stored, or
    past a root grid's last tile column or row; a square's level L is 2^(top − L) tiles
    a side)."""
    if base.shape[0] > top + 2:
        across = base[top + 2 + L]
        if x >= across or y >= base[2 * top + 3 + L]:
            return np.int64(-1)
    else:
        across = np.int64(1) << (top - L)
    return table[base[L] + y * across + x]


@njit(cache=True, nogil=True)
def _coarsest_tile(i, j, top, t, base):
    """Level, slot-table index and sample (a, b) of the coarsest tile holding sample
    (i, j). ``base`` (:meth:`geoterrain.core.grid.Grid.offsets`, then each level's tiles
    across and down: ``base[top + 2 + L]``, ``base[2 top + 3 + L]``; a square's table
    stops at its offsets, its level L 2^(top − L) tiles a side). Index −1: the sample
    lies beyond the level's tiles (a root grid's padding past the raster, no tile)."""
    low = i | j
    L = top
    if low != 0:
        L = 0
        while (low & 1) == 0 and L < top:
            low >>= 1
            L += 1
    li, lj = i >> L, j >> L
    if base.shape[0] > top + 2:
        across, down = base[top + 2 + L], base[2 * top + 3 + L]
    else:
        across = down = np.int64(1) << (top - L)
    ty, tx = li >> t, lj >> t
    if ty == down and li == ty << t:  # the last tile's far border
        ty -= 1
    if tx == across and lj == tx << t:
        tx -= 1
    if ty >= down or tx >= across:
        return L, np.int64(-1), np.int64(0), np.int64(0)
    return L, base[L] + ty * across + tx, li - (ty << t), lj - (tx << t)


@njit(cache=True, nogil=True)
def mark_tiles(flat, N, top, t, base, occ):
    """Flag in ``occ`` (the pool's slot-table layout) the coarsest tile of each sample."""
    for k in range(flat.shape[0]):
        idx = _coarsest_tile(flat[k] // N, flat[k] % N, top, t, base)[1]
        if idx >= 0:
            occ[idx] = True


@njit(cache=True, nogil=True)
def lp_tiles_walk(tree, dmax, rmax, rsub, grow, gsub, view, floor, out):
    """:func:`lp_tiles` for the tiles the quadtree ``tree``
    (:class:`~geoterrain.lod.tiles.TileTree`) reaches from the top: a subtree whose
    box grown by its largest radius (``rsub``: the tile's and every descendant's) and
    vertically by its largest finite δ (``gsub``, as ``grow`` is the tile's) lies
    outside a frustum plane is not entered. A descendant's box lies in its ancestor's
    and its radius and δ are at most ``rsub`` and ``gsub``, so :func:`lp_tiles` gives
    those tiles status 0 too: the result is the same, at a cost that follows the tiles
    near the frustum.
    ``out``/``floor`` are filled for the visited rows (``out`` must start at 0).
    Returns tiles visited."""
    table, base, top, lo, hi = tree
    planes = view.planes
    P = planes.shape[0]
    # a root grid's base carries each level's tiles across and down (_coarsest_tile)
    rect = base.shape[0] > top + 2
    rx = base[2 * top + 2] if rect else 1
    ry = base[3 * top + 3] if rect else 1
    stack = np.empty((4 * (top + 2) + rx * ry, 3), np.int64)
    sp, visited = 0, 0
    for y in range(ry):
        for x in range(rx):
            stack[sp, 0], stack[sp, 1], stack[sp, 2] = top, x, y
            sp += 1
    for k in range(floor.shape[0]):
        floor[k] = -1.0
    fl = np.empty(1)
    while sp > 0:
        sp -= 1
        L, x, y = stack[sp, 0], stack[sp, 1], stack[sp, 2]
        across = base[top + 2 + L] if rect else np.int64(1) << (top - L)
        if rect and (x >= across or y >= base[2 * top + 3 + L]):
            continue  # past a root grid's last tile column or row
        row = table[base[L] + y * across + x]
        if row < 0:
            continue
        visited += 1
        r, g = rsub[row], gsub[row]
        skip = False
        for q in range(P):
            a, b, c, w = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
            fx = hi[row, 0] + r if a >= 0 else lo[row, 0] - r
            fy = hi[row, 1] + r if b >= 0 else lo[row, 1] - r
            fz = hi[row, 2] + r + g if c >= 0 else lo[row, 2] - r - g
            if a * fx + b * fy + c * fz + w < 0:
                skip = True
                break
        if skip:
            continue
        st = lp_tiles(lo[row:row + 1], hi[row:row + 1], dmax[row:row + 1],
                      rmax[row:row + 1], grow[row:row + 1], view, fl)
        out[row] = st[0]
        floor[row] = fl[0]
        if L > 0:
            for dy in range(2):
                for dx in range(2):
                    stack[sp, 0], stack[sp, 1], stack[sp, 2] = L - 1, 2 * x + dx, 2 * y + dy
                    sp += 1
    return visited

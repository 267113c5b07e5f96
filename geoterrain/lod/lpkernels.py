"""Compiled LP activity (numba, seed 002 eq. 2, ``λδ > τ(d − r)``): the flags filled a
block of samples at a time behind the block's bounds (:func:`block_bounds`,
:func:`fill_lp`), and the tiles that can hold an active vertex tested by their bounds
alone (:func:`lp_tiles`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.lod.activekernels import _grow_box, sample_xy

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

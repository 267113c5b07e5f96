"""The compiled horizon kernel of horizon culling (seed 000 §2.6, Fiedler's horizon:
test with the max, add with the min), over azimuth bins.

:func:`_horizon_cull` takes footprints (quadrilaterals in scene x/y, each with its
lowest height, or a hole) and boxes, and marks the boxes hidden behind the footprints'
horizon, seen from an eye above the surface. Why each step is conservative is argued in
:mod:`geoterrain.lod.occlusion`, which builds the footprints from the stored tiles and
calls it. Footprint spans use pseudo-angles (two atan2 a footprint), the frustum's
sector is a wedge test without angles, and a bin that rounding could move (``EPS``)
counts against culling.

Examples
--------
>>> import numpy as np
>>> w = _wedge(0.0, 0.5)
>>> bool(_in_sector(0.0, 0.0, np.array([10.0, 1.0, 0.5]), w))
True
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

BINS = 2048  # azimuth bins over the full turn
EPS = 1e-12  # radians: a bin that rounding could move is counted against culling


class FootprintSet(NamedTuple):
    """Footprints as :func:`_horizon_cull` reads them: per footprint its ``corners``
    (P, K, 2) in scene x/y (a convex polygon), ``cen`` (P, 3) its centre and radius,
    ``state`` (see :func:`_horizon_cull`) and ``zmin`` its lowest (or, standing in,
    highest) height; ``margin``: how far a footprint's drawn surface may reach beyond it
    (every span is widened by it)."""

    corners: np.ndarray
    cen: np.ndarray
    state: np.ndarray
    zmin: np.ndarray
    margin: float


@njit(cache=True, nogil=True, inline="always")
def _pseudo_angle(c, d):
    """A number that grows with atan2(c, d) over (−π, π] (the "diamond angle"), so the
    extreme corners are found without trigonometry."""
    s = abs(c) + abs(d)
    if s == 0.0:
        return 0.0
    if d >= 0.0:
        return c / s
    return (2.0 if c >= 0.0 else -2.0) - c / s


@njit(cache=True, nogil=True)
def _poly_span(ex, ey, c):
    """Azimuth span (start, width) of a convex polygon ``c`` (K, 2) seen from (ex, ey),
    and its nearest and farthest horizontal distance; width < 0 if the eye is inside."""
    K = c.shape[0]
    rx, ry = -K * ex, -K * ey  # the direction to the centroid (times K)
    for k in range(K):
        rx += c[k, 0]
        ry += c[k, 1]
    # the corners' angles about that direction: extremes by pseudo-angle, then atan2 twice
    plo, phi, klo, khi, far2 = 1e300, -1e300, 0, 0, 0.0
    for k in range(K):
        dx, dy = c[k, 0] - ex, c[k, 1] - ey
        pa = _pseudo_angle(rx * dy - ry * dx, rx * dx + ry * dy)
        if pa < plo:
            plo, klo = pa, k
        if pa > phi:
            phi, khi = pa, k
        far2 = max(far2, dx * dx + dy * dy)
    dlx, dly = c[klo, 0] - ex, c[klo, 1] - ey
    dhx, dhy = c[khi, 0] - ex, c[khi, 1] - ey
    lo = math.atan2(rx * dly - ry * dlx, rx * dlx + ry * dly)
    hi = math.atan2(rx * dhy - ry * dhx, rx * dhx + ry * dhy)
    # nearest distance: to the edges (the eye is outside when every cross product of
    # the edges with the eye has one sign)
    near2, sgn, inside = 1e300, 0, True
    for k in range(K):
        ax, ay = c[k, 0], c[k, 1]
        bx, by = c[(k + 1) % K, 0], c[(k + 1) % K, 1]
        ux, uy = bx - ax, by - ay
        cr = ux * (ey - ay) - uy * (ex - ax)
        s = 1 if cr > 0 else (-1 if cr < 0 else 0)
        if s != 0:
            if sgn == 0:
                sgn = s
            elif s != sgn:
                inside = False
        L2 = ux * ux + uy * uy
        w = 0.0 if L2 == 0 else min(1.0, max(0.0, ((ex - ax) * ux + (ey - ay) * uy) / L2))
        qx, qy = ex - ax - w * ux, ey - ay - w * uy
        near2 = min(near2, qx * qx + qy * qy)
    far = math.sqrt(far2)
    if inside or hi - lo >= math.pi:
        return 0.0, -1.0, 0.0, far
    return math.atan2(dly, dlx), hi - lo, math.sqrt(near2), far


@njit(cache=True, nogil=True)
def _near_footprints(ex, ey, corners, cen, reach_to):
    """Footprints within ``reach_to`` of the eye (or holding it)."""
    out = np.zeros(corners.shape[0], np.bool_)
    for p in range(corners.shape[0]):
        if math.hypot(cen[p, 0] - ex, cen[p, 1] - ey) > cen[p, 2] + reach_to:
            continue
        s, w, dn, df = _poly_span(ex, ey, corners[p])
        out[p] = w < 0 or dn <= reach_to
    return out


@njit(cache=True, nogil=True)
def _wedge(sec0, secw):
    """The sector [sec0, sec0 + secw] as its two unit rays, and whether it is the full
    turn (:func:`_sector` gives a width of 4π for any sector π or more wide)."""
    if secw >= math.pi:
        return np.array([1.0, 0.0, 1.0, 0.0, 1.0])
    return np.array([math.cos(sec0), math.sin(sec0), math.cos(sec0 + secw),
                     math.sin(sec0 + secw), 0.0])


@njit(cache=True, nogil=True, inline="always")
def _in_sector(ex, ey, cen, wedge):
    """Whether a footprint (centre x, y and radius ``cen``) may meet the sector of
    azimuths ``wedge`` (:func:`_wedge`; a cheap test before :func:`_poly_span`): its
    centre lies in the wedge, or its circle reaches one of the wedge's two rays."""
    if wedge[4] != 0.0:  # the sector is the full turn
        return True
    cx, cy, R = cen[0] - ex, cen[1] - ey, cen[2] * (1 + 1e-9) + 1e-300
    ax, ay, bx, by = wedge[0], wedge[1], wedge[2], wedge[3]
    if ax * cy - ay * cx >= 0.0 and cx * by - cy * bx >= 0.0:
        return True  # the centre is inside the wedge (narrower than π)
    for ux, uy in ((ax, ay), (bx, by)):
        t = ux * cx + uy * cy
        d2 = cx * cx + cy * cy - t * t if t > 0.0 else cx * cx + cy * cy
        if d2 <= R * R:
            return True
    return False


@njit(cache=True, nogil=True)
def _horizon_cull(ex, ey, ez, fps, sec0, secw, lo, hi, out):
    """``out[row] = True`` for each box (``lo``, ``hi``) hidden behind the horizon of
    the footprints ``fps`` (:class:`FootprintSet`), seen from (``ex``, ``ey``, ``ez``)
    (the eye already known to be above the surface).

    ``state`` per footprint: 1 all valid (an occluder), 0 a hole (nodata or outside the
    grid), −1 ignored (replaced by finer footprints), 2 standing in for finer
    footprints inside it, with ``zmin`` their highest sample (an upper bound of their
    horizon, so the boxes it hides are a superset); ``cen`` its centre and radius.
    Only rays in the sector of azimuths [sec0, sec0 + secw] (the frustum's) matter.

    Returns 1 (``out`` left as is) when a state-2 footprint holds the eye or lies within
    ``margin`` of it, where it gives no upper bound; else 0."""
    corners, cen, state, zmin, margin = fps
    P = corners.shape[0]
    B = BINS
    dphi = 2 * math.pi / B
    wedge = _wedge(sec0, secw)
    reach = np.full(B, 1e300)  # per bin: distance to the nearest footprint with a hole
    # 1. holes: a ray counts as blocked only until it may have passed over one
    for p in range(P):
        if state[p] != 0 or not _in_sector(ex, ey, cen[p], wedge):
            continue
        s, w, dn, df = _poly_span(ex, ey, corners[p])
        if w < 0:  # the eye is over a hole: nothing is hidden
            return 0
        m = (math.asin(min(1.0, margin / dn)) if dn > 0 else math.pi) + EPS
        b0 = int(math.floor((s - m) / dphi))
        b1 = int(math.floor((s + w + m) / dphi))
        d = dn - margin
        for b in range(b0, b1 + 1):
            k = b % B
            if d < reach[k]:
                reach[k] = d
    # the occludees by their nearest distance, with the height their rays rise to at
    # least (over the box: from its nearest point if above the eye, else its farthest)
    R = lo.shape[0]
    dnear = np.empty(R)
    tops = np.empty(R)
    for r in range(R):
        dx = max(lo[r, 0] - ex, 0.0, ex - hi[r, 0])
        dy = max(lo[r, 1] - ey, 0.0, ey - hi[r, 1])
        dnear[r] = math.hypot(dx, dy)
        dz = hi[r, 2] - ez
        if dz >= 0:
            tops[r] = dz / dnear[r] if dnear[r] > 0 else 1e300
        else:
            fx = max(abs(lo[r, 0] - ex), abs(hi[r, 0] - ex))
            fy = max(abs(lo[r, 1] - ey), abs(hi[r, 1] - ey))
            tops[r] = dz / math.sqrt(fx * fx + fy * fy)
    rorder = np.argsort(dnear)
    sd = dnear[rorder]
    lowest = np.empty(R + 1)  # lowest[i]: the lowest top of the occludees i … R−1 (sorted)
    lowest[R] = 1e300
    for i in range(R - 1, -1, -1):
        lowest[i] = min(lowest[i + 1], tops[rorder[i]])
    # 2. occluders: valid footprints, ordered by their farthest distance
    occ_far = np.empty(P)
    occ_tan = np.empty(P)
    occ_b0 = np.empty(P, np.int64)
    occ_b1 = np.empty(P, np.int64)
    n_occ = 0
    for p in range(P):
        st = state[p]
        if st == 1:
            # its horizon is at most (zmin − z_eye)/d_centre (d_near ≤ d_centre ≤ d_far),
            # and it blocks only occludees nearest-farther than d_centre: skip it if none
            # of those reaches below that (no trigonometry spent on it)
            dc = math.hypot(cen[p, 0] - ex, cen[p, 1] - ey)
            if dc > 0 and (zmin[p] - ez) / dc <= lowest[np.searchsorted(sd, dc, "right")]:
                continue
        elif st != 2:
            continue
        if not _in_sector(ex, ey, cen[p], wedge):
            continue
        s, w, dn, df = _poly_span(ex, ey, corners[p])
        if w < 0 or dn <= margin:
            if st == 2:  # its blocks may surround the eye: no upper bound from it
                return 1
            continue
        m = math.asin(min(1.0, margin / dn)) + EPS
        dn, df = dn - margin, df + margin
        dz = zmin[p] - ez
        if st == 1:
            b0 = int(math.ceil((s + m) / dphi))
            b1 = int(math.floor((s + w - m) / dphi)) - 1  # bins wholly inside the span
            if b1 < b0:
                continue
            occ_tan[n_occ] = dz / df if dz >= 0 else dz / dn
            occ_far[n_occ] = df
        else:  # an upper bound of any footprint inside it, ``zmin`` its highest sample
            b0 = int(math.floor((s - m) / dphi))
            b1 = int(math.floor((s + w + m) / dphi))  # every bin it touches
            occ_tan[n_occ] = dz / dn if dz >= 0 else dz / df
            occ_far[n_occ] = dn  # (any of them falls behind no sooner)
        occ_b0[n_occ], occ_b1[n_occ] = b0, b1
        n_occ += 1
    order = np.argsort(occ_far[:n_occ])
    # 3. occludees by their nearest distance; the horizon grows as occluders fall behind
    horizon = np.full(B, -1e300)
    hmax = -1e300  # the highest horizon in any bin so far
    box = np.empty((4, 2))
    bc = np.empty(3)
    q = 0
    for rr in range(R):
        r = rorder[rr]
        dn = dnear[r]
        if dn <= 0:
            continue
        while q < n_occ and occ_far[order[q]] < dn:
            o = order[q]
            q += 1
            for b in range(occ_b0[o], occ_b1[o] + 1):
                k = b % B
                if occ_far[o] < reach[k] and occ_tan[o] > horizon[k]:
                    horizon[k] = occ_tan[o]
                    hmax = max(hmax, occ_tan[o])
        top = tops[r]
        if not top < hmax:  # over the horizon in every bin: seen, whatever its span
            continue
        box[0, 0], box[0, 1] = lo[r, 0], lo[r, 1]
        box[1, 0], box[1, 1] = hi[r, 0], lo[r, 1]
        box[2, 0], box[2, 1] = hi[r, 0], hi[r, 1]
        box[3, 0], box[3, 1] = lo[r, 0], hi[r, 1]
        bc[0], bc[1] = 0.5 * (lo[r, 0] + hi[r, 0]), 0.5 * (lo[r, 1] + hi[r, 1])
        bc[2] = 0.5 * math.hypot(hi[r, 0] - lo[r, 0], hi[r, 1] - lo[r, 1])
        if not _in_sector(ex, ey, bc, wedge):
            continue
        s, w, _, df = _poly_span(ex, ey, box)
        if w < 0:
            continue
        b0 = int(math.floor((s - EPS) / dphi))
        b1 = int(math.floor((s + w + EPS) / dphi))
        hid = True
        for b in range(b0, b1 + 1):
            if not top < horizon[b % B]:
                hid = False
                break
        out[r] = hid
    return 0

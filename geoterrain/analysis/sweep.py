"""The viewshed's compiled sweep: Wang, Robinson & White's reference planes (2000), as
``gdal_viewshed`` computes them, over rows outward from the observer, reading a tile's
heights only when its box can reach the sight lines.

Every cell's *sight-line height* (the height a point there must reach to be seen) is
extrapolated from the observable heights H of the two cells next to it toward the
observer, H = max(cell height, sight-line height); heights are lowered by Earth's
curvature and refraction, z − k·d² (k = coefficient / (2 a)). With gdal_viewshed's
default ``edge`` mode the two cells are the one along the row (or column) and the
diagonal one; ``diagonal`` mode takes the row's and the column's; ``max`` and ``min``
the larger or smaller of the two answers.

Heights are known to ±ε (the store's codec error), and the observer's eye with them, so
the sweep carries two fields, the lowest and the highest sight lines the source heights
could give (each formula grows with the heights it reads and falls with the eye's, so
the true one lies between): a cell is visible when its lowest height reaches the highest
sight line, hidden when its highest height stays below the lowest, and *uncertain*
otherwise. With ε = 0 the two fields are one, and every cell is decided exactly as the
sweep over the source raster decides it.

A cell of a tile that is not decoded is decided from a bound of its height: first the
tile's box (the catalog's, free), then the coarser level's surface plus that level's
stored error (the tile's parent, which decoding the tile would read anyway). When the
bound (lowered by the cell's own curvature drop, plus ε and the target height) lies
below the lowest sight line, the cell is hidden and its observable heights are the sight
lines themselves, exactly what its heights would have given. Otherwise the sweep stops
and asks for the tile (:func:`sweep_rows` returns it) and goes on from that cell.

Codes: 0 hidden, 1 visible, 255 uncertain, 254 no answer (outside the radius, or nodata:
a void neither hides nor is seen).

Examples
--------
>>> line_height(2, 10.0, 0.0), edge_height(1, 3, 10.0, 4.0, 0.0)
(20.0, 9.0)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

HIDDEN, VISIBLE, UNCERTAIN, NO_ANSWER = 0, 1, 255, 254
MODES = ("edge", "diagonal", "max", "min")
NEED_NONE = -1


class SweepGeometry(NamedTuple):
    """The observer in window cells (``orow``, ``ocol``), ground metres per column step
    ``mx`` (per window row; ``mx0`` the observer's row's, which the radius is measured
    with, so that the disc is convex on the grid) and the north-south offset ``ny`` of
    each row from the observer's (metres), the radius² (m²), the curvature factor ``kcurv``
    (metres of drop per m²), the eye's height interval (``eye_lo``, ``eye_hi``, metres),
    the target's height above ground, ε (metres), the mode (0 edge, 1 diagonal, 2 max, 3 min) and
    ``two``: whether heights are known only within bounds (two fields are swept)."""

    orow: int
    ocol: int
    mx: np.ndarray
    mx0: float
    ny: np.ndarray
    r2max: float
    kcurv: float
    eye_lo: float
    eye_hi: float
    target: float
    eps: float
    mode: int
    two: bool


class SweepTiles(NamedTuple):
    """The window's heights ``z`` (metres, NaN: nodata; read only in decoded tiles), in
    (2^t + 1)² blocks: window tile (ty, tx) holds its heights in block ``slot[ty, tx]``
    (``z[slot[ty, tx], i, j]``: grid sample (row, column) (ty + ty0)·2^t + i,
    (tx + tx0)·2^t + j; −1: no block), a block given to a tile when it is first read and
    taken back once the sweep has left the tile's row (a tile's cells lie together, and
    the few blocks are used again and again, so reads touch little fresh memory), each
    window tile's ``status`` (0 not decoded, 1 decoded, 2 not stored: no data, 3 ``z``
    holds upper bounds of its heights, less ε, from a coarser level), ``ztop``
    (the highest height of its box, metres) and ``zerr`` (how far its heights in ``z`` may
    be from the source's: ε, plus the pyramid level's error where read coarser); the
    window's first grid row and column (``r0``, ``c0``), the tile size 2^``t``, the
    window's first tile row and column (``ty0``, ``tx0``) and the grid's last tile index
    (``tlast_y`` down, ``tlast_x`` across: a root grid's level 0 is a rectangle of tiles)."""

    z: np.ndarray
    slot: np.ndarray
    status: np.ndarray
    ztop: np.ndarray
    zerr: np.ndarray
    r0: int
    c0: int
    t: int
    ty0: int
    tx0: int
    tlast_y: int
    tlast_x: int


class SweepState(NamedTuple):
    """The observable heights (low, high) of the previous row and of the row being swept,
    the codes ``out`` (window rows, columns; NO_ANSWER where the sweep writes nothing,
    as it comes), and where a row that waited for a tile goes
    on (``resume``: 0 from its start, 1 from the columns ``resume[1]`` westward and
    ``resume[2]`` eastward); ``probe``: the cell that asked for a tile (column, its
    lowest sight line, curvature drop and lift: it is hidden by a bound z when
    z − drop + lift < sight line; column −1: none)."""

    last_lo: np.ndarray
    last_hi: np.ndarray
    this_lo: np.ndarray
    this_hi: np.ndarray
    out: np.ndarray
    resume: np.ndarray
    probe: np.ndarray


@njit(cache=True, inline="always")
def line_height(i, za, zo):
    """Sight-line height at i cells along a row or column through the observer, from the
    observable height ``za`` one cell nearer (GDAL's CalcHeightLine)."""
    if i == 1:
        return za
    return (za - zo) / (i - 1) + za


@njit(cache=True, inline="always")
def edge_height(i, j, za, zb, zo):
    """Sight-line height from the cells along the edge toward the observer: ``za`` the
    diagonal neighbour, ``zb`` the one along the longer axis (GDAL's CalcHeightEdge)."""
    if i == j:
        return line_height(i, za, zo)
    return ((za - zo) * i + (zb - zo) * (j - i)) / (j - 1) + zo


@njit(cache=True, inline="always")
def diagonal_height(i, j, za, zb, zo):
    """Sight-line height from the row's and the column's neighbours (GDAL's
    CalcHeightDiagonal)."""
    return ((za - zo) * i + (zb - zo) * j) / (i + j - 1) + zo


@njit(cache=True, inline="always")
def _los(mode, i, j, this_prev, last, last_prev, zo):
    """The sight-line height of cell (i columns, j rows from the observer; i, j ≥ 1) from
    its neighbours toward the observer: along its row ``this_prev``, in the previous row
    ``last`` (same column) and ``last_prev`` (diagonal)."""
    if mode == 1:
        return diagonal_height(i, j, this_prev, last, zo)
    if i >= j:
        e = edge_height(j, i, last_prev, this_prev, zo)
    else:
        e = edge_height(i, j, last_prev, last, zo)
    if mode == 0:
        return e
    d = diagonal_height(i, j, this_prev, last, zo)
    return max(e, d) if mode == 2 else min(e, d)


@njit(cache=True, inline="always")
def _tile_of(tiles, r, c):
    ty = min((r + tiles.r0) >> tiles.t, tiles.tlast_y) - tiles.ty0
    tx = min((c + tiles.c0) >> tiles.t, tiles.tlast_x) - tiles.tx0
    return ty, tx


@njit(cache=True, inline="always")
def _z(tiles, r, c):
    """The height held for window cell (r, c): in its tile's block."""
    ty, tx = _tile_of(tiles, r, c)
    return tiles.z[tiles.slot[ty, tx], r + tiles.r0 - ((ty + tiles.ty0) << tiles.t),
                   c + tiles.c0 - ((tx + tiles.tx0) << tiles.t)]


@njit(cache=True, inline="always")
def _decide(geo, st, r, c, z, e, lo, hi, curv):
    """A cell with heights z ± e: its code and observable heights (z NaN: a void)."""
    if np.isnan(z):  # transparent, no answer
        st.out[r, c] = NO_ANSWER
        st.this_lo[c] = lo
        st.this_hi[c] = hi
        return
    z_lo = z - curv - e
    z_hi = z - curv + e
    if z_lo + geo.target >= hi:
        st.out[r, c] = VISIBLE
    elif z_hi + geo.target < lo:
        st.out[r, c] = HIDDEN
    else:
        st.out[r, c] = UNCERTAIN
    st.this_lo[c] = max(z_lo, lo)
    st.this_hi[c] = max(z_hi, hi)


@njit(cache=True, inline="always")
def _tile_col(tiles, c):
    return min((c + tiles.c0) >> tiles.t, tiles.tlast_x) - tiles.tx0


@njit(cache=True, inline="always")
def _reach(geo, r):
    """How many columns either side of the observer's row r reaches within the radius:
    the largest k with (k·mx0)² + ny² ≤ radius² (the test each cell's centre takes;
    monotone in k, so found from an estimate and a step or two); −1 when none."""
    ny2 = geo.ny[r] * geo.ny[r]
    if ny2 > geo.r2max:
        return -1
    mx0 = geo.mx0
    if not mx0 > 0:
        return 1 << 40
    k = int(np.sqrt(geo.r2max - ny2) / mx0)
    while k > 0 and (k * mx0) * (k * mx0) + ny2 > geo.r2max:
        k -= 1
    while ((k + 1) * mx0) * ((k + 1) * mx0) + ny2 <= geo.r2max:
        k += 1
    return k


@njit(cache=True, inline="always")
def _run(tiles, ty, c, side, ncol):
    """The run of columns in one tile that column c begins, going ``side`` (−1 west, +1
    east): its tile column, status, block, box top and error, the column's offset into
    the block and the column just past the run."""
    t, c0, tx0, tlast = tiles.t, tiles.c0, tiles.tx0, tiles.tlast_x
    tx = min((c + c0) >> t, tlast) - tx0
    edge = (tx + tx0) << t  # the run's first grid column
    stop = (edge - c0 - 1) if side < 0 else (edge + (1 << t) - c0)
    if (tx + tx0) == tlast and side > 0:
        stop = ncol
    return (tx, tiles.status[ty, tx], tiles.slot[ty, tx], tiles.ztop[ty, tx],
            tiles.zerr[ty, tx], c0 - edge, stop)


@njit(cache=True, inline="always")
def _cell(s, zc, top, e, lo, hi, curv, target, lift):
    """A cell of a tile of status s (its height zc where s is 1 or 3): its code (−1: the
    tile must be read) and observable heights, given its sight lines lo, hi."""
    if s == 1:
        if np.isnan(zc):  # transparent, no answer
            return NO_ANSWER, lo, hi
        z_lo = zc - curv - e
        z_hi = zc - curv + e
        if z_lo + target >= hi:
            code = VISIBLE
        elif z_hi + target < lo:
            code = HIDDEN
        else:
            code = UNCERTAIN
        return code, max(z_lo, lo), max(z_hi, hi)
    if s == 2:  # no data in the tile
        return NO_ANSWER, lo, hi
    if (zc if s == 3 else top) - curv + lift < lo:
        # the cell's bound (its tile's box, or the coarser level's surface plus that
        # level's error) is below every sight line: hidden
        return HIDDEN, lo, hi
    return -1, lo, hi


@njit(cache=True, nogil=True)
def _sides(geo, tiles, st, r):
    """Cells of row r outward on both sides of the observer's column, from the columns
    ``st.resume[1]`` (west) and ``st.resume[2]`` (east) to the radius or the window's
    edge, each cell from its neighbours toward the observer. The two sides are
    independent chains (a cell waits on its neighbour's division), stepped together so
    that the processor overlaps them, a west cell then an east one, in stretches where
    neither side leaves its tile (each side's state in registers). Returns a tile to
    decode (the resume columns then say where each side stands) or NEED_NONE when the
    row is done."""
    z = tiles.z
    out, this_lo, this_hi, last_lo, last_hi = st.out[r], st.this_lo, st.this_hi, \
        st.last_lo, st.last_hi
    oc, kcurv, target = geo.ocol, geo.kcurv, geo.target
    eye_lo, eye_hi, mode, two = geo.eye_lo, geo.eye_hi, geo.mode, geo.two
    t, tlast = tiles.t, tiles.tlast_y
    ncol = out.shape[0]
    j = abs(r - geo.orow)
    ny2 = geo.ny[r] * geo.ny[r]
    mxr2 = geo.mx[r] * geo.mx[r]
    ty = min((r + tiles.r0) >> t, tlast) - tiles.ty0
    zr = r + tiles.r0 - ((ty + tiles.ty0) << t)  # the row in its tiles' blocks
    lift = geo.eps + max(target, 0.0)
    # the columns within the radius (and the window)
    reach = _reach(geo, r)
    first_c, last_c = max(oc - reach, 0), min(oc + reach, ncol - 1)
    cw, ce = st.resume[1], st.resume[2]
    on_w = first_c <= cw <= last_c
    on_e = first_c <= ce <= last_c
    # each side's run of columns in one tile: tile column, status, block, box top,
    # error, column offset into the block, the column past it; its last cell's
    # observable heights
    tx_w = s_w = b_w = zc_w = tx_e = s_e = b_e = zc_e = 0
    top_w = e_w = top_e = e_e = 0.0
    stop_w, stop_e = cw, ce  # a new run at the first cell
    plo_w = phi_w = plo_e = phi_e = 0.0
    if on_w:
        plo_w, phi_w = this_lo[cw + 1], this_hi[cw + 1]
    if on_e:
        plo_e, phi_e = this_lo[ce - 1], this_hi[ce - 1]
    need = NEED_NONE
    while on_w or on_e:
        nw = ne = 0
        if on_w:
            if cw == stop_w:
                tx_w, s_w, b_w, top_w, e_w, zc_w, stop_w = _run(tiles, ty, cw, -1, ncol)
            nw = cw - max(stop_w, first_c - 1)
        if on_e:
            if ce == stop_e:
                tx_e, s_e, b_e, top_e, e_e, zc_e, stop_e = _run(tiles, ty, ce, 1, ncol)
            ne = min(stop_e, last_c + 1) - ce
        k = min(nw, ne) if on_w and on_e else max(nw, ne)
        for _ in range(k):
            if on_w:
                c = cw
                dc = c - oc
                i = -dc
                if j == 0:
                    lo = line_height(i, plo_w, eye_hi)
                    hi = line_height(i, phi_w, eye_lo) if two else lo
                else:
                    lo = _los(mode, i, j, plo_w, last_lo[c], last_lo[c + 1], eye_hi)
                    hi = _los(mode, i, j, phi_w, last_hi[c], last_hi[c + 1], eye_lo) \
                        if two else lo
                curv = kcurv * (dc * dc * mxr2 + ny2)
                zc = z[b_w, zr, c + zc_w] if s_w & 1 else 0.0
                code, nlo, nhi = _cell(s_w, zc, top_w, e_w, lo, hi, curv, target, lift)
                if code < 0:
                    need = (ty << 16) | tx_w
                    st.probe[0], st.probe[1], st.probe[2], st.probe[3] = c, lo, curv, lift
                    break
                out[c] = code
                this_lo[c] = nlo
                this_hi[c] = nhi
                plo_w, phi_w = nlo, nhi
                cw = c - 1
            if on_e:
                c = ce
                dc = c - oc
                i = dc
                if j == 0:
                    lo = line_height(i, plo_e, eye_hi)
                    hi = line_height(i, phi_e, eye_lo) if two else lo
                else:
                    lo = _los(mode, i, j, plo_e, last_lo[c], last_lo[c - 1], eye_hi)
                    hi = _los(mode, i, j, phi_e, last_hi[c], last_hi[c - 1], eye_lo) \
                        if two else lo
                curv = kcurv * (dc * dc * mxr2 + ny2)
                zc = z[b_e, zr, c + zc_e] if s_e & 1 else 0.0
                code, nlo, nhi = _cell(s_e, zc, top_e, e_e, lo, hi, curv, target, lift)
                if code < 0:
                    need = (ty << 16) | tx_e
                    st.probe[0], st.probe[1], st.probe[2], st.probe[3] = c, lo, curv, lift
                    break
                out[c] = code
                this_lo[c] = nlo
                this_hi[c] = nhi
                plo_e, phi_e = nlo, nhi
                ce = c + 1
        if need != NEED_NONE:
            break
        on_w = on_w and cw >= first_c
        on_e = on_e and ce <= last_c
    st.resume[1], st.resume[2] = cw, ce
    return need


@njit(cache=True, nogil=True)
def _centre(geo, tiles, st, r):
    """The observer's column in row r (or, in the observer's row, the observer and its
    two neighbours). Returns a tile to decode, or NEED_NONE; −2 when out of range."""
    oc, ncol = geo.ocol, st.out.shape[1]
    ty = min((r + tiles.r0) >> tiles.t, tiles.tlast_y) - tiles.ty0
    j = abs(r - geo.orow)
    ny2 = geo.ny[r] * geo.ny[r]
    if j == 0:
        for c in (oc - 1, oc + 1):  # seen, as they are: their heights are read
            if 0 <= c < ncol and tiles.status[ty, _tile_col(tiles, c)] in (0, 3):
                return (ty << 16) | _tile_col(tiles, c)
        z0 = _z(tiles, r, oc)
        st.out[r, oc] = VISIBLE
        st.this_lo[oc] = z0 - geo.eps
        st.this_hi[oc] = z0 + geo.eps
        for c in (oc - 1, oc + 1):
            if not 0 <= c < ncol:
                continue
            d0 = geo.mx0
            dx2 = geo.mx[r] * geo.mx[r]
            tx = _tile_col(tiles, c)
            z = _z(tiles, r, c) if tiles.status[ty, tx] == 1 else np.nan
            if np.isnan(z):
                st.out[r, c] = NO_ANSWER
                st.this_lo[c] = -np.inf
                st.this_hi[c] = -np.inf
            else:
                st.out[r, c] = VISIBLE if d0 * d0 <= geo.r2max else NO_ANSWER
                st.this_lo[c] = z - geo.kcurv * dx2 - tiles.zerr[ty, tx]
                st.this_hi[c] = z - geo.kcurv * dx2 + tiles.zerr[ty, tx]
        return NEED_NONE
    if ny2 > geo.r2max:
        return -2
    tx = _tile_col(tiles, oc)
    s = tiles.status[ty, tx]
    lo = line_height(j, st.last_lo[oc], geo.eye_hi)
    hi = line_height(j, st.last_hi[oc], geo.eye_lo) if geo.two else lo
    curv = geo.kcurv * ny2
    if s == 1:
        _decide(geo, st, r, oc, _z(tiles, r, oc), tiles.zerr[ty, tx], lo, hi, curv)
    elif s == 2:
        st.out[r, oc] = NO_ANSWER
        st.this_lo[oc] = lo
        st.this_hi[oc] = hi
    elif (_z(tiles, r, oc) if s == 3 else tiles.ztop[ty, tx]) - curv + geo.eps \
            + max(geo.target, 0.0) < lo:
        st.out[r, oc] = HIDDEN
        st.this_lo[oc] = lo
        st.this_hi[oc] = hi
    else:
        return (ty << 16) | tx
    return NEED_NONE


@njit(cache=True, nogil=True)
def count_codes(codes):
    """How many cells of ``codes`` (2-D, uint8) are hidden, visible, uncertain and without
    an answer, in one pass.

    Examples
    --------
    >>> count_codes(np.array([[0, 1, 1], [255, 254, 254]], np.uint8))
    (1, 2, 1, 2)
    """
    n0 = n1 = n255 = n254 = 0
    for i in range(codes.shape[0]):
        row = codes[i]
        for k in range(row.shape[0]):
            x = row[k]
            n0 += x == HIDDEN
            n1 += x == VISIBLE
            n255 += x == UNCERTAIN
            n254 += x == NO_ANSWER
    return n0, n1, n255, n254


@njit(cache=True, nogil=True)
def sweep_rows(geo, tiles, st, first, stop, step):
    """Sweep rows ``first``, ``first + step``, … up to ``stop`` (excluded) outward from the
    observer (``first`` equal to its row sweeps that row alone). Returns (row, tile) when
    a tile must be decoded (call again from that row: ``st.resume`` says where the row
    goes on, so no cell is computed twice), or (stop, NEED_NONE) when done."""
    r = first
    while r != stop:
        j = abs(r - geo.orow)
        if st.resume[0] == 0:
            need = _centre(geo, tiles, st, r)
            if need == -2:  # the row is beyond the radius, and so are those after it
                return stop, NEED_NONE
            if need != NEED_NONE:
                return r, need
            d = 2 if j == 0 else 1
            st.resume[0], st.resume[1], st.resume[2] = 1, geo.ocol - d, geo.ocol + d
        need = _sides(geo, tiles, st, r)
        if need != NEED_NONE:
            return r, need
        st.resume[0] = 0
        # the next row (farther out) reads only within this row's reach
        k = _reach(geo, r) + 1
        a, b = max(geo.ocol - k, 0), min(geo.ocol + k, st.out.shape[1] - 1) + 1
        st.last_lo[a:b] = st.this_lo[a:b]
        if geo.two:
            st.last_hi[a:b] = st.this_hi[a:b]
        if j == 0:
            return stop, NEED_NONE
        r += step
    return stop, NEED_NONE

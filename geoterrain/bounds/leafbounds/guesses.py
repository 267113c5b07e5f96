"""Guesses from a tile's heights that a store keeps its codes as differences from: a
geographic level-0 r's cell centres (:func:`centre_guess`, flag ``CENTRES`` with
``PRED``), a geographic r above level 0 (:func:`mids_residuals`, :func:`mids_codes`: flags
``MIDS`` and ``PRED``), and ``Terrain``'s readers of those blobs and of the δ guesses of
:mod:`geoterrain.bounds.ownguess` (:func:`tile_own_codes`, :func:`tile_edge_own_codes`).
IEEE products, sums and square roots only, so a writer and any reader guess the same bits."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.leafbounds.closedforms import _table
from geoterrain.bounds.log8codes import log8_table, new_mask  # noqa: F401 (the doctests')
from geoterrain.bounds.ownguess import edge_own_codes, own_codes
from geoterrain.bounds.radii import code_up_nb
from geoterrain.core.limits import BOX_STEP
from geoterrain.core.threads import cores_for, parallel_kernel

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["CentreHeights", "centre_guess", "mids_codes", "mids_residuals", "tile_centre_guess",
           "tile_edge_own_codes", "tile_mids_codes", "tile_own_codes"]


class CentreHeights(NamedTuple):
    """What a writer predicts a geographic level-0 r's cell centres from
    (:func:`centre_guess`; flag ``CENTRES`` with ``PRED``): the scene heights ``z``
    (float64) and mask ``valid`` (uint8) of the lattice the codes are indexed in,
    the store's ``stand_in`` height for invalid samples, and each tile's scene box
    ``boxes`` (k, 4: xmin, xmax, ymin, ymax, the tile table's numbers) in the order of
    the tiles given."""

    z: np.ndarray
    valid: np.ndarray
    stand_in: float
    boxes: np.ndarray


@njit(cache=True, nogil=True)
def _zp(z, valid, stand_in, i, j):
    # a sample's height, the stand-in where it is not valid (radii._proxy_positions)
    return z[i, j] if valid[i, j] else stand_in


@njit(cache=True, nogil=True)
def _centre_guess_nb(z, valid, stand_in, rows, cols, sx, sy, T, table, out):
    # IEEE basic operations only (products, sums, sqrt: no hypot, no pyproj), so a
    # writer and any reader get the same codes bit for bit
    h = (T - 1) // 2
    for k in range(rows.shape[0]):
        sxx = sx[k] * sx[k]
        syy = sy[k] * sy[k]
        for a in range(h):
            ci = rows[k] + 2 * a + 1
            for b in range(h):
                cj = cols[k] + 2 * b + 1
                zc = _zp(z, valid, stand_in, ci, cj)
                d1 = _zp(z, valid, stand_in, ci - 1, cj) - zc
                d2 = _zp(z, valid, stand_in, ci + 1, cj) - zc
                d3 = _zp(z, valid, stand_in, ci, cj - 1) - zc
                d4 = _zp(z, valid, stand_in, ci, cj + 1) - zc
                m = max(math.sqrt(syy + d1 * d1), math.sqrt(syy + d2 * d2),
                        math.sqrt(sxx + d3 * d3), math.sqrt(sxx + d4 * d4))
                out[k, a, b] = code_up_nb(table, m)


def centre_guess(c: CentreHeights, origins: np.ndarray, T: int, e: int) -> np.ndarray:
    """The predicted log8 codes (k, h, h) uint8, h = (T − 1) / 2, of the cell centres of
    the level-0 tiles whose first samples sit at ``origins`` (k, 2: row, column) of
    ``c``'s lattice: each centre's code (from ``2^e``) of the largest distance to its four
    edge midpoints, √(s² + Δz²), s the tile's sample spacing across the cell's edge
    (its box's width or height over T − 1, the box rounded outward to ``BOX_STEP`` as the
    tile table stores it, so a writer's exact box and a reader's stored one agree) and
    Δz from the heights. A geographic store's
    level-0 r is that nesting (seed 002 §2.4, L50–52: the midpoints are leaves) raised by
    curvilinear terms far below a code step, so the guess is mostly the stored code, and
    a ``CENTRES`` ``PRED`` payload holds (guess − code) mod 256: a wrong guess costs
    bytes, never exactness.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 3.0
    >>> c = CentreHeights(z, np.ones((3, 3), np.uint8), 0.0, np.array([[0.0, 8.0, 0, 8]]))
    >>> g = centre_guess(c, np.zeros((1, 2), np.int64), 3, 0)
    >>> float(log8_table(0)[g[0, 0, 0]]) >= 5.0  # √(4² + 3²)
    True
    """
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    # the box as the tile table stores it (rounded outward to BOX_STEP; idempotent), so
    # a writer's exact box and a reader's stored one give the same spacing
    sx, sy = _spacings(c.boxes, T)
    h = (T - 1) // 2
    out = np.zeros((len(o), h, h), np.uint8)
    _centre_guess_nb(np.asarray(c.z, np.float64), np.asarray(c.valid, np.uint8),
                     float(c.stand_in), np.ascontiguousarray(o[:, 0]),
                     np.ascontiguousarray(o[:, 1]), sx, sy, T, _table(e), out)
    return out


def tile_centre_guess(terrain: TerrainLike, key: tuple[int, int, int], e: int) -> np.ndarray:
    """A level-0 tile's :func:`centre_guess` (h, h) from its decoded heights and its
    tile-table box (``Terrain``'s reader of a ``CENTRES`` ``PRED`` r blob)."""
    return centre_guess(_tile_heights(terrain, key), np.zeros((1, 2), np.int64),
                        terrain.grid.tile_samples, e)[0]


def _tile_heights(terrain: TerrainLike, key: tuple[int, int, int]) -> CentreHeights:
    # one stored tile's decoded scene heights, mask, the stand-in height and its
    # tile-table box: what a reader's guesses from the heights start from
    tile = terrain.tile(*key)
    z = terrain.frame.z(tile.heights)
    ok = (np.asarray(tile.valid, bool) & np.isfinite(z)).view(np.uint8)
    info = terrain.tile_info[key]
    box = np.array([[info[k] if info[k] is not None else np.nan
                     for k in ("xmin", "xmax", "ymin", "ymax")]], np.float64)
    return CentreHeights(z, ok, float(terrain.stand_in_z), box)


def _spacings(boxes: np.ndarray, T: int) -> tuple[np.ndarray, np.ndarray]:
    # each tile's sample spacing (x, y) from its scene box (k, 4), the box rounded outward
    # to BOX_STEP as the tile table stores it (idempotent), so a writer's exact box and a
    # reader's stored one give the same spacing bit for bit; 0 where not finite
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    lo, hi = np.floor(b[:, 0::2] / BOX_STEP), np.ceil(b[:, 1::2] / BOX_STEP)
    with np.errstate(invalid="ignore"):
        sx = (hi[:, 0] - lo[:, 0]) * BOX_STEP / (T - 1)
        sy = (hi[:, 1] - lo[:, 1]) * BOX_STEP / (T - 1)
    return np.where(np.isfinite(sx), sx, 0.0), np.where(np.isfinite(sy), sy, 0.0)


@njit(cache=True, nogil=True, inline="always")
def _zq(z, valid, stand_in, r0, c0, T, i, j, zc):
    # tile sample (i, j)'s height (the stand-in where invalid); ``zc`` outside the tile
    # and at its four corners: a streamed writer's lattice holds no height for the grid's
    # coarsest vertices (the root tiles' corners), which are tile corners at every level
    if i < 0 or j < 0 or i >= T or j >= T or ((i == 0 or i == T - 1) and (j == 0 or j == T - 1)):
        return zc
    return z[r0 + i, c0 + j] if valid[r0 + i, c0 + j] else stand_in


@njit(cache=True, nogil=True, inline="always")
def _mid_base(z, valid, stand_in, r0, c0, T, i, j, sxx, syy):
    # an edge midpoint's largest distance √(s² + Δz²) to its four neighbours in the tile
    # (its diamond's corners: the edge's ends and the cell centres beside it)
    zc = z[r0 + i, c0 + j] if valid[r0 + i, c0 + j] else stand_in
    d1 = _zq(z, valid, stand_in, r0, c0, T, i - 1, j, zc) - zc
    d2 = _zq(z, valid, stand_in, r0, c0, T, i + 1, j, zc) - zc
    d3 = _zq(z, valid, stand_in, r0, c0, T, i, j - 1, zc) - zc
    d4 = _zq(z, valid, stand_in, r0, c0, T, i, j + 1, zc) - zc
    return max(math.sqrt(syy + d1 * d1), math.sqrt(syy + d2 * d2),
               math.sqrt(sxx + d3 * d3), math.sqrt(sxx + d4 * d4))


@njit(cache=True, nogil=True)
def _mids_pred_nb(z, valid, stand_in, origins, sx, sy, T, table, a_off, codes, res, encode):
    # IEEE basic operations only (products, sums, sqrt), so a writer and any reader get
    # the same guesses bit for bit. Each tile: the edge midpoints first (raster order),
    # guess code_up(base + a · min(sx, sy) / 16) + off; then the cell centres, guess the
    # nesting over their four decoded midpoints (seed 002 §2.4, L50–52). ``origins``:
    # each tile's first sample (row, column); ``a_off``: its header bytes a and off
    for k in range(origins.shape[0]):
        r0, c0 = origins[k, 0], origins[k, 1]
        sxx = sx[k] * sx[k]
        syy = sy[k] * sy[k]
        add = np.float64(a_off[k, 0]) * (min(sx[k], sy[k]) * 0.0625)
        m = 0
        for i in range(T):
            for j in range(1 - (i & 1), T, 2):  # one odd coordinate: an edge midpoint
                g = (code_up_nb(table, _mid_base(z, valid, stand_in, r0, c0, T, i, j, sxx,
                                                 syy) + add) + a_off[k, 1]) & 255
                if encode:
                    res[k, m] = (g - codes[k, i, j]) & 255
                else:
                    codes[k, i, j] = (g - res[k, m]) & 255
                m += 1
        for ci in range(1, T - 1, 2):
            for cj in range(1, T - 1, 2):
                zc = _zp(z, valid, stand_in, r0 + ci, c0 + cj)
                best = 0.0
                for q in range(4):
                    mi = ci + (-1 if q == 0 else 1 if q == 1 else 0)
                    mj = cj + (-1 if q == 2 else 1 if q == 3 else 0)
                    d = _zp(z, valid, stand_in, r0 + mi, c0 + mj) - zc
                    v = math.sqrt((syy if q < 2 else sxx) + d * d) + table[codes[k, mi, mj]]
                    best = max(best, v)
                g = code_up_nb(table, best)
                if encode:
                    res[k, m] = (g - codes[k, ci, cj]) & 255
                else:
                    codes[k, ci, cj] = (g - res[k, m]) & 255
                m += 1


@njit(cache=True, nogil=True)
def _alpha_score(base, cm, add, table, hist):
    # Σ n log n of the counts of (code − guess) mod 256 at one a (larger: fewer bits of
    # order-0 entropy), and the commonest difference
    hist[:] = 0
    for q in range(base.shape[0]):
        hist[(cm[q] - code_up_nb(table, base[q] + add)) & 255] += 1
    score = 0.0
    top = 0
    for b in range(256):
        c = hist[b]
        if c > 1:
            score += c * math.log(c)
        if c > hist[top]:
            top = b
    return score, top


@parallel_kernel(cache=True, nogil=True)
def _mids_alpha_nb(z, valid, stand_in, rows, cols, sx, sy, T, table, codes, a_out, off_out):
    # each tile's a (0 … 63) whose midpoint guesses leave the fewest bits of order-0
    # entropy, searched coarse to fine (every 8th, then ±4, ±2, ±1 around the best), and
    # the commonest difference (the offset that makes it 0); tiles on every core, each
    # its own scratch, so the choice does not depend on the cores
    h = (T - 1) // 2
    nm = T * T - (h + 1) * (h + 1) - h * h  # the edge midpoints
    for k in prange(rows.shape[0]):
        r0, c0 = rows[k], cols[k]
        sxx = sx[k] * sx[k]
        syy = sy[k] * sy[k]
        step = min(sx[k], sy[k]) * 0.0625
        base = np.empty(nm)
        cm = np.empty(nm, np.int64)
        hist = np.zeros(256, np.int64)
        m = 0
        for i in range(T):
            for j in range(1 - (i & 1), T, 2):
                base[m] = _mid_base(z, valid, stand_in, r0, c0, T, i, j, sxx, syy)
                cm[m] = codes[k, i, j]
                m += 1
        best, best_a, best_off = -1.0, 0, 0
        for a in range(0, 64, 8):
            score, top = _alpha_score(base, cm, np.float64(a) * step, table, hist)
            if score > best:
                best, best_a, best_off = score, a, top
        for d in (4, 2, 1):
            centre = best_a
            for a in (centre - d, centre + d):
                if 0 <= a < 64:
                    score, top = _alpha_score(base, cm, np.float64(a) * step, table, hist)
                    if score > best:
                        best, best_a, best_off = score, a, top
        a_out[k] = best_a
        off_out[k] = best_off


def mids_residuals(c: CentreHeights, origins: np.ndarray, T: int, e: int,
                   codes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A geographic store's r above level 0 as differences from guesses from the heights
    (flags ``MIDS`` and ``PRED``, schema 20): for tiles whose first samples sit at
    ``origins`` (k, 2: row, column) of ``c``'s lattice (the tiles' level) and their log8
    codes ``codes`` (k, T, T, from ``2^e``), returns each tile's payload (k, 3h² + 2h)
    uint8, h = (T − 1) / 2, and its two header bytes ``a``, ``off`` (k,).

    An edge midpoint's descendants fill its diamond, so its nested radius grows with the
    largest distance √(s² + Δz²) to the diamond's corners (the tile's neighbours of it; s
    the tile's spacing from its box as :func:`centre_guess` takes it; a neighbour outside
    the tile or at its corner counts Δz = 0): its guess is the code of that distance plus
    a · min(sx, sy) / 16, plus ``off`` codes (a, 0 … 63, and off chosen per tile: the
    least order-0 entropy of the differences, searched coarse to fine). A cell centre's
    children are its four edge midpoints, in the tile: its guess is the code of the
    nesting max √(s² + Δz²) + r(m) over their decoded codes, which the stored r exceeds
    only by the curvilinear terms (seed 002 §2.4). The payload holds (guess − code) mod
    256, midpoints first, then centres, each in raster order: a wrong guess costs bytes,
    never exactness (:func:`mids_codes` inverts it).

    Examples
    --------
    >>> T = 5; z = np.arange(T * T, dtype=float).reshape(T, T)
    >>> c = CentreHeights(z, np.ones((T, T), np.uint8), 0.0, np.array([[0.0, 4.0, 0, 4]]))
    >>> codes = np.random.default_rng(0).integers(0, 256, (1, T, T)).astype(np.uint8)
    >>> res, a, off = mids_residuals(c, np.zeros((1, 2), np.int64), T, 0, codes)
    >>> back = mids_codes(c, np.zeros(2, np.int64), T, 0, int(a[0]), int(off[0]), res[0])
    >>> bool((back[new_mask(T)] == codes[0][new_mask(T)]).all())
    True
    """
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    sx, sy = _spacings(c.boxes, T)
    w = np.array(codes, np.uint8).reshape(len(o), T, T)  # writable: one kernel both ways
    a = np.zeros(len(o), np.int64)
    off = np.zeros(len(o), np.int64)
    z, v = np.asarray(c.z, np.float64), np.asarray(c.valid, np.uint8)
    rows, cols = np.ascontiguousarray(o[:, 0]), np.ascontiguousarray(o[:, 1])
    table = _table(e)
    with cores_for(w.size):
        _mids_alpha_nb(z, v, float(c.stand_in), rows, cols, sx, sy, T, table, w, a, off)
    h = (T - 1) // 2
    res = np.zeros((len(o), 3 * h * h + 2 * h), np.uint8)
    _mids_pred_nb(z, v, float(c.stand_in), o, sx, sy, T, table, np.stack([a, off], axis=1),
                  w, res, True)
    return res, a.astype(np.uint8), off.astype(np.uint8)


def mids_codes(c: CentreHeights, origin: np.ndarray, T: int, e: int, a: int, off: int,
               res: np.ndarray) -> np.ndarray:
    """The log8 codes (T, T) uint8 of one tile's new vertices from its ``MIDS`` ``PRED``
    payload ``res`` and header bytes ``a``, ``off`` (:func:`mids_residuals`; the parent's
    vertices, even row and column, are 0: the caller takes them from the parent)."""
    o = np.asarray(origin, np.int64).reshape(1, 2)
    sx, sy = _spacings(c.boxes, T)
    h = (T - 1) // 2
    r = np.array(res, np.uint8).reshape(1, 3 * h * h + 2 * h)  # writable: one kernel
    codes = np.zeros((1, T, T), np.uint8)
    _mids_pred_nb(np.asarray(c.z, np.float64), np.asarray(c.valid, np.uint8),
                  float(c.stand_in), o, sx, sy, T, _table(e),
                  np.array([[a, off]], np.int64), codes, r, False)
    return codes[0]


def tile_mids_codes(terrain: TerrainLike, key: tuple[int, int, int], e: int, a: int,
                    off: int, res: np.ndarray) -> np.ndarray:
    """A tile's :func:`mids_codes` from its decoded heights and its tile-table box
    (``Terrain``'s reader of a ``MIDS`` ``PRED`` r blob: a geographic store's r above
    level 0)."""
    return mids_codes(_tile_heights(terrain, key), np.zeros(2, np.int64),
                      terrain.grid.tile_samples, e, a, off, res)


def tile_own_codes(terrain: TerrainLike, key: tuple[int, int, int], e: int,
                   ring: bool = False, step: int = 1) -> np.ndarray:
    """A tile's :func:`geoterrain.bounds.ownguess.own_codes` (T, T) from its decoded
    heights, invalid samples by the store's stand-in height (``Terrain``'s reader of a
    schema-20 δ blob: ``PRED`` with ``SLACK``, ``RING`` with ``PRED``; ``ring``: the
    border's new vertices only, 0 elsewhere; ``step``: of the tile's samples ``step``
    apart, a whole tile's level inside it, schema 23's top δ)."""
    tile = terrain.tile(*key)
    z = terrain.frame.z(tile.heights)
    ok = np.asarray(tile.valid, bool) & np.isfinite(z)
    s = np.s_[::step, ::step]
    return own_codes(np.ascontiguousarray(z[s]), np.ascontiguousarray(ok[s]),
                     float(terrain.stand_in_z), e, ring=ring)[0]


def tile_edge_own_codes(terrain: TerrainLike, key: tuple[int, int, int], e: int,
                        step: int = 1) -> np.ndarray | None:
    """A level-0 tile's guess of its δ_edge codes (T, T) from its decoded heights, the
    padding replicated from the data's edge
    (:func:`geoterrain.bounds.ownguess.edge_own_codes`; ``Terrain``'s reader of a
    schema-23 ``DIFF`` blob with ``PRED``; ``step``: of the tile's samples ``step``
    apart, a whole tile's level inside it)."""
    tile = terrain.tile(*key)
    z = terrain.frame.z(tile.heights)
    ok = np.asarray(tile.valid, bool) & np.isfinite(z)
    g, (L, x, y) = terrain.grid, key
    r0, c0 = y << (g.t + L), x << (g.t + L)  # the tile's first sample, at steps 2^L
    s = np.s_[::step, ::step]
    return edge_own_codes(np.ascontiguousarray(z[s]), np.ascontiguousarray(ok[s]),
                          float(terrain.stand_in_z), e, ((g.rows - 1 - r0) >> L) // step + 1,
                          ((g.cols - 1 - c0) >> L) // step + 1)

"""A level-0 tile's δ, r and normals, derived on read from the tile's decoded heights.

(:func:`tile_leaf_bounds` is what ``Terrain`` calls for a ring blob of δ or r; for one of
normals it derives the rest with :func:`geoterrain.bounds.normals.derived_codes` from the
x, y of :func:`normal_xy`.)

Below the top level a tile stores only the vertices new at its level (the others are
its parent's, :mod:`geoterrain.bounds.vertexdata`). At level 0 those are the samples with an
odd row or column: the bintree's finest vertices, of half-span h = 1 (seed 002 §2.3):

- a block centre (odd row and column): its diamond is its own closed 2 × 2 cell, so its
  exact δ (:func:`geoterrain.bounds.delta.vertex_errors`) is the h = 1 closed form over those
  9 samples, saturated with its 4 edge midpoints (§2.4, L46: they are its children and
  have none), and its sphere radius is the largest distance to them (L50–52: they are
  leaves, r = 0);
- an edge midpoint: a leaf (r = 0); its diamond is the two cells beside it, both inside
  the tile unless it lies on the tile's border.

So every new vertex's δ and r is a function of the tile's own samples, except the δ of
the edge midpoints on the border ring, whose second cell lies in the next tile (its
validity decides between the closed form, a partial sweep and +inf). A store keeps only
those ring values (:data:`geoterrain.bounds.vertexdata.RING`); a reader rebuilds the rest here,
with the same arithmetic as the whole-grid kernels (the same compiled helpers, no fast
math), and codes them as the preprocess codes them, so it decodes the same values.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import _centre1, _edge_err, _mid1, saturate
from geoterrain.bounds.log8codes import log8_table, new_mask, ring_new_index
from geoterrain.bounds.ownguess import edge_own_codes, own_codes
from geoterrain.bounds.radii import _nest, code_up_nb
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.limits import BOX_STEP
from geoterrain.core.rounding import round_up, round_up32
from geoterrain.core.threads import cores_for, parallel_kernel

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["CentreHeights", "centre_guess", "centre_radius", "geographic_leaf_delta",
           "leaf_delta", "leaf_radius", "mids_codes", "mids_residuals", "normal_axes",
           "normal_xy", "ring_guesses", "tile_centre_guess", "tile_centre_radius",
           "tile_edge_own_codes", "tile_leaf_bounds", "tile_mids_codes", "tile_own_codes",
           "tile_slack"]


class Ring(NamedTuple):
    """A level-0 tile's border ring as stored: the rows, columns and δ of its new
    vertices (what a reader cannot derive from the tile's own samples)."""

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray


_NO_RING = Ring(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32))


@njit(cache=True, nogil=True)
def _status(vb, ci, cj):
    # the closed 2 × 2 cell centred at (ci, cj): bit 1 holds a valid sample, bit 2 an
    # invalid one (bounds._block_status_nb at h = 1)
    f = 0
    for di in range(-1, 2):
        for dj in range(-1, 2):
            f |= 1 if vb[ci + di, cj + dj] else 2
    return f


@njit(cache=True, nogil=True)
def _leaf_delta_nb(z, vb, all_valid, i0, j0, ring, table, slack, sat, code, out):
    # bounds._raw_delta_nb's h = 1 pass on the tile's interior, then its saturation
    # (delta.saturate: centre = max(centre, its 4 edge midpoints), the border's edge
    # midpoints from ``ring``), then the codes' values (the code map is monotone: coding
    # after the max = the max of the codes).
    # ``slack`` (a geographic tile's, else 0: x + 0 is x) is added to every raw value;
    # ``code`` False leaves the values uncoded (the preprocess codes them with the grid);
    # ``sat`` False leaves them raw too (no ring, no saturation)
    rr, rc, rv = ring
    T = z.shape[0]
    for ci in range(1, T - 1, 2):
        for cj in range(1, T - 1, 2):
            f = 1 if all_valid else _status(vb, ci, cj)
            if f == 1:
                out[ci, cj] = round_up32(_centre1(z, ci, cj,
                                                  main_diagonal_nb((i0 + ci) // 2,
                                                                   (j0 + cj) // 2)) + slack)
            elif f == 3:
                out[ci, cj] = np.inf
            else:
                out[ci, cj] = 0.0
    for i in range(1, T - 1):
        for j in range(1 + (i & 1), T - 1, 2):  # (odd, even) and (even, odd), off the ring
            rows = (i & 1) == 1  # hypotenuse along the rows: ends (i ± 1, j)
            if all_valid:
                f = 1
            elif rows:
                f = _status(vb, i, j - 1) | _status(vb, i, j + 1)
            else:
                f = _status(vb, i - 1, j) | _status(vb, i + 1, j)
            v = np.float32(0.0)
            if f == 1:
                v = round_up32(_mid1(z, i, j, rows) + slack)
            elif f != 2:
                # h an int64, not a literal 1: the δ sweep's compilation (delta.py)
                m, c = _edge_err(z, vb, i, j, np.int64(1), rows, T)
                if c == 2:
                    v = np.float32(np.inf)
                elif c == 1:
                    v = round_up32(m + slack)
            out[i, j] = v
    if not sat:
        return
    for k in range(rr.shape[0]):  # the border's edge midpoints, as stored
        out[rr[k], rc[k]] = rv[k]
    for ci in range(1, T - 1, 2):
        for cj in range(1, T - 1, 2):
            out[ci, cj] = max(out[ci, cj], out[ci - 1, cj], out[ci + 1, cj],
                              out[ci, cj - 1], out[ci, cj + 1])
    if not code:
        return
    for i in range(T):
        for j in range(1 - (i & 1), T, 2 - (i & 1)):  # the new vertices
            out[i, j] = table[code_up_nb(table, np.float64(out[i, j]))]


def leaf_delta(z: np.ndarray, valid: np.ndarray, origin: tuple[int, int],
               ring_rows: np.ndarray, ring_cols: np.ndarray, ring_values: np.ndarray,
               e: int | None, slack: float = 0.0) -> np.ndarray:
    """The stored δ (float32) of a level-0 tile's new vertices: saturated exact δ, coded
    as 8-bit log codes from ``2^e`` (:func:`geoterrain.bounds.log8codes.log8_codes`); ``e``
    None: not coded (the preprocess's values before the grid is coded).

    ``slack`` (a geographic tile's, :func:`geographic_leaf_delta`; 0 elsewhere) is added to
    each closed-form value before it is rounded up to float32 and saturated.

    ``z``: the tile's (T, T) scene heights (invalid samples ignored); ``valid``: its
    mask; ``origin``: the (row, column) of its first sample in the full grid (the
    cells' diagonals alternate with the global cell index, seed 002's union jack);
    ``ring_*``: the border's new vertices and their stored δ. The other samples of the
    result (the parent's vertices) are 0. Equal to the code values of
    :func:`~geoterrain.bounds.delta.vertex_errors` of the whole grid there (tested).

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> r, c = np.array([0, 2, 1, 1]), np.array([1, 1, 0, 2])
    >>> float(leaf_delta(z, np.ones((3, 3), bool), (0, 0), r, c, np.zeros(4), -3)[1, 1])
    2.0
    """
    valid = np.asarray(valid, bool) & np.isfinite(z)
    zf = np.where(valid, z, 0.0)  # invalid heights are never read
    out = np.zeros(zf.shape, np.float32)
    ring = Ring(np.asarray(ring_rows, np.int64), np.asarray(ring_cols, np.int64),
                np.asarray(ring_values, np.float32))
    _leaf_delta_nb(zf, valid.view(np.uint8), bool(valid.all()), int(origin[0]), int(origin[1]),
                   ring, _table(0 if e is None else e), float(slack), True, e is not None, out)
    return out


@lru_cache(maxsize=64)
def _table(e: int) -> np.ndarray:
    return log8_table(e).astype(np.float64)


@njit(cache=True, nogil=True)
def _leaf_radius_nb(x, y, z, table, out):
    T = z.shape[0]
    r = np.zeros((T, T), np.float32)  # the edge midpoints: leaves of code 0
    for ci in range(1, T - 1, 2):
        for cj in range(1, T - 1, 2):
            # the log8 code of the nesting over its children (tileblobs.radius_codes)
            out[ci, cj] = table[code_up_nb(table, _nest(x, y, z, r, ci, cj, 1))]


def leaf_radius(x: np.ndarray, y: np.ndarray, z: np.ndarray, valid: np.ndarray,
                stand_in_z: float, e: int) -> np.ndarray:
    """The stored r (float32) of a level-0 tile's new vertices: nested sphere radii coded
    as the preprocess codes them, 8-bit log codes from ``2^e``
    (:func:`geoterrain.bounds.tileblobs.radius_codes`).

    ``x, y, z``: the tile's (T, T) scene positions; invalid heights are replaced by
    ``stand_in_z``, as :func:`geoterrain.bounds.radii.vertex_radii` does. The edge midpoints
    (leaves) and the parent's vertices are 0.

    Examples
    --------
    >>> ii, jj = np.indices((3, 3)).astype(float)
    >>> float(leaf_radius(jj, -ii, np.zeros((3, 3)), np.ones((3, 3), bool), 0.0, 0)[1, 1])
    1.0
    """
    ok = np.asarray(valid, bool) & np.isfinite(z)
    zp = np.where(ok, z, stand_in_z)
    out = np.zeros(zp.shape, np.float32)
    _leaf_radius_nb(np.ascontiguousarray(x, np.float64), np.ascontiguousarray(y, np.float64),
                    zp, _table(e), out)
    return out


@njit(cache=True, nogil=True)
def _centre_radius_nb(x, y, z, mids, table, out):
    T = z.shape[0]
    for ci in range(1, T - 1, 2):
        for cj in range(1, T - 1, 2):
            # a centre's children are its 4 edge midpoints (half-span 1 in the tile's own
            # indices): the code of the nesting over their coded radii, as radius_codes
            out[ci, cj] = table[code_up_nb(table, _nest(x, y, z, mids, ci, cj, 1))]


def centre_radius(x: np.ndarray, y: np.ndarray, z: np.ndarray, valid: np.ndarray,
                  stand_in_z: float, e: int, mids: np.ndarray) -> np.ndarray:
    """The stored r (float32, T × T) of a tile whose cell centres (odd row and column)
    were left out (flag ``MIDS``, :mod:`geoterrain.bounds.vertexdata`): ``mids`` as given
    (the other samples' decoded r), each centre the log8 code from ``2^e`` of the nesting
    over its four edge midpoints, max |p_c − p_m| + r(m), as
    :func:`geoterrain.bounds.tileblobs.radius_codes` codes it on a frame whose r is not
    raised beyond the nesting (projected and pixel). ``x, y, z`` the tile's scene positions,
    invalid heights replaced by ``stand_in_z`` as there.

    Examples
    --------
    >>> ii, jj = np.indices((3, 3)).astype(float)
    >>> m = np.zeros((3, 3), np.float32); m[0, 1] = 1.0
    >>> r = centre_radius(jj, -ii, np.zeros((3, 3)), np.ones((3, 3), bool), 0.0, 0, m)
    >>> float(r[1, 1]) >= 2.0, float(r[0, 1])
    (True, 1.0)
    """
    ok = np.asarray(valid, bool) & np.isfinite(z)
    zp = np.where(ok, z, stand_in_z)
    out = np.array(mids, np.float32)
    _centre_radius_nb(np.ascontiguousarray(x, np.float64), np.ascontiguousarray(y, np.float64),
                      zp, out, _table(e), out)
    return out


def tile_centre_radius(terrain: TerrainLike, key: tuple[int, int, int], mids: np.ndarray,
                       e: int) -> np.ndarray:
    """A ``MIDS`` r blob's values with its cell centres derived from the tile's decoded
    heights and x, y (:func:`centre_radius`; ``Terrain``'s reader of the blob)."""
    if terrain.frame.kind == "geographic":  # r there holds curvilinear terms: never derived
        raise ValueError("a geographic store's r is stored whole")
    tile = terrain.tile(*key)
    X, Y = terrain.tile_xy(*key)
    return centre_radius(X, Y, terrain.frame.z(tile.heights), tile.valid, terrain.stand_in_z,
                         e, mids)


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


# ------------------------------------------------ a store's level-0 tiles, derived on read
def tile_leaf_bounds(terrain: TerrainLike, key: tuple[int, int, int], kind: str, log8: bool, e: int,
                     rows: np.ndarray, cols: np.ndarray, ring: np.ndarray,
                     slack: float = 0.0) -> np.ndarray:
    """The stored δ or r of a level-0 tile's new vertices, derived from its decoded
    heights; the border ring's as stored (``Terrain``'s reader of a ``RING`` blob).
    ``slack``: a geographic tile's δ slack (:func:`geographic_leaf_delta`).

    Examples
    --------
    >>> from geoterrain.bounds.log8codes import ring_new_index
    >>> r, c = ring_new_index(t.grid.tile_samples)
    >>> d = tile_leaf_bounds(t, (0, 0, 0), "delta", True, 0, r, c, np.zeros(len(r)))
    >>> d.shape == (t.grid.tile_samples,) * 2 and bool((d >= 0).all())
    True
    """
    if not log8:  # ring blobs are only ever written in log8 codes
        raise ValueError(f"a ring {kind} blob not in log8 codes")
    tile = terrain.tile(*key)
    z = terrain.frame.z(tile.heights)
    if kind == "delta":
        t = terrain.grid.t
        return leaf_delta(z, tile.valid, (key[2] << t, key[1] << t), rows, cols, ring, e,
                          slack)
    X, Y = terrain.tile_xy(*key)
    r = leaf_radius(X, Y, z, tile.valid, terrain.stand_in_z, e)
    r[rows, cols] = ring
    return r


def geographic_leaf_delta(delta: np.ndarray, z: np.ndarray, valid: np.ndarray, t: int,
                          dm: np.ndarray, bulge: np.ndarray, span: int | None = None
                          ) -> dict[tuple[int, int, int], float] | None:
    """Level-0 δ of a geographic grid as a reader derives it: raised in place, tile by
    tile, then saturated again; the per-tile slack, or None (``delta`` untouched) where
    the closed forms cannot bound a tile.

    On a geographic grid δ also holds the metric term δ_m of :mod:`geoterrain.bounds.curvature`
    (the error measured in the scene's curvilinear x, y), which needs pyproj's x, y of
    every sample. At level 0 that term is tiny (a sample's offset from its index-space
    place on a 1-sample triangle, about 10⁻⁴ m), so each tile stores one number instead
    of its values: the slack s, the largest amount by which δ_m exceeds the index-space
    closed form (seed 002 §2.3) at one of the tile's new vertices off the border ring. A
    reader adds s to each closed form before it rounds up and saturates
    (:func:`leaf_delta`), which gives at least max(closed form, δ_m) at every vertex, so
    at least the grid's saturated δ: still a bound. The border ring's values are stored
    as they are. Since the raised values may exceed ``delta``, the grid is saturated
    again (§2.4, L46), so every parent still bounds its children.

    ``delta``: (N, N) float32, saturated, or a root grid's (R, C) extent with roots of
    side ``span`` (:mod:`geoterrain.bounds.delta`); ``z``: scene heights; ``valid``: the
    mask; ``t``: the tile exponent; ``dm``, ``bulge``:
    :func:`~geoterrain.bounds.curvature.metric_terms`' raw terms. Returns {(0, x, y): s}
    for the tiles with a valid sample.

    Examples
    --------
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> z = np.random.default_rng(0).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> dm = np.zeros((9, 9)); dm[1, 1] = 5.0  # a metric term, say
    >>> d = saturate(np.maximum(vertex_errors(z, v), dm.astype(np.float32)))
    >>> s = geographic_leaf_delta(d, z, v, 2, dm, np.zeros((9, 9), bool))
    >>> 0 < s[(0, 0, 0)] <= 5.0
    True
    """
    T = (1 << t) + 1
    down, across = ((k - 1) >> t for k in delta.shape)
    raised = []
    out: dict[tuple[int, int, int], float] = {}
    for y in range(down):
        for x in range(across):
            sub = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]
            got = tile_slack(delta[sub], z[sub], valid[sub], dm[sub], bulge[sub],
                             (y << t, x << t))
            if got is None:
                return None
            if got is True:
                continue
            s, d = got
            raised.append((sub, d))
            out[(0, x, y)] = s
    inner = _inner(T)
    for sub, d in raised:
        blk = delta[sub]
        blk[inner] = d[inner]
    saturate(delta, span)
    return out


@lru_cache(maxsize=16)
def _inner(T: int) -> np.ndarray:
    # a level-0 tile's new vertices off its border ring
    rr, rc = ring_new_index(T)
    inner = new_mask(T)
    inner[rr, rc] = False  # the ring is stored as it is
    inner.flags.writeable = False
    return inner


def tile_slack(w: np.ndarray, z: np.ndarray, valid: np.ndarray, dm: np.ndarray,
               bulge: np.ndarray, origin: tuple[int, int]
               ) -> tuple[float, np.ndarray] | bool | None:
    """One level-0 tile of :func:`geographic_leaf_delta`: (its slack s, the δ a reader
    derives with it, whose inner new vertices replace ``w``'s), True for a tile without a
    valid sample, or None where the closed forms cannot bound it.

    ``w``, ``z``, ``valid``, ``dm``, ``bulge``: the tile's (T, T) saturated δ, scene
    heights, mask and raw metric terms; ``origin``: its first sample's (row, column).

    Examples
    --------
    >>> T = 5; z = np.arange(25.0).reshape(5, 5) ** 1.5; v = np.ones((5, 5), bool)
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> w = vertex_errors(z, v); dm = np.full((5, 5), 0.5)
    >>> s, d = tile_slack(w, z, v, dm, np.zeros((5, 5), bool), (0, 0))
    >>> s >= 0 and bool((d[_inner(5)] >= w[_inner(5)]).all())
    True
    """
    T = w.shape[0]
    rr, rc = ring_new_index(T)
    inner = _inner(T)
    v = np.asarray(valid, bool) & np.isfinite(z)
    if not v.any():
        return True
    if bulge[inner].any():
        return None  # a border chord that needs refining (no such case known)
    zt = np.where(v, z, 0.0)
    raw = np.zeros((T, T), np.float32)  # the closed forms, unsaturated
    _leaf_delta_nb(zt, v.view(np.uint8), bool(v.all()), origin[0], origin[1], _NO_RING,
                   _table(0), 0.0, False, False, raw)
    fin = inner & np.isfinite(raw)
    s = max(0.0, float((dm[fin] - raw[fin]).max())) if fin.any() else 0.0
    for _ in range(8):  # float32 rounding may leave a value an ulp short
        s = float(round_up(np.array([s]), np.float32)[0])
        d = leaf_delta(zt, v, origin, rr, rc, w[rr, rc], None, s)
        short = d[inner].astype(np.float64) < w[inner]
        if not short.any():
            return s, d
        if np.isinf(w[inner][short]).any():
            return None  # a +inf the closed forms do not give (no such case known)
        s += float((w[inner][short] - d[inner][short]).max()) + 2.0**-40
    return None


def normal_xy(terrain: TerrainLike, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
    """Scene X, Y (T, T) from which a tile's normals are derived on read.

    In a projected or pixel frame, the preprocess's values (:meth:`Frame.axis_xy`, as
    :meth:`Frame.grid_xy`'s), so the derived codes are its codes. In a geographic frame,
    pyproj at ``NORMAL_XY_NODES`` × ``NORMAL_XY_NODES`` nodes of the tile only (every 8
    samples of a 65² tile), bilinear between them: a sample's own pyproj call would cost
    about 2.6 ms a 65² tile, 20× the stored read. The bilinear positions are off by the
    projection's curvature over a node cell, far under a normal code's resolution
    (tested: a code or its neighbour); the border ring, which the preprocess stores
    from the full map, keeps its exact codes. pyproj at the cells' centres checks the
    interpolation: where it strays (a tile next to a pole, where latitudes clamp, or at
    the scene frame's antipode), the tile's own x, y (:meth:`Terrain.tile_xy`), and so
    the full map's codes.

    Examples
    --------
    >>> X, Y = normal_xy(t, 0, 0, 0)
    >>> X.shape == (t.grid.tile_samples,) * 2
    True
    """
    g = terrain.grid
    if terrain.frame.kind != "geographic":
        # the preprocess's grid_xy values as broadcast views: no T² positions to compute
        # for every tile shaded
        T = g.tile_samples
        xs, ys = normal_axes(terrain, level, x, y)
        return np.broadcast_to(xs[None, :], (T, T)), np.broadcast_to(ys[:, None], (T, T))
    T = g.tile_samples
    m = min(T, NORMAL_XY_NODES)  # nodes a side: every (T − 1) / (m − 1) samples
    w = (T - 1) // (m - 1)
    if w == 1:  # a node on every sample: exact
        return terrain.tile_xy(level, x, y)
    k = np.arange(m) * w
    rows, cols = g.tile_rows(level, y), g.tile_cols(level, x)
    # pyproj at the nodes and at the cells' centres, which check the interpolation
    kc = k[:-1] + w // 2
    pick = np.concatenate([k, kc])
    ii, jj = np.meshgrid(rows[pick], cols[pick], indexing="ij")
    px, py = (np.asarray(v, np.float64) for v in terrain.frame.xy(ii, jj))
    cx, cy = px[:m, :m], py[:m, :m]
    X, Y = _bilinear(cx, k, T), _bilinear(cy, k, T)
    # where the frame bends within a cell (next to a pole, where latitudes clamp, or
    # the scene frame's antipode) the bilinear x, y stray: then the tile's own
    step = min(np.hypot(np.diff(cx, axis=1), np.diff(cy, axis=1)).min(),
               np.hypot(np.diff(cx, axis=0), np.diff(cy, axis=0)).min()) / w
    off = max(np.abs(X[np.ix_(kc, kc)] - px[m:, m:]).max(),
              np.abs(Y[np.ix_(kc, kc)] - py[m:, m:]).max())
    if not (np.isfinite(off) and step > 0 and off <= NORMAL_XY_TOLERANCE * w * step):
        return terrain.tile_xy(level, x, y)
    return X, Y


def normal_axes(terrain: TerrainLike, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
    """A projected or pixel frame's :func:`normal_xy` as its two axes: X (T,) of the
    tile's columns and Y (T,) of its rows (:meth:`Frame.axis_xy`'s values), cached by
    tile column and row (a frame's new tiles share them).

    Examples
    --------
    >>> xs, ys = normal_axes(t, 0, 0, 0)
    >>> xs.shape == ys.shape == (t.grid.tile_samples,)
    True
    """
    g, f = terrain.grid, terrain.frame
    xs = terrain.memo(("normal_x", level, x), lambda: f.axis_xy(
        g.tile_rows(level, 0)[:1], g.tile_cols(level, x))[0][0])
    ys = terrain.memo(("normal_y", level, y), lambda: f.axis_xy(
        g.tile_rows(level, y), g.tile_cols(level, 0)[:1])[1][:, 0])
    return xs, ys


class _Layout:
    """What :func:`normal_xy` and :func:`normal_axes` read of a terrain, for a writer
    that has no store yet: the grid, the frame, a tile's x, y and a memo."""

    def __init__(self, grid, frame) -> None:
        self.grid, self.frame = grid, frame
        self._memo: dict = {}

    def memo(self, key, make):
        got = self._memo.get(key)
        if got is None:
            got = self._memo[key] = make()
        return got

    def tile_xy(self, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
        g = self.grid
        ii, jj = np.meshgrid(g.tile_rows(level, y), g.tile_cols(level, x), indexing="ij")
        return self.frame.xy(ii, jj)


def ring_guesses(grid, frame, level: int, tiles: list[tuple[int, int]], z: np.ndarray,
                 valid: np.ndarray, origins: np.ndarray, bits: int = 8,
                 chunk: int = 64) -> np.ndarray:
    """What a reader derives at the border rings of level ``level``'s tiles ``tiles``
    ((x, y) each) before it sets their stored codes (:func:`geoterrain.bounds.normals.ring_guess`
    on the x, y of :func:`normal_xy`, or :func:`normal_axes` on a projected or pixel
    frame): (k, 4T − 4, 2) codes, from the level's scene heights ``z`` and mask ``valid``
    (a window of its lattice; tile k's first sample at ``origins[k]`` = row, column).
    A writer stores each ring as its difference from them (schema 17).

    Examples
    --------
    >>> from geoterrain.core.grid import Grid
    >>> from geoterrain.core.frame import Frame
    >>> g = Grid(5, 5, 2, 2); z = np.arange(25.0).reshape(5, 5)
    >>> ring_guesses(g, Frame.pixel(5, 5, 1.0), 0, [(0, 0)], z, np.ones((5, 5), bool),
    ...              np.zeros((1, 2), np.int64)).shape
    (1, 16, 2)
    """
    from geoterrain.bounds.normalbytes import ring_index
    from geoterrain.bounds.normals import ring_guess

    T = grid.tile_samples
    lay = _Layout(grid, frame)
    ring = ring_index(T)
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    out = np.empty((len(o), len(ring[0]), 2), np.uint8 if bits == 8 else np.uint16)
    if frame.kind != "geographic":  # x by column, y by row: broadcast, no T² copies
        # every tile's axes in one call (normal_axes' values: X of a column and Y of a row
        # are element-wise affine maps, the same bits whatever the array they are in)
        k = len(o)
        txy = np.asarray(tiles, np.int64).reshape(-1, 2)
        idx = np.arange(T)
        cols = ((txy[:, 0, None] << grid.t) + idx) << level
        rows = ((txy[:, 1, None] << grid.t) + idx) << level
        zero = np.zeros(1, np.int64)  # normal_axes' row 0 for X, column 0 for Y
        xs = frame.axis_xy(zero, cols.ravel())[0][0].reshape(-1, T)
        ys = frame.axis_xy(rows.ravel(), zero)[1][:, 0].reshape(-1, T)
        return ring_guess(z, valid, np.broadcast_to(xs[:, None, :], (k, T, T)),
                          np.broadcast_to(ys[:, :, None], (k, T, T)), ring, bits, o)
    for a in range(0, len(o), chunk):
        b = min(a + chunk, len(o))
        X = np.empty((b - a, T, T))
        Y = np.empty((b - a, T, T))
        for k in range(a, b):
            X[k - a], Y[k - a] = normal_xy(lay, level, *tiles[k])
        out[a:b] = ring_guess(z, valid, X, Y, ring, bits, o[a:b])
    return out


NORMAL_XY_NODES = 9  # pyproj nodes a side of a tile for its derived normals' x, y
# a cell centre's bilinear x, y may be off by this × the cell's width in samples × the
# sample spacing: a parabolic bump that size tilts the tangents by under 10⁻³ rad
NORMAL_XY_TOLERANCE = 2e-4


def _bilinear(c: np.ndarray, k: np.ndarray, T: int) -> np.ndarray:
    """(T, T) values bilinear between node values ``c`` (m, m) at sample offsets ``k``."""
    s = np.arange(T)
    cell = np.minimum(np.searchsorted(k, s, side="right") - 1, len(k) - 2)
    f = (s - k[cell]) / (k[cell + 1] - k[cell])
    a, b = cell[:, None], cell[None, :]
    fa, fb = f[:, None], f[None, :]
    top = c[a, b] + (c[a, b + 1] - c[a, b]) * fb
    bot = c[a + 1, b] + (c[a + 1, b + 1] - c[a + 1, b]) * fb
    return top + (bot - top) * fa

"""A level-0 tile's δ and r from its own samples: the h = 1 closed forms of δ (seed 002
§2.3, the same compiled helpers as the whole grid's, :mod:`geoterrain.bounds.delta.sweeps`),
saturated with the border ring as stored (§2.4, L46), and the nested radii of its centres
(L50–52), each coded as the preprocess codes it; :func:`tile_leaf_bounds` is ``Terrain``'s
reader of a ``RING`` blob."""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from geoterrain.bounds.delta import _centre1, _edge_err, _mid1
from geoterrain.bounds.log8codes import log8_table
from geoterrain.bounds.radii import _nest, code_up_nb
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["centre_radius", "leaf_delta", "leaf_radius", "tile_centre_radius",
           "tile_leaf_bounds"]


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
                # h an int64, not a literal 1: the δ sweep's compilation (delta/sweeps.py)
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

"""The bounds' 8-bit logarithmic codes and a tile's vertex index sets.

- :data:`LOG_STEPS`, :func:`log8_table`, :func:`log8_exponent`, :func:`log8_codes`: the
  log8 codes from ``2^e`` (code 0 is 0, code 255 is +inf), ``LOG_STEPS`` per octave,
  rounded *up*, so a coded value is never below the exact one and, with one ``e`` per
  store and kind, saturation survives the code (the ``LOG8`` flag of
  :mod:`geoterrain.bounds.vertexdata`).
- :func:`new_mask`, :func:`ring_new_index`, :func:`mids_index`: which samples of a T × T
  tile a payload holds (the new vertices, the border ring's, all but the cell centres).
- :func:`pred_residuals` / :func:`pred_codes`: schema 14's ``PRED`` payload, each new
  vertex's code as its difference mod 256 from its parents' prediction in the bintree
  (seed 002 §2.3-2.4: a saturated δ and a nested r never exceed a parent's).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from geoterrain.bounds.delta import delta_max_finite
from geoterrain.core.rounding import round_up

LOG_STEPS = 16  # codes per octave: at most 2^(1/16) - 1 = 4.4 % above the exact value


@lru_cache(maxsize=256)
def _log8_table_ro(e: int) -> np.ndarray:
    v = log8_table(e)
    v.flags.writeable = False
    return v


@lru_cache(maxsize=256)
def _log8_table64(e: int) -> np.ndarray:
    v = log8_table(e).astype(np.float64)
    v.flags.writeable = False
    return v


@lru_cache(maxsize=8)
def _new_flat(T: int) -> np.ndarray:
    """Flat indices of :func:`new_mask` (T), in row-major order (read-only, cached)."""
    f = np.flatnonzero(new_mask(T))
    f.flags.writeable = False
    return f


def log8_table(e: int) -> np.ndarray:
    """The 256 float32 values of the 8-bit log codes from ``2^e`` (0, then increasing, +inf).

    Examples
    --------
    >>> v = log8_table(-3)
    >>> float(v[0]), float(v[1]), bool(np.isinf(v[255])), bool((np.diff(v) > 0).all())
    (0.0, 0.125, True, True)
    """
    c = np.arange(1, 255, dtype=np.float64)
    v = np.empty(256, np.float32)
    v[0], v[255] = 0.0, np.inf
    v[1:255] = round_up(np.exp2(e + (c - 1) / LOG_STEPS), np.float32)
    return v


def log8_exponent(a: np.ndarray) -> int:
    """The exponent ``e`` whose top finite code (254) covers the largest finite value.

    Examples
    --------
    >>> log8_exponent(np.array([0.5, np.inf, 3.0, np.nan], np.float32)), log8_exponent(np.zeros(2))
    (-14, 0)
    """
    peak = delta_max_finite(np.ascontiguousarray(a))  # exact: a's own value
    if peak <= 0:
        return 0
    return int(np.clip(np.ceil(np.log2(peak) - 253 / LOG_STEPS), -128, 127))


def log8_codes(a: np.ndarray, e: int) -> np.ndarray:
    """The smallest code whose value is ≥ each value of ``a`` (non-negative, +inf allowed).

    Examples
    --------
    >>> a = np.array([0.0, 1e-9, 0.3, 7.0, np.inf])
    >>> e = log8_exponent(a)
    >>> b = log8_table(e)[log8_codes(a, e)]
    >>> bool((b >= a).all()), bool((b[1:4] <= a[1:4] * 2 ** (1 / 16) + 2.0 ** e).all())
    (True, True)
    """
    table = log8_table(e).astype(np.float64)
    a = np.asarray(a, np.float64)
    a = np.where(np.isnan(a), np.inf, a)  # never a bound smaller than unknown
    # the first table entry ≥ a: monotone in a, so orderings (saturation) survive
    return np.searchsorted(table, a, side="left").astype(np.uint8)


@lru_cache(maxsize=8)
def ring_new_index(T: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the new vertices on a T × T tile's border (an odd column on
    the top and bottom rows, an odd row on the left and right columns; T odd): 2(T − 1)
    samples, the top row, the bottom row, then the left and the right column.

    Examples
    --------
    >>> r, c = ring_new_index(5)
    >>> list(zip(r.tolist(), c.tolist()))
    [(0, 1), (0, 3), (4, 1), (4, 3), (1, 0), (3, 0), (1, 4), (3, 4)]
    """
    odd = np.arange(1, T, 2)
    k = len(odd)
    rows = np.concatenate([np.zeros(k, np.int64), np.full(k, T - 1), odd, odd])
    cols = np.concatenate([odd, odd, np.zeros(k, np.int64), np.full(k, T - 1)])
    rows.flags.writeable = cols.flags.writeable = False
    return rows, cols


def new_mask(T: int) -> np.ndarray:
    """(T, T) True where a sample is new at its level (not on the parent's even grid)."""
    m = np.ones((T, T), bool)
    m[::2, ::2] = False
    return m


@lru_cache(maxsize=8)
def _shape_index(T: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions in a ``NEW_ONLY`` payload (new vertices, raster order) of the cell
    centres and of the other new vertices (read-only, cached)."""
    new = _new_flat(T)
    i, j = np.divmod(new, T)
    centre = (i & 1).astype(bool) & (j & 1).astype(bool)
    c, o = np.flatnonzero(centre), np.flatnonzero(~centre)
    c.flags.writeable = o.flags.writeable = False
    return c, o


@lru_cache(maxsize=8)
def mids_index(T: int, new_only: bool) -> np.ndarray:
    """Flat (T × T) indices of the samples a ``MIDS`` payload keeps, in raster order: every
    sample (of the new vertices if ``new_only``) but the cell centres, odd row and column
    (read-only, cached).

    Examples
    --------
    >>> mids_index(3, True).tolist(), mids_index(3, False).tolist()
    ([1, 3, 5, 7], [0, 1, 2, 3, 5, 6, 7, 8])
    """
    i, j = np.divmod(np.arange(T * T), T)
    keep = ~((i & 1).astype(bool) & (j & 1).astype(bool))
    if new_only:
        keep &= new_mask(T).ravel()
    f = np.flatnonzero(keep)
    f.flags.writeable = False
    return f


@lru_cache(maxsize=8)
def _pred_index(T: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For a T × T tile (T odd ≥ 3), read-only and cached: the flat indices of the new
    vertices that are not cell centres (raster order, as :func:`_shape_index`), for each
    of them the flat indices of the two cell centres beside it (T · T where there is none: a slot
    past the tile that holds 255); and a (h, h) mask of the centres whose cell is split
    along its main diagonal (union-jack parity counted from the tile's first cell)."""
    h = (T - 1) // 2
    i, j = np.divmod(_new_flat(T), T)
    centre = (i & 1).astype(bool) & (j & 1).astype(bool)
    ci, cj = i[~centre], j[~centre]  # the edge midpoints: one odd coordinate
    rows = (ci & 1).astype(bool)  # odd row, even column: centres left and right
    n1 = np.where(rows, ci * T + cj - 1, (ci - 1) * T + cj)
    n2 = np.where(rows, ci * T + cj + 1, (ci + 1) * T + cj)
    n1 = np.where(rows & (cj == 0) | ~rows & (ci == 0), T * T, n1)
    n2 = np.where(rows & (cj == T - 1) | ~rows & (ci == T - 1), T * T, n2)
    main = np.add.outer(np.arange(h), np.arange(h)) % 2 == 0
    out = (_new_flat(T)[~centre], n1, n2, main)
    for a in out:
        a.flags.writeable = False
    return out


def _pred_centres(W: np.ndarray, main: np.ndarray) -> np.ndarray:
    # each cell centre's prediction (k, h, h) from tiles W (k, T, T) int16: the smaller
    # code of the two corners its cell's diagonal does not join (seed 002 §2.3)
    a, b = W[:, 0:-2:2, 0:-2:2], W[:, 0:-2:2, 2::2]
    c, d = W[:, 2::2, 0:-2:2], W[:, 2::2, 2::2]
    return np.where(main, np.minimum(b, c), np.minimum(a, d))


def pred_residuals(W: np.ndarray) -> np.ndarray:
    """The ``PRED`` payloads of tiles ``W`` (k, T, T) of log8 codes (T odd ≥ 3): each new
    vertex's code subtracted from its prediction, mod 256, the cell centres first, then
    the other new vertices (each in raster order). :func:`pred_codes` inverts it.

    Examples
    --------
    >>> W = np.zeros((1, 3, 3), np.uint8); W[0, ::2, ::2] = 9; W[0, 1, 1] = 7
    >>> W[0, 0, 1] = W[0, 1, 0] = W[0, 1, 2] = W[0, 2, 1] = 5
    >>> pred_residuals(W).tolist()
    [[2, 2, 2, 2, 2]]
    """
    W = np.asarray(W, np.int16)
    k, T = W.shape[0], W.shape[1]
    other, n1, n2, main = _pred_index(T)
    rc = _pred_centres(W, main) - W[:, 1::2, 1::2]
    ext = np.concatenate([W.reshape(k, -1), np.full((k, 1), 255, np.int16)], axis=1)
    rm = np.minimum(ext[:, n1], ext[:, n2]) - ext[:, other]
    return (np.concatenate([rc.reshape(k, -1), rm], axis=1) & 0xFF).astype(np.uint8)


def pred_codes(corners: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """A tile's (T, T) log8 codes from its parent's ``corners`` (h + 1, h + 1; the even
    rows and columns) and its ``PRED`` payload (:func:`pred_residuals`, 3h² + 2h bytes).

    Examples
    --------
    >>> W = np.random.default_rng(1).integers(0, 256, (1, 5, 5)).astype(np.uint8)
    >>> bool((pred_codes(W[0, ::2, ::2], pred_residuals(W)[0]) == W[0]).all())
    True
    """
    corners = np.asarray(corners, np.int16)
    h = corners.shape[0] - 1
    T = 2 * h + 1
    other, n1, n2, main = _pred_index(T)
    p = np.asarray(payload, np.int16)
    ext = np.empty(T * T + 1, np.int16)
    W = ext[:-1].reshape(1, T, T)
    W[0, ::2, ::2] = corners
    ext[-1] = 255
    W[0, 1::2, 1::2] = (_pred_centres(W, main)[0] - p[: h * h].reshape(h, h)) & 0xFF
    ext[other] = (np.minimum(ext[n1], ext[n2]) - p[h * h:]) & 0xFF
    return W[0].astype(np.uint8)

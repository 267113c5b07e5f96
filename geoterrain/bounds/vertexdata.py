"""Compact, conservative storage of per-vertex bounds (δ and r) in tile blobs.

Every value is rounded *up*, so a stored δ or r is never smaller than the computed
one: every bound stays a bound (and δ = +inf, the mixed-diamond marker, stays +inf).
Blob version 1 (older stores, still read): version byte, int8 scale exponent, then
float16 times that power of two, byte-shuffled, zstd (at most 2^-10 relative above
the exact value). The preprocess uses one exponent per store and kind, so rounding is
a single monotone map and saturation survives it.

Blob version 2 (:func:`pack_bounds_v2`, issue 12's size levers): version byte, flags,
int8 exponent, then zstd of the samples kept. Flag ``NEW_ONLY``: the samples shared
with the parent tile (every other row and column) are left out and read back from
the parent's decoded values, which are the same vertices' bounds, so decoding is
exact. Flag ``LOG8``: 8-bit logarithmic codes, ``LOG_STEPS`` per octave from
``2^e``, rounded *up* (code 0 is 0, code 255 is +inf): a stored value exceeds the
exact one by less than ``2^(1/LOG_STEPS) - 1`` relative, and with one ``e`` per store
and kind the map is monotone, so saturation survives it. δ is always coded so; r is
too in stores written now, its codes nested again on the coded values
(:func:`geoterrain.bounds.tileblobs.radius_codes`), and as float16 times ``2^e`` (no ``LOG8``)
in stores before. Flag ``RING`` (level 0, with
``NEW_ONLY``): only the new vertices of the tile's border ring are stored
(:func:`ring_new_index`); a reader derives the others from the tile's decoded heights
and codes them as the preprocess did (:mod:`geoterrain.bounds.leafbounds`). Flag ``DIFF`` (log8
only; a stored tile's ``delta_edge``): each code is stored as its difference mod 256
from the same vertex's code in the tile's ``delta`` blob (same ``e``): δ_edge differs
from δ only near the padding, so the payload is mostly zeros. Flag ``SLACK`` (a ``RING``
δ of a geographic tile): a little-endian float32 s ≥ 0 follows the exponent; the reader
adds it to each derived closed form (:func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`).
Flag ``CENTRES`` (schema 6, issue 51; a ``NEW_ONLY`` log8 blob, neither ``RING`` nor
``DIFF``): every new vertex but the cell centres (odd row and column) has code 0, and only
the centres are stored, in raster order (:func:`shape_codes`): a geographic store's level-0
r, whose edge midpoints are leaves of radius 0 (srtm1_japan: 40 % fewer r bytes there).
Flag ``MIDS`` (schema 12, issue 51; log8, neither ``RING``, ``DIFF``, ``SLACK`` nor
``CENTRES``; a projected or pixel store's r above level 0): the cell centres (odd row
and column) are left out of the payload, the other samples kept in raster order
(:func:`mids_index`). A centre's children are its four edge midpoints, in the same tile,
and its code is the nesting over them alone (r is not raised beyond the nesting on these
frames), so a reader derives it from the tile's decoded heights, x, y and the midpoints'
codes, as the preprocess codes it (:func:`geoterrain.bounds.leafbounds.centre_radius`).
Flag ``PRED`` (schema 14, issue 51; a ``NEW_ONLY`` log8 blob with no other shape flag: δ
and r above level 0): each new vertex's code is stored as its difference mod 256 from a
prediction by its parents in the bintree (seed 002 §2.4: a saturated δ and a nested r
never exceed a parent's), centres first, then the other new vertices
(:func:`pred_residuals`): a cell centre's from the smaller code of the two corners its
cell's diagonal does not join (the parent tile's vertices), an edge midpoint's from the
smaller code of the one or two cell centres beside it. The map is a bijection whatever
the codes, so decoding is exact (:func:`pred_codes`); where the bounds hold, the payload
is mostly small numbers. ``CENTRES`` and ``PRED`` together (schema 17, issue 51; a
geographic store's level-0 r, ``NEW_ONLY`` log8, no other flag): the centres of a
``CENTRES`` payload stored as (guess − code) mod 256, the guess the code of the largest
distance √(s² + Δz²) to the centre's four edge midpoints, from the tile's decoded
heights and its tile-table box (:func:`geoterrain.bounds.leafbounds.centre_guess`; IEEE
products, sums and square roots only, so any reader gets the writer's guess bit for
bit); the decode needs ``guess(e)``. ``MIDS`` and ``PRED`` together (schema 20, issue
51; a geographic store's r above level 0, ``NEW_ONLY`` log8, no other flag): two header
bytes ``a``, ``off`` follow the exponent, then every new vertex's (guess − code) mod 256,
the edge midpoints first, guessed from the tile's heights, then the cell centres, guessed
by the nesting over their decoded midpoints
(:func:`geoterrain.bounds.leafbounds.mids_residuals`); the decode needs ``guess(e, a,
off, payload)``, the tile's (T, T) codes. ``PRED`` and ``SLACK`` together (schema 20; a
δ ``PRED`` blob): the ``PRED`` values range-coded (:func:`pred_payloads_own`) in the
contexts of each vertex's gap between its parents' prediction and the code of its own
error on the tile's decoded heights (:func:`own_codes`), which bounds δ below; ``RING``
and ``PRED`` together (schema 20; a level-0 ring δ): the ring's codes less their
:func:`own_codes`, mod 256, range-coded (:func:`ring_payloads_own`); both decodes need
``own(e)``, and any guess decodes exactly. ``CENTRES``, ``PRED`` and ``RING`` payloads
are otherwise compressed at zstd level :data:`SHAPED_ZSTD_LEVEL` (11), a whole tile's (the
top level's) and a ``DIFF`` one at 15 (``tileblobs.EDGE_ZSTD_LEVEL``), the others at 3:
any zstd decoder reads each.
"""

from __future__ import annotations

import math
import zlib
from functools import lru_cache

import numpy as np
import zstandard
from numba import njit

from geoterrain.codec.entropy import _bit, _canonical, _direct, _finish, _start
from geoterrain.core import zstdsafe
from geoterrain.core.rounding import round_up

VERSION = 1
VERSION_2 = 2
NEW_ONLY, LOG8, RING, DIFF, SLACK = 1, 2, 4, 8, 16  # version-2 flags
CENTRES = 32  # a NEW_ONLY log8 payload of the cell centres only (shape_codes)
MIDS = 64  # a log8 r payload without the cell centres (mids_index): derived on read
PRED = 128  # a NEW_ONLY log8 payload as differences from its parents' codes (pred_residuals)
# zstd level of CENTRES, PRED and RING payloads: 11 (btlazy2) finds the repeats of their
# small residuals that 3 misses (srtm1_japan's 7-13 % fewer bytes there); 12 saves 0.3 %
# of those bytes more at 1.5x the time (docs/lab/store-size.md)
SHAPED_ZSTD_LEVEL = 11
# a small grid's shaped payloads at 15 instead: srtm3's store 1 kB smaller, where 15 would
# cost a large grid's preprocess 9 % more CPU (docs/lab/store-size.md); the same threshold
# as the store's 512-byte pages (store.database.SMALL_GRID)
SMALL_SHAPED_ZSTD_LEVEL = 15
SMALL_GRID_SAMPLES = 3 << 16
LOG_STEPS = 16  # codes per octave: at most 2^(1/16) - 1 = 4.4 % above the exact value
_F16_MAX = 32768.0  # keep the scaled maximum well inside float16's finite range


def shaped_zstd_level(rows: int, cols: int) -> int:
    """The zstd level of a store's ``CENTRES``, ``PRED`` and ``RING`` payloads (and its
    normals' ring residuals) for a ``rows`` × ``cols`` grid: :data:`SMALL_SHAPED_ZSTD_LEVEL`
    up to :data:`SMALL_GRID_SAMPLES` samples, else :data:`SHAPED_ZSTD_LEVEL`. Every writer
    (preprocess, streamed or whole, and the edit) passes it to the blob writers, so their
    bytes agree; a reader needs no level.

    Examples
    --------
    >>> shaped_zstd_level(359, 367), shaped_zstd_level(513, 513)
    (15, 11)
    """
    small = int(rows) * int(cols) <= SMALL_GRID_SAMPLES
    return SMALL_SHAPED_ZSTD_LEVEL if small else SHAPED_ZSTD_LEVEL


def encode_bounds(a: np.ndarray, cctx: zstandard.ZstdCompressor) -> bytes:
    """Encode a non-negative float array (+inf allowed) so decoding never under-estimates.

    Examples
    --------
    >>> a = np.array([[0.0, 1e-3], [123.456, np.inf]], np.float32)
    >>> b = decode_bounds(encode_bounds(a, zstandard.ZstdCompressor()), a.shape)
    >>> bool((b >= a).all()), bool(np.isinf(b[1, 1])), float(b[1, 0]) <= 123.456 * (1 + 2**-10)
    (True, True, True)
    """
    h, k = scale_bounds(np.asarray(a)[None])
    return pack_bounds(h[0], int(k[0]), cctx)


def scale_exponent(a: np.ndarray) -> int:
    """The power-of-two scale exponent that fits the largest finite value of ``a``."""
    fin = np.asarray(a)[np.isfinite(a)]
    peak = float(fin.max()) if fin.size else 0.0
    return int(np.clip(np.ceil(np.log2(peak / _F16_MAX)), -100, 100)) if peak > 0 else 0


def scale_bounds(tiles: np.ndarray, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised first half of :func:`encode_bounds` for a stack of tiles (..., T, T).

    Returns the rounded-up float16 values and the scale exponents (one per tile).
    With one exponent ``k`` for a whole store, rounding is one monotone function,
    so orderings such as saturation (δ(parent) ≥ δ(child)) survive it exactly.
    A blob is ``bytes([VERSION, k & 0xFF]) + zstd(byte-shuffled float16)``, see
    :func:`pack_bounds`.
    """
    a = np.asarray(tiles, np.float64)
    if k is None:
        fin = np.where(np.isfinite(a), a, 0.0).max(axis=(-2, -1))
        with np.errstate(divide="ignore"):
            kk = np.where(fin > 0, np.ceil(np.log2(fin / _F16_MAX)), 0.0)
        k = np.clip(kk, -100, 100).astype(np.int64)
    else:
        k = np.full(a.shape[:-2], k, np.int64)
    v = a * np.exp2(-k.astype(np.float64))[..., None, None]  # exact: powers of two
    return round_up(v, np.float16), k


def pack_bounds(h: np.ndarray, k: int, cctx: zstandard.ZstdCompressor) -> bytes:
    """Second half of :func:`encode_bounds`: one tile's float16 values and exponent → blob."""
    planes = np.ascontiguousarray(h).view(np.uint8).reshape(-1, 2).T.copy()
    return bytes([VERSION, int(k) & 0xFF]) + cctx.compress(planes.tobytes())


def decode_bounds(blob: bytes, shape: tuple[int, ...], parent: np.ndarray | None = None,
                  parity: tuple[int, int] = (0, 0), derive=None,
                  base: np.ndarray | None = None, guess=None, own=None) -> np.ndarray:
    """Inverse of :func:`encode_bounds` and :func:`pack_bounds_v2`: float32 values ≥ the
    encoded ones. A version-2 new-vertices-only blob needs the parent tile's decoded
    values and the tile's ``(x % 2, y % 2)``; a ``RING`` blob also needs ``derive(rows,
    cols, ring_values, log8, e, slack)``: the stored values (T, T) of the tile's new
    vertices, computed from its heights with the ring's (:mod:`geoterrain.bounds.leafbounds`;
    ``slack``: the blob's ``SLACK``, else 0) and coded with the blob's code (log8 or
    float16) and exponent; a ``MIDS`` blob calls ``derive(None, None, mids, True, e, 0.0)``
    with the decoded values (T, T) of the samples it keeps (0 elsewhere) and takes its
    result (those values, and each cell centre's derived). A ``DIFF`` blob needs ``base``:
    the tile's decoded δ, whose codes its payload is added to. A ``CENTRES`` ``PRED`` blob
    (a geographic level-0 r) needs ``guess(e)``: the (h, h) codes its centres are
    predicted by (:func:`geoterrain.bounds.leafbounds.centre_guess`); a ``MIDS`` ``PRED``
    blob (a geographic r above level 0) ``guess(e, a, off, payload)``: the tile's (T, T)
    codes (:func:`geoterrain.bounds.leafbounds.mids_codes`). A schema-20 δ blob
    (``PRED`` with ``SLACK``, or ``RING`` with ``PRED``) needs ``own(e)``: the tile's
    (T, T) :func:`own_codes` from its decoded heights."""
    if len(blob) >= 1 and blob[0] == VERSION_2:
        return _decode_v2(blob, shape, parent, parity, derive, base, guess, own)
    if len(blob) < 2 or blob[0] != VERSION:
        raise ValueError("not a bounds blob of a known version")
    k = int(np.int8(np.uint8(blob[1])))
    n = int(np.prod(shape))
    raw = zstdsafe.decompress(blob[2:], 2 * n, exact=True)  # bounded: never a bomb
    planes = np.frombuffer(raw, np.uint8).reshape(2, n)
    h = planes.T.copy().view(np.float16).reshape(shape)
    # float32 output: round up again so the bound survives the cast
    return round_up(h.astype(np.float64) * 2.0**k, np.float32)


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


@njit(cache=True, nogil=True)
def _positive_finite_max_nb(a):
    # the largest finite value if one is > 0, else 0, one pass without a copy
    m = 0.0
    for v in a.ravel():
        if np.isfinite(v) and v > m:
            m = v
    return m


def log8_exponent(a: np.ndarray) -> int:
    """The exponent ``e`` whose top finite code (254) covers the largest finite value.

    Examples
    --------
    >>> log8_exponent(np.array([0.5, np.inf, 3.0, np.nan], np.float32)), log8_exponent(np.zeros(2))
    (-14, 0)
    """
    peak = float(_positive_finite_max_nb(np.ascontiguousarray(a)))  # exact: a's own value
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


def shape_codes(payload: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The ``CENTRES`` shape of ``NEW_ONLY`` log8 payloads.

    ``payload`` (k, n): each tile's codes of its new vertices (raster order). Returns each
    tile's payload as it is stored and its flags: ``CENTRES`` (the centres only) where
    every new vertex but the centres has code 0, else 0 (the payload as given). A tile's
    shape depends on its own codes only, so an edit that rewrites a tile rewrites no
    other. :func:`decode_bounds` inverts it.

    Examples
    --------
    >>> T = 5; codes = np.zeros((T, T), np.uint8); codes[1::2, 1::2] = 7
    >>> rows, flags = shape_codes(codes[new_mask(T)][None])
    >>> rows[0].tolist(), int(flags[0]) == CENTRES
    ([7, 7, 7, 7], True)
    """
    p = np.asarray(payload, np.uint8)
    n = p.shape[1] if p.ndim == 2 else 0
    h = int(round((np.sqrt(1 + 3 * n) - 1) / 3))  # n = 3h² + 2h new vertices, T = 2h + 1
    T = 2 * h + 1
    if p.ndim != 2 or h < 1 or 3 * h * h + 2 * h != n:
        raise ValueError("payloads of a tile's new vertices expected")
    c, o = _shape_index(T)
    centres_only = ~p[:, o].any(axis=1)
    flags = np.where(centres_only, CENTRES, 0).astype(np.uint8)
    if not centres_only.any():
        return list(p), flags
    return [p[n, c] if centres_only[n] else p[n] for n in range(p.shape[0])], flags


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


# ------------------------------------------- schema 20: δ guessed from the tile's heights
#: contexts of a schema-20 δ payload's values: the gap between a vertex's bounds,
#: bucketed (:func:`_gap_bucket`)
GAP_BUCKETS = 14
_GAP_ROWS = GAP_BUCKETS * 17  # per bucket: zero flag, 7 length steps, 9 mantissa bits


@njit(cache=True, nogil=True, inline="always")
def _code_up(table, x, e):
    # the smallest log8 code whose value is ≥ x (radii.code_up_nb's binary search, the
    # same result): a guess from log2(x), walked to the first entry ≥ x
    if not x > table[1]:  # 0 for x ≤ 0, else 1
        return 0 if not x > 0.0 else 1
    if x > table[254]:
        return 255
    c = min(max(int(LOG_STEPS * (math.log2(x) - e)) + 1, 1), 254)
    while table[c - 1] >= x:
        c -= 1
    while table[c] < x:
        c += 1
    return c


@njit(cache=True, nogil=True)
def _own_codes_nb(z, valid, stand_in, r0, c0, s, ring, table, e, out):
    # tile k's samples are z[r0[k] + s i, c0[k] + s j], copied first into ``w`` with the
    # stand-in where not valid (no mask: all valid). IEEE products, sums and abs only (no
    # fast math): a writer and any reader get the same codes bit for bit. Edge midpoints:
    # |z − the mean of the split edge's ends|; cell centres: seed 002 §2.3's h = 1 closed
    # form over the cell's 9 samples (delta._centre1: the centre off its diagonal, each
    # edge midpoint off its edge), the diagonal by the union-jack parity from the tile's
    # first cell (as _pred_index). ``ring``: the border's new vertices only
    T = out.shape[1]
    w = np.empty((T, T))
    masked = valid.shape[0] > 0
    for k in range(out.shape[0]):
        for i in range(T):
            a = r0[k] + s * i
            for j in range(T):
                if ring and 1 < i < T - 2 and 1 < j < T - 2:
                    continue
                b = c0[k] + s * j
                w[i, j] = z[a, b] if not masked or valid[a, b] else stand_in
        for i in range(T):
            for j in range(1 - (i & 1), T, 2 - (i & 1)):  # the new vertices
                if ring and 0 < i < T - 1 and 0 < j < T - 1:
                    continue
                zv = w[i, j]
                if (i & 1) and (j & 1):
                    z00 = w[i - 1, j - 1]
                    z01 = w[i - 1, j + 1]
                    z10 = w[i + 1, j - 1]
                    z11 = w[i + 1, j + 1]
                    main = ((i >> 1) + (j >> 1)) % 2 == 0
                    sc = 0.5 * (z00 + z11) if main else 0.5 * (z01 + z10)
                    m = abs(zv - sc)
                    m = max(m, abs(w[i - 1, j] - 0.5 * (z00 + z01)))
                    m = max(m, abs(w[i + 1, j] - 0.5 * (z10 + z11)))
                    m = max(m, abs(w[i, j - 1] - 0.5 * (z00 + z10)))
                    m = max(m, abs(w[i, j + 1] - 0.5 * (z01 + z11)))
                elif i & 1:  # odd row, even column: the ends above and below
                    m = abs(zv - 0.5 * (w[i - 1, j] + w[i + 1, j]))
                else:
                    m = abs(zv - 0.5 * (w[i, j - 1] + w[i, j + 1]))
                out[k, i, j] = _code_up(table, m, e) if m == m else 0


def own_codes(z: np.ndarray, valid: np.ndarray | None, stand_in: float, e: int,
              origins: np.ndarray | None = None, T: int | None = None, step: int = 1,
              ring: bool = False) -> np.ndarray:
    """The log8 codes (from ``2^e``) of a lower bound of each new vertex's δ, from the
    scene heights ``z`` (invalid samples, where ``valid`` is False, by the store's
    ``stand_in`` height, as the radii take them; ``valid`` None: all valid): an edge
    midpoint's own error, |z − the mean of its split edge's ends|, and a cell centre's
    closed form over its cell (its own error and its four edge midpoints', seed 002
    §2.3). δ is the largest error over the vertex's diamond, saturated over its
    children, so it is never below these where the samples are valid. (k, T, T) uint8 of
    the tiles whose first samples are at ``origins`` (k, 2: row, column; None: one tile,
    ``z`` itself) with samples ``step`` apart, 0 on the parent's vertices (and off the
    border with ``ring``). Schema 20's guess for δ (:func:`pred_payloads_own`, and
    :func:`ring_payloads_own`): a wrong one costs bytes, never exactness.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0; z[0, 1] = 1.0
    >>> c = own_codes(z, None, 0.0, -3)[0]; t = log8_table(-3)
    >>> float(t[c[1, 1]]), float(t[c[0, 1]]), int(c[0, 0])
    (2.0, 1.0, 0)
    """
    z = np.asarray(z, np.float64)
    if origins is None:
        origins, T = np.zeros((1, 2), np.int64), z.shape[0]
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    v = np.zeros((0, 0), np.uint8) if valid is None else np.asarray(valid).view(np.uint8) \
        if np.asarray(valid).dtype in (np.bool_, np.uint8) else np.asarray(valid, np.uint8)
    out = np.zeros((len(o), T, T), np.uint8)
    _own_codes_nb(z, v, float(stand_in), np.ascontiguousarray(o[:, 0]),
                  np.ascontiguousarray(o[:, 1]), int(step), bool(ring),
                  _log8_table64(int(e)), int(e), out)
    return out


@njit(cache=True, nogil=True, inline="always")
def _gap_bucket(g):
    # the gap between a vertex's upper bound (its parents') and its own error's code:
    # 0 (the code is known where the bounds hold), 1, 2, 3, then roughly log-spaced
    if g <= 0:
        return 0
    if g < 4:
        return g
    if g < 6:
        return 4
    if g < 8:
        return 5
    if g < 12:
        return 6
    if g < 16:
        return 7
    if g < 24:
        return 8
    if g < 32:
        return 9
    if g < 48:
        return 10
    if g < 64:
        return 11
    return 12 if g < 255 else 13


@njit(cache=True, nogil=True)
def _gap_values(enc, S, buf, m, r, gap):
    """Code (or decode into ``r``) the values ``r`` (0 … 255) in their contexts, the
    buckets of ``gap``: a zero flag, the bit length k (1 … 8) in unary, the bit below the
    leading one (adaptive: the range coder of :mod:`geoterrain.codec.entropy`), the rest
    as equiprobable bits. Returns the coder's state."""
    for i in range(r.shape[0]):
        c = _gap_bucket(gap[i]) * 17
        u = r[i] if enc else 0
        nz, S = _bit(enc, S, buf, m, c, np.int64(u != 0))
        if nz == 0:
            r[i] = 0
            continue
        kk = 0
        x = u
        while x:
            kk += 1
            x >>= 1
        k = 1
        while k < 8:  # 1 = longer
            b, S = _bit(enc, S, buf, m, c + k, np.int64(kk > k))
            if b == 0:
                break
            k += 1
        v = np.int64(1)
        if k >= 2:
            b, S = _bit(enc, S, buf, m, c + 7 + k, np.int64((u >> (k - 2)) & 1) if enc
                        else np.int64(0))
            v = (v << 1) | b
            if k >= 3:
                low, S = _direct(enc, S, buf, k - 2,
                                 np.int64(u & ((1 << (k - 2)) - 1)) if enc else np.int64(0))
                v = (v << (k - 2)) | low
        r[i] = v
    return S


@njit(cache=True, nogil=True)
def _encode_gaps(r, gap, buf):
    m = np.zeros((_GAP_ROWS, 2), np.int64)
    S = _start(True, buf)
    # a bool, not a literal True: the specialisation GapDecoder.take runs (called from
    # Python), so a reader loads what the writer compiled
    S = _gap_values(np.bool_(True), S, buf, m, r, gap)
    return _finish(S, buf)


def encode_gaps(r: np.ndarray, gap: np.ndarray) -> bytes:
    """Schema 20's range-coded δ payload: values ``r`` (0 … 255) in the contexts of their
    ``gap`` (:func:`decode_gaps` inverts it).

    Examples
    --------
    >>> r = np.array([0, 0, 3, 1, 200, 0]); gap = np.array([0, 0, 5, 1, 255, 40])
    >>> d = GapDecoder(encode_gaps(r, gap))
    >>> d.take(gap[:2]).tolist(), d.take(gap[2:]).tolist()
    ([0, 0], [3, 1, 200, 0])
    """
    r = np.ascontiguousarray(r, np.int64).copy()
    gap = np.ascontiguousarray(gap, np.int64)
    buf = np.zeros(16 * len(r) + 64, np.uint8)  # > 12 bytes a value at the worst odds
    n = int(_encode_gaps(r, gap, buf))
    if n < 0:
        raise ValueError("a range-coded bounds payload overflowed its buffer")
    return buf[:n].tobytes()


class GapDecoder:
    """Decodes a payload of :func:`encode_gaps` in parts, each part's contexts known only
    once the parts before it are decoded (a tile's centres, then its other new vertices).
    A stranger's bytes decode to values 0 … 255, never past the payload (zeros are read
    past its end); :meth:`check` refuses bytes the encoder would not have written."""

    def __init__(self, data: bytes) -> None:
        self.buf = np.frombuffer(data, np.uint8).copy()  # writable: one kernel codes both ways
        self.m = np.zeros((_GAP_ROWS, 2), np.int64)
        self.S = _start(False, self.buf)

    def take(self, gap: np.ndarray) -> np.ndarray:
        """The next ``len(gap)`` values, in the contexts of ``gap``."""
        r = np.zeros(len(gap), np.int64)
        self.S = _gap_values(False, self.S, self.buf, self.m, r,
                             np.ascontiguousarray(gap, np.int64))
        return r

    def check(self) -> None:
        """ValueError unless the bytes were exactly the encoder's stream: every byte read
        (a spliced, padded or foreign payload has bytes past it) and the last one not a
        zero the encoder drops (:mod:`geoterrain.codec.entropy`'s rule)."""
        if not _canonical(self.buf, self.S):
            raise ValueError("a range-coded bounds payload is not the encoder's stream")


def guess_check(g: np.ndarray) -> int:
    """The byte that opens a schema-20 δ payload: the low byte of the crc32 of the guess
    it was coded against (a tile's :func:`own_codes`, or its ring's, as uint8). A reader
    compares it with its own guess's, so a payload moved to another tile (its checksum
    recomputed) is refused rather than decoded against the wrong heights (a ring's
    differences, mostly 0, would decode to plausible codes there).

    Examples
    --------
    >>> guess_check(np.array([1, 2, 3])) != guess_check(np.array([2, 3, 4]))
    True
    """
    return zlib.crc32(np.ascontiguousarray(g, np.uint8).tobytes()) & 0xFF


def pred_gaps(W: np.ndarray, lo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For tiles ``W`` (k, T, T) of log8 codes and their :func:`own_codes` ``lo``:
    :func:`pred_residuals`' differences (k, n) (the parents' prediction minus the code,
    mod 256; the centres, then the other new vertices) and their gaps (k, n) (the
    prediction minus ``lo``): where the bounds hold, 0 ≤ difference ≤ gap."""
    W = np.asarray(W, np.int16)
    lo = np.asarray(lo, np.int16)
    k, T = W.shape[0], W.shape[1]
    other, n1, n2, main = _pred_index(T)
    hc = _pred_centres(W, main).reshape(k, -1)
    ext = np.concatenate([W.reshape(k, -1), np.full((k, 1), 255, np.int16)], axis=1)
    hm = np.minimum(ext[:, n1], ext[:, n2])
    r = np.concatenate([hc - W[:, 1::2, 1::2].reshape(k, -1), hm - ext[:, other]], axis=1)
    gap = np.concatenate([hc - lo[:, 1::2, 1::2].reshape(k, -1),
                          hm - lo.reshape(k, -1)[:, other]], axis=1)
    return r & 0xFF, gap


def pred_payloads_own(W: np.ndarray, lo: np.ndarray) -> list[bytes]:
    """Schema 20's ``PRED`` δ payloads (``PRED`` with ``SLACK``) of tiles ``W`` (k, T, T)
    with their :func:`own_codes` ``lo``: :func:`pred_gaps`' differences range-coded
    (:func:`encode_gaps`) in the contexts of their gaps. Where a gap is 0 the code is
    known (a zero costs a few hundredths of a bit), where it is small the difference is
    small: srtm1_japan's level-1 δ 87.5 kB in raster order at zstd 11, 73.8 kB so
    (docs/lab/store-size.md). Exact whatever ``lo``: a wrong guess costs bytes.
    :func:`pred_codes_own` inverts it.

    Examples
    --------
    >>> W = np.random.default_rng(1).integers(0, 256, (2, 5, 5)).astype(np.uint8)
    >>> lo = np.random.default_rng(2).integers(0, 256, (2, 5, 5)).astype(np.uint8)
    >>> p = pred_payloads_own(W, lo)
    >>> all((pred_codes_own(W[k, ::2, ::2], p[k], lo[k]) == W[k]).all() for k in range(2))
    True
    """
    r, gap = pred_gaps(W, lo)
    return [bytes([guess_check(lo[n])]) + encode_gaps(r[n], gap[n]) for n in range(len(r))]


def pred_codes_own(corners: np.ndarray, payload: bytes, lo: np.ndarray) -> np.ndarray:
    """A tile's (T, T) log8 codes from its parent's ``corners`` (h + 1, h + 1), its
    schema-20 ``PRED`` payload (:func:`pred_payloads_own`) and its :func:`own_codes`
    ``lo`` (T, T): the centres first (their contexts from the corners and ``lo``), then
    the other new vertices (theirs from the centres and ``lo``)."""
    h = np.shape(corners)[0] - 1
    lo = np.asarray(lo, np.int16).reshape(2 * h + 1, 2 * h + 1)
    if len(payload) < 1 or payload[0] != guess_check(lo):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = _pred_take(dec, corners, lo)
    dec.check()
    return out


def _pred_take(dec: GapDecoder, corners: np.ndarray, lo: np.ndarray) -> np.ndarray:
    # one tile's (T, T) codes from its corners (h + 1, h + 1): the next values of ``dec``
    # in pred_gaps' order (the centres, then the other new vertices), in their gaps
    corners = np.asarray(corners, np.int16)
    h = corners.shape[0] - 1
    T = 2 * h + 1
    lo = np.asarray(lo, np.int16).reshape(T, T)
    other, n1, n2, main = _pred_index(T)
    ext = np.empty(T * T + 1, np.int16)
    W = ext[:-1].reshape(1, T, T)
    W[0, ::2, ::2] = corners
    ext[-1] = 255
    hc = _pred_centres(W, main)[0].ravel()
    rc = dec.take(hc - lo[1::2, 1::2].ravel())
    W[0, 1::2, 1::2] = ((hc - rc) & 0xFF).reshape(h, h)
    hm = np.minimum(ext[n1], ext[n2])
    ext[other] = (hm - dec.take(hm - lo.ravel()[other])) & 0xFF
    return W[0].astype(np.uint8)


def edge_own_codes(z: np.ndarray, valid: np.ndarray | None, stand_in: float, e: int,
                   rows: int, cols: int) -> np.ndarray | None:
    """Schema 23's guess of a level-0 tile's δ_edge (T, T) log8 codes: the
    :func:`own_codes` of the tile's heights ``z`` (invalid and non-finite samples by
    ``stand_in``) with the padding replicated from the data's edge as
    :func:`geoterrain.bounds.edgepad.edge_support` does (the data: the tile's first
    ``rows`` rows and ``cols`` columns), 0 on the new vertices whose diamond misses the
    data (row > ``rows`` or column > ``cols``). None where the tile holds no data row or
    column to replicate. The writer and the reader call it on the same heights.

    Examples
    --------
    >>> z = np.zeros((5, 5)); z[:3, :3] = [[0, 1, 2], [1, 2, 3], [2, 3, 9]]
    >>> g = edge_own_codes(z, None, 0.0, -3, 3, 3)
    >>> int(g[1, 1] > 0), int(g[4, 3]), int(g[3, 4]), edge_own_codes(z, None, 0.0, -3, 0, 3)
    (1, 0, 0, None)
    """
    T = z.shape[0]
    if rows < 1 or cols < 1:
        return None
    ok = np.isfinite(z) if valid is None else np.asarray(valid, bool) & np.isfinite(z)
    Z = np.where(ok, np.asarray(z, np.float64), float(stand_in))
    if cols < T:
        Z[:rows, cols:] = Z[:rows, cols - 1:cols]
    if rows < T:
        Z[rows:] = Z[rows - 1]
    g = own_codes(Z, None, stand_in, e)[0]
    g[rows + 1:] = 0
    g[:, cols + 1:] = 0
    return g


def edge_payload_own(codes: np.ndarray, base: np.ndarray, guess: np.ndarray,
                     pred: bool = False) -> bytes | None:
    """Schema 23's δ_edge payload of a tile below the top (flags ``DIFF`` with ``PRED``):
    its new vertices' δ_edge log8 ``codes`` (T, T) where its δ codes ``base`` are +inf
    (255), range-coded (:func:`encode_gaps`) after the :func:`guess_check` of their
    ``guess`` (:func:`edge_own_codes`): level 0's as the codes less the guess, mod 256, in
    one context; ``pred`` (above level 0, ``SLACK`` too) as :func:`pred_gaps`'
    differences from the parents' prediction in the contexts of their gaps above the
    guess (``codes`` then holds the parent's codes on the even vertices). Everywhere else
    δ_edge is δ, and None where it is not (the writer keeps the plain ``DIFF`` payload
    then). srtm3's 19 δ_edge blobs below the top 2.99 → 1.0 kB (docs/lab/store-size.md).
    :func:`edge_codes_own` inverts it.

    Examples
    --------
    >>> b = np.full((3, 3), 255, np.uint8); b[0, 1] = 4
    >>> c = b.copy(); c[1, 1], c[2, 1] = 7, 9; c[::2, ::2] = 0  # the corners: not new
    >>> g = np.full((3, 3), 7, np.uint8); p = edge_payload_own(c, b, g)
    >>> bool((edge_codes_own(p, b, g) == c).all()), edge_payload_own(b - 1, b, g)
    (True, None)
    >>> c[::2, ::2] = 8; q = edge_payload_own(c, b, g, pred=True)
    >>> bool((edge_codes_own(q, b, g, c[::2, ::2]) == c).all())
    True
    """
    T = codes.shape[0]
    keep = _new_flat(T)
    c = np.asarray(codes, np.int64).ravel()[keep]
    b = np.asarray(base, np.int64).ravel()[keep]
    sel = b == 255
    if (c[~sel] != b[~sel]).any():
        return None
    g = np.asarray(guess, np.int64).ravel()[keep]
    head = bytes([guess_check(g[sel])])
    if not pred:
        return head + encode_gaps((c[sel] - g[sel]) & 0xFF, np.zeros(int(sel.sum()), np.int64))
    r, gap = pred_gaps(np.asarray(codes)[None], np.asarray(guess)[None])
    ps = _edge_pred_order(np.asarray(base), T)
    return head + encode_gaps(r[0][ps], gap[0][ps])


def _edge_pred_order(base: np.ndarray, T: int) -> np.ndarray:
    # pred_gaps' order (the centres, then the other new vertices) of the new vertices
    # where δ's codes ``base`` are +inf
    other = _pred_index(T)[0]
    return np.concatenate([base[1::2, 1::2].ravel() == 255, base.ravel()[other] == 255])


def edge_codes_own(payload: bytes, base: np.ndarray, guess: np.ndarray,
                   corners: np.ndarray | None = None) -> np.ndarray:
    """A tile's δ_edge codes (T, T; its new vertices', and ``corners`` on the even ones)
    from its :func:`edge_payload_own` payload, its δ codes ``base`` and its ``guess``
    (:func:`edge_own_codes`); ``corners`` (h + 1, h + 1): the parent's codes, for a
    ``pred`` payload. ValueError for a payload coded against other heights or bytes the
    encoder would not have written."""
    T = base.shape[0]
    keep = _new_flat(T)
    sel = np.asarray(base).ravel()[keep] == 255
    if len(payload) < 1 or payload[0] != guess_check(np.asarray(guess).ravel()[keep][sel]):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = _edge_take(dec, base, guess, corners)
    dec.check()
    return out


def _edge_take(dec: GapDecoder, base: np.ndarray, guess: np.ndarray,
               corners: np.ndarray | None) -> np.ndarray:
    # one tile's δ_edge codes (T, T): δ's codes ``base`` where they are finite, the next
    # values of ``dec`` where they are +inf (edge_payload_own's order and contexts)
    T = base.shape[0]
    keep = _new_flat(T)
    b = np.asarray(base, np.int64).ravel()[keep]
    g = np.asarray(guess, np.int64)
    sel = b == 255
    out = np.zeros(T * T, np.int16)
    out[keep] = b
    if corners is None:
        out[keep[sel]] = (g.ravel()[keep][sel] + dec.take(np.zeros(int(sel.sum()), np.int64))
                          ) & 0xFF
    else:  # the centres from the corners, then the other new vertices (pred_gaps)
        other, n1, n2, main = _pred_index(T)
        ext = np.empty(T * T + 1, np.int16)
        ext[:-1] = out
        ext[-1] = 255
        W = ext[:-1].reshape(1, T, T)
        W[0, ::2, ::2] = corners
        cs = np.asarray(base)[1::2, 1::2] == 255
        hc = _pred_centres(W, main)[0]
        rc = dec.take((hc - g[1::2, 1::2])[cs])
        W[0, 1::2, 1::2][cs] = (hc[cs] - rc) & 0xFF
        os_ = np.asarray(base).ravel()[other] == 255
        hm = np.minimum(ext[n1], ext[n2])[os_]
        ext[other[os_]] = (hm - dec.take(hm - g.ravel()[other[os_]])) & 0xFF
        out = ext[:-1]
    return out.astype(np.uint8).reshape(T, T)


def top_edge_payload_own(codes: np.ndarray, base: np.ndarray, guess_at) -> bytes | None:
    """Schema 23's whole-tile δ_edge payload (the top tile's; flags ``DIFF``, ``PRED`` and
    ``SLACK`` without ``NEW_ONLY``): the tile's (T, T) δ_edge log8 ``codes`` level by
    level inside it (:func:`top_steps`), its four corners as they are, then each level's
    new vertices where δ's codes ``base`` are +inf as :func:`edge_payload_own` with
    ``pred`` codes a tile below the top, ``guess_at(s)`` the :func:`edge_own_codes` of
    the tile's samples s apart, in one range-coded stream after the :func:`guess_check`
    of every guess there. None where δ_edge is not δ wherever δ is finite (off the
    corners). :func:`top_edge_codes_own` inverts it.

    Examples
    --------
    >>> rng = np.random.default_rng(4)
    >>> b = rng.choice(np.array([3, 255], np.uint8), (9, 9)); c = b.copy()
    >>> c[b == 255] = rng.integers(0, 256, int((b == 255).sum()))
    >>> g = {s: rng.integers(0, 256, (8 // s + 1,) * 2).astype(np.uint8) for s in (4, 2, 1)}
    >>> bool((top_edge_codes_own(top_edge_payload_own(c, b, g.get), b, g.get) == c).all())
    True
    """
    c, b = np.asarray(codes, np.uint8), np.asarray(base, np.uint8)
    T = c.shape[0]
    off = np.ones((T, T), bool)
    off[::T - 1, ::T - 1] = False
    if (c[off & (b != 255)] != b[off & (b != 255)]).any():
        return None
    rs, gs, checks = [], [], []
    for s in top_steps(T):
        g = np.asarray(guess_at(s), np.uint8)
        r, gap = pred_gaps(c[None, ::s, ::s], g[None])
        ps = _edge_pred_order(b[::s, ::s], g.shape[0])
        rs.append(r[0][ps])
        gs.append(gap[0][ps])
        checks.append(g.ravel()[_new_flat(g.shape[0])][b[::s, ::s].ravel()[
            _new_flat(g.shape[0])] == 255])
    return (bytes([guess_check(np.concatenate(checks))]) + c[::T - 1, ::T - 1].tobytes()
            + encode_gaps(np.concatenate(rs), np.concatenate(gs)))


def top_edge_codes_own(payload: bytes, base: np.ndarray, guess_at) -> np.ndarray:
    """A whole tile's (T, T) δ_edge codes from its :func:`top_edge_payload_own` payload,
    its δ codes ``base`` and its guesses ``guess_at(s)``; ValueError for a payload
    coded against other heights, or bytes the encoder would not have written."""
    b = np.asarray(base, np.uint8)
    T = b.shape[0]
    gs, checks = [], []
    for s in top_steps(T):
        g = np.asarray(guess_at(s), np.uint8)
        n = (T - 1) // s + 1
        if g.shape != (n, n):
            raise ValueError("an edge guess of the wrong shape")
        gs.append(g)
        checks.append(g.ravel()[_new_flat(n)][b[::s, ::s].ravel()[_new_flat(n)] == 255])
    if len(payload) < 5 or payload[0] != guess_check(np.concatenate(checks)):
        raise ValueError("a guessed bounds payload coded against other heights")
    W = np.frombuffer(payload[1:5], np.uint8).reshape(2, 2)
    dec = GapDecoder(payload[5:])
    for s, g in zip(top_steps(T), gs, strict=True):
        W = _edge_take(dec, b[::s, ::s], g, W)
    dec.check()
    return W


def top_steps(T: int) -> list[int]:
    """The sample steps of a whole tile's levels inside it, coarsest first:
    (T − 1) / 2, …, 2, 1 (T − 1 a power of two ≥ 2)."""
    if T < 3 or (T - 1) & (T - 2):
        raise ValueError("a tile of 2^k + 1 samples a side, k ≥ 1")
    return [1 << b for b in range((T - 1).bit_length() - 2, -1, -1)]


def top_payload_own(codes: np.ndarray, lo_at) -> bytes:
    """Schema 23's whole-tile δ payload (the top tile's; flags ``PRED`` with ``SLACK``
    without ``NEW_ONLY``): the tile's (T, T) log8 ``codes`` level by level inside it, as
    :func:`pred_payloads_own` codes a tile below the top: its four corners, then, for each
    step s of :func:`top_steps`, the vertices new at s (the samples s apart, their parents
    2s apart) as :func:`pred_gaps`' differences in their gaps above ``lo_at(s)``, the
    :func:`own_codes` of the tile's samples s apart, all range-coded in one stream
    (:func:`encode_gaps`), after the :func:`guess_check` of every level's guess.
    srtm3's top δ 1.50 → 0.97 kB (docs/lab/store-size.md). :func:`top_codes_own`
    inverts it; any guess decodes exactly.

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> c = rng.integers(0, 256, (9, 9)).astype(np.uint8)
    >>> lo = {s: rng.integers(0, 256, (8 // s + 1,) * 2).astype(np.uint8) for s in (4, 2, 1)}
    >>> bool((top_codes_own(top_payload_own(c, lo.get), 9, lo.get) == c).all())
    True
    """
    c = np.asarray(codes, np.uint8)
    T = c.shape[0]
    los = [np.asarray(lo_at(s), np.uint8) for s in top_steps(T)]
    rs, gs = [], []
    for s, lo in zip(top_steps(T), los, strict=True):
        r, gap = pred_gaps(c[None, ::s, ::s], lo[None])
        rs.append(r[0])
        gs.append(gap[0])
    check = guess_check(np.concatenate([lo.ravel() for lo in los]))
    return (bytes([check]) + c[::T - 1, ::T - 1].tobytes()
            + encode_gaps(np.concatenate(rs), np.concatenate(gs)))


def top_codes_own(payload: bytes, T: int, lo_at) -> np.ndarray:
    """A whole tile's (T, T) log8 codes from its :func:`top_payload_own` payload and its
    guesses ``lo_at(s)`` (each step s of :func:`top_steps`: the :func:`own_codes` of the
    tile's samples s apart); ValueError for a payload coded against other heights, or
    bytes the encoder would not have written."""
    steps = top_steps(T)
    los = []
    for s in steps:
        lo = np.asarray(lo_at(s), np.uint8)
        if lo.shape != ((T - 1) // s + 1,) * 2:
            raise ValueError("an own-error guess of the wrong shape")
        los.append(lo)
    if len(payload) < 5 or payload[0] != guess_check(
            np.concatenate([lo.ravel() for lo in los])):
        raise ValueError("a guessed bounds payload coded against other heights")
    W = np.frombuffer(payload[1:5], np.uint8).reshape(2, 2)
    dec = GapDecoder(payload[5:])
    for lo in los:
        W = _pred_take(dec, W, lo)
    dec.check()
    return W


def ring_payloads_own(rings: np.ndarray, guess: np.ndarray) -> list[bytes]:
    """Schema 20's level-0 ``RING`` δ payloads (``RING`` with ``PRED``): each ring's codes
    (k, 2(T − 1)) less their :func:`own_codes` ``guess``, mod 256, range-coded in one
    context (:func:`encode_gaps`; mostly zeros: an edge midpoint at level 0 is a leaf, its
    δ its own error but where the next tile's cell holds nodata, or a geographic store's
    curvilinear term raises it). :func:`ring_codes_own` inverts one.

    Examples
    --------
    >>> c = np.array([[5, 7, 0, 255]], np.uint8); g = np.array([[5, 6, 1, 255]], np.uint8)
    >>> ring_codes_own(ring_payloads_own(c, g)[0], g[0]).tolist()
    [5, 7, 0, 255]
    """
    g = np.asarray(guess, np.int64)
    d = (np.asarray(rings, np.int64) - g) & 0xFF
    zero = np.zeros(d.shape[1], np.int64)
    return [bytes([guess_check(g[n])]) + encode_gaps(d[n], zero) for n in range(len(d))]


def ring_codes_own(payload: bytes, guess: np.ndarray) -> np.ndarray:
    """A ring's codes from its :func:`ring_payloads_own` payload and its guess."""
    g = np.asarray(guess, np.int64)
    if len(payload) < 1 or payload[0] != guess_check(g):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = ((dec.take(np.zeros(len(g), np.int64)) + g) & 0xFF).astype(np.uint8)
    dec.check()
    return out


def pack_bounds_v2(values: np.ndarray, e: int, log8: bool, new_only: bool,
                   cctx: zstandard.ZstdCompressor) -> bytes:
    """A version-2 blob of one tile: ``values`` are log8 codes (uint8) or scaled float16.

    Examples
    --------
    >>> a = np.abs(np.random.default_rng(0).normal(size=(5, 5)))
    >>> e = log8_exponent(a)
    >>> blob = pack_bounds_v2(log8_codes(a, e), e, True, False, zstandard.ZstdCompressor())
    >>> bool((decode_bounds(blob, (5, 5)) >= a).all())
    True
    """
    v = np.asarray(values)
    flags = (NEW_ONLY if new_only else 0) | (LOG8 if log8 else 0)
    if new_only:
        v = v[new_mask(v.shape[0])]
    if log8 and new_only and np.shape(values)[0] >= 3:  # CENTRES (shape_codes), else PRED
        rows, shape = shape_codes(np.asarray(v, np.uint8)[None])
        v, flags = rows[0], flags | int(shape[0])
        if not shape[0]:
            v, flags = pred_residuals(np.asarray(values, np.uint8)[None])[0], flags | PRED
    if log8:
        payload = np.ascontiguousarray(v, np.uint8).tobytes()
    else:
        payload = np.ascontiguousarray(v, np.float16).view(np.uint8).reshape(-1, 2).T.tobytes()
    frame = (zstdsafe.compress_one(payload, SHAPED_ZSTD_LEVEL) if flags & (CENTRES | PRED)
             else zstdsafe.strip_magic(cctx.compress(payload)))
    return bytes([VERSION_2, flags, int(e) & 0xFF]) + frame


def _decode_v2(blob: bytes, shape: tuple[int, ...], parent: np.ndarray | None,
               parity: tuple[int, int], derive, base, guess=None, own=None) -> np.ndarray:
    if len(blob) < 3 or blob[1] & ~(NEW_ONLY | LOG8 | RING | DIFF | SLACK | CENTRES | MIDS
                                    | PRED):
        raise ValueError("not a bounds blob of a known version")
    flags, e = blob[1], int(np.int8(np.uint8(blob[2])))
    guessed = flags & (CENTRES | PRED) == CENTRES | PRED  # schema 17: centres from heights
    # schema 20: a geographic r above level 0, every new vertex from the heights' guess
    mguessed = flags & (MIDS | PRED) == MIDS | PRED
    if mguessed and (flags & (RING | DIFF | SLACK | CENTRES) or not flags & NEW_ONLY
                     or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1]
                     or shape[0] < 3 or shape[0] % 2 == 0 or guess is None
                     or len(blob) < 5 or parent is None
                     or np.shape(parent) != tuple(shape)):
        raise ValueError("a guessed mids bounds blob needs a square tile's new log8 codes, "
                         "its heights and its parent's values")
    # schema 20: a δ PRED payload range-coded in the contexts of its own-error gaps (PRED
    # with SLACK: the gap between the parents' bound and the own error's), a level-0 δ
    # ring as differences from the own errors' codes (RING with PRED), range-coded
    coded = flags & (PRED | SLACK | RING | CENTRES | MIDS) == PRED | SLACK
    own_ring = flags & (RING | PRED | CENTRES) == RING | PRED
    if (coded or own_ring) and own is None:
        raise ValueError("a bounds blob guessed from the heights needs the tile's heights")
    if flags & (DIFF | PRED | SLACK | NEW_ONLY) == DIFF | PRED | SLACK:
        # schema 23: a whole (top) tile's δ_edge, level by level, guessed
        if flags & (RING | CENTRES | MIDS) or not flags & LOG8 or len(shape) != 2 \
                or shape[0] != shape[1] or shape[0] < 3 or (shape[0] - 1) & (shape[0] - 2) \
                or own is None or base is None or np.shape(base) != tuple(shape) \
                or parent is not None:
            raise ValueError("a whole tile's guessed difference bounds blob needs a square "
                             "tile's δ and heights")
        b = log8_codes(np.asarray(base, np.float64), e).astype(np.uint8)
        codes = top_edge_codes_own(blob[3:], b, lambda s: own(e, s))
        return _log8_table_ro(e)[codes.ravel()].reshape(shape).astype(np.float32)
    if flags & (DIFF | PRED) == DIFF | PRED:  # schema 23: a δ_edge below the top, guessed
        if flags & (RING | CENTRES | MIDS) or not flags & NEW_ONLY \
                or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1] \
                or shape[0] < 3 or own is None or base is None \
                or np.shape(base) != tuple(shape) or parent is None \
                or np.shape(parent) != tuple(shape):
            raise ValueError("a guessed difference bounds blob needs a level-0 tile's δ, "
                             "heights and parent")
        g = own(e)
        if g is None or np.shape(g) != tuple(shape):
            raise ValueError("an edge guess of the wrong shape")
        b = log8_codes(np.asarray(base, np.float64), e).astype(np.uint8)
        half = (shape[0] - 1) // 2
        px, py = int(parity[0]) & 1, int(parity[1]) & 1
        a = np.asarray(parent[py * half: py * half + half + 1,
                              px * half: px * half + half + 1], np.float64)
        corners = (np.searchsorted(_log8_table64(e), np.where(np.isnan(a), np.inf, a))
                   if flags & SLACK else None)  # SLACK: predicted from the parents
        out = _log8_table_ro(e)[edge_codes_own(blob[3:], b, g, corners).ravel()]
        out = out.reshape(shape).astype(np.float32)
        out[::2, ::2] = a
        return out
    if coded and not flags & NEW_ONLY:  # schema 23: a whole tile's δ, level by level
        if flags & DIFF or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1] \
                or shape[0] < 3 or (shape[0] - 1) & (shape[0] - 2) or parent is not None:
            raise ValueError("a whole tile's guessed bounds blob needs a square tile of "
                             "log8 codes and its heights")
        codes = top_codes_own(blob[3:], shape[0], lambda s: own(e, s))
        return _log8_table_ro(e)[codes.ravel()].reshape(shape).astype(np.float32)
    if coded and flags & DIFF:
        raise ValueError("a range-coded predicted bounds blob has no other shape")
    if own_ring and flags & (DIFF | CENTRES | MIDS):
        raise ValueError("a guessed ring bounds blob has no other shape")
    if own_ring:  # the ring's checks below, as a plain ring's
        flags &= ~PRED
    if coded:  # the predicted blob's checks below
        flags &= ~SLACK
    if guessed and (flags & (RING | DIFF | SLACK | MIDS) or not flags & NEW_ONLY
                    or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1]
                    or shape[0] < 3 or shape[0] % 2 == 0 or guess is None):
        raise ValueError("a guessed centres bounds blob needs a square level-0 tile's new "
                         "log8 codes and its heights")
    if flags & PRED and not guessed and not mguessed and (
            flags & (RING | DIFF | SLACK | CENTRES | MIDS) or not flags & NEW_ONLY
            or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1]
            or shape[0] < 3 or shape[0] % 2 == 0 or parent is None
            or np.shape(parent) != tuple(shape)):
        raise ValueError("a predicted bounds blob needs a square tile's new log8 codes and "
                         "its parent's values")
    if flags & MIDS and not mguessed and (
            flags & (RING | DIFF | SLACK | CENTRES) or not flags & LOG8
            or len(shape) != 2 or shape[0] != shape[1] or shape[0] < 3 or derive is None):
        raise ValueError("a mids bounds blob needs a square tile's log8 codes and its heights")
    if flags & CENTRES and (flags & (RING | DIFF | SLACK) or not flags & NEW_ONLY
                            or not flags & LOG8 or len(shape) != 2 or shape[0] != shape[1]
                            or shape[0] < 3):
        raise ValueError("a centres bounds blob needs a square tile's new log8 codes")
    body, slack = (blob[5:] if mguessed else blob[3:]), 0.0
    if flags & SLACK:  # a float32 after the exponent: only on a ring δ
        if not (flags & RING and flags & LOG8) or len(blob) < 7:
            raise ValueError("a slack needs a ring of log8 codes")
        slack = float(np.frombuffer(blob[3:7], "<f4")[0])
        if not (np.isfinite(slack) and slack >= 0):
            raise ValueError("a bounds slack must be finite and not negative")
        body = blob[7:]
    if flags & DIFF and (flags & RING or not flags & LOG8 or base is None
                         or np.shape(base) != tuple(shape)):
        raise ValueError("a difference bounds blob needs log8 codes and the tile's δ")
    T = shape[0]
    square = len(shape) == 2 and shape[0] == shape[1]
    if flags & RING and not (flags & NEW_ONLY and square and T >= 3 and derive is not None):
        raise ValueError("a ring bounds blob needs a level-0 tile's heights")
    keep = _new_flat(T) if flags & NEW_ONLY and square else None
    if flags & RING:
        rr, rc = ring_new_index(T)
        n = len(rr)
    elif flags & CENTRES:
        n = ((T - 1) // 2) ** 2
    elif mguessed:
        n = len(keep)
    elif flags & MIDS:
        n = len(mids_index(T, bool(flags & NEW_ONLY)))
    else:
        n = len(keep) if keep is not None else int(np.prod(shape))
    width = 1 if flags & LOG8 else 2
    # schema 20's payloads are range-coded (bounded by their count), the others zstd
    raw = body if coded or own_ring else zstdsafe.decompress(body, width * n, exact=True) \
        if body or not guessed else bytes(n)  # schema 23: no payload, every guess exact
    if guessed:  # each centre from the heights' guess, the other new vertices code 0
        h = (T - 1) // 2
        g = np.asarray(guess(e), np.uint8)
        if g.shape != (h, h):
            raise ValueError("a centres guess of the wrong shape")
        codes = np.zeros(len(keep), np.uint8)
        codes[_shape_index(T)[0]] = g.ravel() - np.frombuffer(raw, np.uint8)  # mod 256
        vals = _log8_table_ro(e)[codes]
    elif mguessed:  # midpoints, then centres, from the heights' guesses (header: a, off)
        codes = np.asarray(guess(e, blob[3], blob[4], np.frombuffer(raw, np.uint8)), np.uint8)
        if codes.shape != (T, T):
            raise ValueError("a mids guess of the wrong shape")
        vals = _log8_table_ro(e)[codes.ravel()[keep]]
    elif flags & PRED:  # each code from its parents' (the parent tile's corners first)
        half = (T - 1) // 2
        px, py = int(parity[0]) & 1, int(parity[1]) & 1
        a = np.asarray(parent[py * half: py * half + half + 1,
                              px * half: px * half + half + 1], np.float64)
        # log8_codes with the cached table: the smallest code ≥ each value (NaN: +inf)
        corners = np.searchsorted(_log8_table64(e), np.where(np.isnan(a), np.inf, a))
        if coded:
            lo = np.asarray(own(e), np.uint8)
            if lo.shape != (T, T):
                raise ValueError("an own-error guess of the wrong shape")
            codes = pred_codes_own(corners, raw, lo)
        else:
            codes = pred_codes(corners, np.frombuffer(raw, np.uint8))
        vals = _log8_table_ro(e)[codes.ravel()[keep]]
    elif flags & CENTRES:  # the centres as stored, the other new vertices code 0
        codes = np.zeros(len(keep), np.uint8)
        codes[_shape_index(T)[0]] = np.frombuffer(raw, np.uint8)
        vals = _log8_table_ro(e)[codes]
    elif flags & DIFF:  # + the codes of the tile's δ at the same vertices, mod 256
        b = log8_codes(np.asarray(base).ravel() if keep is None
                       else np.asarray(base).ravel()[keep], e)
        vals = _log8_table_ro(e)[b + np.frombuffer(raw, np.uint8)]
    elif own_ring:  # + the own errors' codes at the ring, mod 256
        g = np.asarray(own(e), np.uint8)
        if g.shape != (T, T):
            raise ValueError("an own-error guess of the wrong shape")
        vals = _log8_table_ro(e)[ring_codes_own(raw, g[rr, rc])]
    elif flags & LOG8:
        vals = _log8_table_ro(e)[np.frombuffer(raw, np.uint8)]
    else:
        h = np.frombuffer(raw, np.uint8).reshape(2, n).T.copy().view(np.float16).ravel()
        vals = round_up(h.astype(np.float64) * 2.0**e, np.float32)
    out = np.empty(shape, np.float32)
    if flags & MIDS and not mguessed:  # the midpoints as stored, the centres derived
        mids = np.zeros(shape, np.float32)
        mids.ravel()[mids_index(T, bool(flags & NEW_ONLY))] = vals
        out[:] = derive(None, None, mids, True, e, 0.0)
    elif flags & RING:  # the ring as stored, the rest derived and coded as stored
        out.ravel()[keep] = derive(rr, rc, vals, bool(flags & LOG8), e, slack).ravel()[keep]
    elif keep is None:
        out.ravel()[:] = vals
    else:
        out.ravel()[keep] = vals
    if flags & NEW_ONLY:
        if parent is None or parent.shape != tuple(shape):
            raise ValueError("a new-vertices-only bounds blob needs its parent's values")
        half = (T - 1) // 2
        px, py = int(parity[0]) & 1, int(parity[1]) & 1
        out[::2, ::2] = parent[py * half: py * half + half + 1, px * half: px * half + half + 1]
    return out


NORMALS_PLANAR_DXDY = 2  # metadata ``normals_layout``; absent or 1: raw interleaved bytes
NORMAL_BITS = 8  # bits per octahedral normal component the preprocess stores


def store_metadata(*, source: str, source_dtype: str, source_nodata: float | None,
                   encoding: str, grid: dict, frame: dict, quantizer: dict,
                   normals_derived: list[int], valid_samples: int, samples: int,
                   height_range: list, delta_max_finite: float, edge_max: list | None,
                   stand_in_z: float, block_delta_levels: int,
                   ring_residual: bool = False) -> dict:
    """The metadata a preprocess writes (the whole-grid one and the streaming one).

    ``normals_derived``: the levels whose normals blobs are border rings (every level of
    the grid, or none); ``ring_residual``: those rings hold their codes' differences from
    the tile's derived map (``normals_ring_residual``, schema 17).

    Examples
    --------
    >>> m = store_metadata(source="d.tif", source_dtype="int16", source_nodata=None,
    ...     encoding="raw", grid={}, frame={}, quantizer={}, normals_derived=[0, 1],
    ...     valid_samples=3, samples=4, height_range=[0, 1], delta_max_finite=0.0,
    ...     edge_max=None, stand_in_z=0.5, block_delta_levels=1)
    >>> m["nodata_fraction"], m["normals_derived"], "delta_edge" in m
    (0.25, [0, 1], False)
    """
    from geoterrain._version import __version__

    return {
        "format": "geoterrain",
        "generator": f"geoterrain {__version__}",
        "source": source,
        "source_dtype": source_dtype,
        "source_nodata": source_nodata,
        "encoding": encoding,
        "grid": grid,
        "frame": frame,
        "quantizer": quantizer,
        "normal_bits": NORMAL_BITS,
        "normals_layout": NORMALS_PLANAR_DXDY,
        # levels whose normals blobs hold only the tile's border ring (the interior is
        # the central differences of the level's decoded heights, computed on read)
        **({"normals_derived": [int(v) for v in normals_derived]} if normals_derived else {}),
        # each ring code as its difference mod 256 from the code the reader derives there
        # from the tile alone (one-sided at the border: bounds.normals.ring_guess)
        **({"normals_ring_residual": True} if normals_derived and ring_residual else {}),
        "valid_samples": valid_samples,
        "nodata_fraction": float(1.0 - valid_samples / samples),
        "height_range": height_range,
        "delta_max_finite": delta_max_finite,
        # per tile with a second δ (padding replicated, edgepad.py): [L, x, y, max of its
        # new vertices' stored δ_edge (None: +inf)]; absent without padding
        **({"delta_edge": edge_max} if edge_max is not None else {}),
        "stand_in_z": stand_in_z,
        # the root tile's block_delta blob: each block's δ_n, n = 0 … this − 1
        "block_delta_levels": block_delta_levels,
        # no timings and no clock: the same input and options give the same bytes
        # (preprocess(timings=...) and `preprocess -v` report the stages' times)
    }


def normals_to_bytes(oct8: np.ndarray) -> bytes:
    """A tile's 8-bit octahedral normals (T, T, 2) as two planes of 2-D differences
    (mod 256): neighbouring normals agree, so zstd finds ~15 % fewer bytes than in the
    raw interleaved pairs (`benchmarks/bench_size.py`; docs/lab/store-size.md).

    Examples
    --------
    >>> a = np.random.default_rng(1).integers(0, 256, (5, 5, 2)).astype(np.uint8)
    >>> bool((normals_from_bytes(normals_to_bytes(a), 5) == a).all())
    True
    """
    p = np.ascontiguousarray(np.moveaxis(np.asarray(oct8, np.uint8), -1, 0))
    d = p.copy()
    d[:, 1:, :] = p[:, 1:, :] - p[:, :-1, :]  # uint8: wraps mod 256, exactly invertible
    e = d.copy()
    e[:, :, 1:] = d[:, :, 1:] - d[:, :, :-1]
    return e.tobytes()


@lru_cache(maxsize=8)
def ring_index(T: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a T × T tile's border ring, 4T − 4 samples: the top row, the
    bottom row, then the left and the right column without their corners.

    Examples
    --------
    >>> r, c = ring_index(3)
    >>> list(zip(r.tolist(), c.tolist()))
    [(0, 0), (0, 1), (0, 2), (2, 0), (2, 1), (2, 2), (1, 0), (1, 2)]
    """
    a = np.arange(T)
    m = np.arange(1, T - 1)
    rows = np.concatenate([np.zeros(T, np.int64), np.full(T, T - 1), m, m])
    cols = np.concatenate([a, a, np.zeros(T - 2, np.int64), np.full(T - 2, T - 1)])
    rows.setflags(write=False)  # shared: cached per T
    cols.setflags(write=False)
    return rows, cols


def ring_planes(rings: np.ndarray) -> np.ndarray:
    """Rings' 8-bit codes (k, R, 2), each as two planes of first differences (mod 256):
    (k, 2R) uint8, one stored blob's bytes per row (:func:`ring_from_bytes` inverts one).

    Examples
    --------
    >>> a = np.random.default_rng(2).integers(0, 256, (3, 8, 2)).astype(np.uint8)
    >>> all((ring_from_bytes(r.tobytes()) == a[k]).all() for k, r in enumerate(ring_planes(a)))
    True
    """
    p = np.ascontiguousarray(np.asarray(rings, np.uint8).transpose(0, 2, 1))  # (k, 2, R)
    d = p.copy()
    d[:, :, 1:] = p[:, :, 1:] - p[:, :, :-1]  # uint8: wraps mod 256, exactly invertible
    return d.reshape(len(d), -1)


def ring_from_bytes(raw: bytes, residual: bool = False) -> np.ndarray:
    """One row of :func:`ring_planes` back to the ring's codes: (R, 2) uint8; with
    ``residual``, one of :func:`residual_planes` back to the ring's residuals."""
    d = np.frombuffer(raw, np.uint8).reshape(2, -1)
    if residual:
        return np.ascontiguousarray(d.T)
    return np.ascontiguousarray(np.cumsum(d, axis=1, dtype=np.uint8).T)


def residual_planes(res: np.ndarray) -> np.ndarray:
    """Rings' residuals (k, R, 2) uint8 (schema 17's ``normals_ring_residual``: each
    code's difference from the reader's guess) as two planes each, without
    :func:`ring_planes`' first differences (the residuals are mostly 0 and ±1 already:
    srtm1_japan's rings 59.8 kB so at zstd 11 against 60.4 with the differences):
    (k, 2R), one stored blob's bytes per row.

    Examples
    --------
    >>> a = np.random.default_rng(2).integers(0, 256, (3, 8, 2)).astype(np.uint8)
    >>> all((ring_from_bytes(r.tobytes(), True) == a[k]).all()
    ...     for k, r in enumerate(residual_planes(a)))
    True
    """
    r = np.asarray(res, np.uint8)
    return np.ascontiguousarray(r.transpose(0, 2, 1)).reshape(len(r), -1)


def normals_from_bytes(raw: bytes, T: int) -> np.ndarray:
    """Inverse of :func:`normals_to_bytes`: (T, T, 2) uint8."""
    e = np.frombuffer(raw, np.uint8).reshape(2, T, T)
    p = np.cumsum(np.cumsum(e, axis=2, dtype=np.uint8), axis=1, dtype=np.uint8)
    return np.ascontiguousarray(np.moveaxis(p, 0, -1))


def pack_block_errors(blocks: np.ndarray) -> bytes:
    """Every GeoMipMapping block's δ_n (nb, nb, levels), as little-endian float32
    rounded *up* (a stored δ_n is never below the exact one; +inf stays +inf), zstd.

    Examples
    --------
    >>> b = np.array([[[0.0, 0.1, np.inf]]])
    >>> back = unpack_block_errors(pack_block_errors(b), 1, 3)
    >>> bool((back >= b).all()), back[0, 0, 2]
    (True, np.float64(inf))
    """
    a = round_up(np.asarray(blocks, np.float64), np.float32).astype("<f4")
    return zstdsafe.compress_one(np.ascontiguousarray(a).tobytes(), 6)


def unpack_block_errors(blob: bytes, nb: int | tuple[int, int], levels: int) -> np.ndarray:
    """Inverse of :func:`pack_block_errors`: (nb, nb, levels) float64, or (down, across,
    levels) with ``nb`` = (down, across) (a root grid's level-0 tiles). A store may come
    from a stranger: ``ValueError`` unless the blob decodes to exactly that many values,
    each ≥ 0 (+inf allowed, NaN not)."""
    nd, na = (nb, nb) if np.ndim(nb) == 0 else nb
    raw = zstdsafe.decompress(blob, nd * na * levels * 4, exact=True)
    a = np.frombuffer(raw, "<f4").astype(np.float64).reshape(nd, na, levels)
    if not (a >= 0).all():  # NaN fails too
        raise ValueError("a block δ_n is negative or NaN")
    return a

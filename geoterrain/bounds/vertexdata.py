"""Compact, conservative storage of per-vertex bounds (δ and r) in tile blobs.

Every value is rounded *up*, so a stored δ or r is never smaller than the computed
one: every bound stays a bound (and δ = +inf, the mixed-diamond marker, stays +inf).
Blob version 1 (older stores, still read): version byte, int8 scale exponent, then
float16 times that power of two, byte-shuffled, zstd (at most 2^-10 relative above
the exact value). The preprocess uses one exponent per store and kind, so rounding is
a single monotone map and saturation survives it.

Blob version 2 (:func:`pack_bounds_v2`, issue 12's size levers): version byte, flags, int8 exponent,
then zstd of the samples kept. Flag ``NEW_ONLY``: the samples shared with the parent tile (every
other row and column) are left out and read back from the parent's decoded values, which are the
same vertices' bounds, so decoding is exact. Flag ``LOG8``: 8-bit logarithmic codes, ``LOG_STEPS``
per octave from ``2^e``, rounded *up* (code 0 is 0, code 255 is +inf): a stored value exceeds the
exact one by less than ``2^(1/LOG_STEPS) - 1`` relative, and with one ``e`` per store and kind the
map is monotone, so saturation survives it. δ is always coded so; r is too in stores written now,
its codes nested again on the coded values (:func:`geoterrain.bounds.tileblobs.radius_codes`), and
as float16 times ``2^e`` (no ``LOG8``) in stores before. Flag ``RING`` (level 0, with ``NEW_ONLY``):
only the new vertices of the tile's border ring are stored
(:func:`~geoterrain.bounds.log8codes.ring_new_index`); a reader derives the others from the tile's
decoded heights and codes them as the preprocess did (:mod:`geoterrain.bounds.leafbounds`). Flag
``DIFF`` (log8 only; a stored tile's ``delta_edge``): each code is stored as its difference mod 256
from the same vertex's code in the tile's ``delta`` blob (same ``e``): δ_edge differs from δ only
near the padding, so the payload is mostly zeros. Flag ``SLACK`` (a ``RING`` δ of a geographic
tile): a little-endian float32 s ≥ 0 follows the exponent; the reader adds it to each derived closed
form (:func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`). Flag ``CENTRES`` (schema 6, issue
51; a ``NEW_ONLY`` log8 blob, neither ``RING`` nor ``DIFF``): every new vertex but the cell centres
(odd row and column) has code 0, and only the centres are stored, in raster order
(:func:`shape_codes`): a geographic store's level-0 r, whose edge midpoints are leaves of radius 0
(srtm1_japan: 40 % fewer r bytes there). Flag ``MIDS`` (schema 12, issue 51; log8, neither ``RING``,
``DIFF``, ``SLACK`` nor ``CENTRES``; a projected or pixel store's r above level 0): the cell centres
(odd row and column) are left out of the payload, the other samples kept in raster order
(:func:`~geoterrain.bounds.log8codes.mids_index`). A centre's children are its four edge midpoints,
in the same tile, and its code is the nesting over them alone (r is not raised beyond the nesting on
these frames), so a reader derives it from the tile's decoded heights, x, y and the midpoints'
codes, as the preprocess codes it (:func:`geoterrain.bounds.leafbounds.centre_radius`). Flag
``PRED`` (schema 14, issue 51; a ``NEW_ONLY`` log8 blob with no other shape flag: δ and r above
level 0): each new vertex's code is stored as its difference mod 256 from a prediction by its
parents in the bintree (seed 002 §2.4: a saturated δ and a nested r never exceed a parent's),
centres first, then the other new vertices (:func:`~geoterrain.bounds.log8codes.pred_residuals`): a
cell centre's from the smaller code of the two corners its cell's diagonal does not join (the parent
tile's vertices), an edge midpoint's from the smaller code of the one or two cell centres beside it.
The map is a bijection whatever the codes, so decoding is exact
(:func:`~geoterrain.bounds.log8codes.pred_codes`); where the bounds hold, the payload is mostly
small numbers. ``CENTRES`` and ``PRED`` together (schema 17, issue 51; a geographic store's level-0
r, ``NEW_ONLY`` log8, no other flag): the centres of a ``CENTRES`` payload stored as (guess − code)
mod 256, the guess the code of the largest distance √(s² + Δz²) to the centre's four edge midpoints,
from the tile's decoded heights and its tile-table box
(:func:`geoterrain.bounds.leafbounds.centre_guess`; IEEE products, sums and square roots only, so
any reader gets the writer's guess bit for bit); the decode needs ``guess(e)``. ``MIDS`` and
``PRED`` together (schema 20, issue 51; a geographic store's r above level 0, ``NEW_ONLY`` log8, no
other flag): two header bytes ``a``, ``off`` follow the exponent, then every new vertex's (guess −
code) mod 256, the edge midpoints first, guessed from the tile's heights, then the cell centres,
guessed by the nesting over their decoded midpoints
(:func:`geoterrain.bounds.leafbounds.mids_residuals`); the decode needs ``guess(e, a, off,
payload)``, the tile's (T, T) codes. ``PRED`` and ``SLACK`` together (schema 20; a δ ``PRED`` blob):
the ``PRED`` values range-coded (:func:`~geoterrain.bounds.ownguess.pred_payloads_own`) in the
contexts of each vertex's gap between its parents' prediction and the code of its own error on the
tile's decoded heights (:func:`~geoterrain.bounds.ownguess.own_codes`), which bounds δ below;
``RING`` and ``PRED`` together (schema 20; a level-0 ring δ): the ring's codes less their
:func:`~geoterrain.bounds.ownguess.own_codes`, mod 256, range-coded
(:func:`~geoterrain.bounds.ownguess.ring_payloads_own`); both decodes need ``own(e)``, and any guess
decodes exactly. ``CENTRES``, ``PRED`` and ``RING`` payloads are otherwise compressed at zstd level
:data:`SHAPED_ZSTD_LEVEL` (11), a whole tile's (the top level's) and a ``DIFF`` one at 15
(``tileblobs.EDGE_ZSTD_LEVEL``), the others at 3: any zstd decoder reads each.
"""

from __future__ import annotations

import numpy as np
import zstandard

from geoterrain.bounds.log8codes import (
    _log8_table64,
    _log8_table_ro,
    _new_flat,
    _shape_index,
    log8_codes,
    mids_index,
    new_mask,
    pred_codes,
    pred_residuals,
    ring_new_index,
)
from geoterrain.bounds.ownguess import (
    edge_codes_own,
    pred_codes_own,
    ring_codes_own,
    top_codes_own,
    top_edge_codes_own,
)
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
# as the store's 512-byte pages (store.schema.SMALL_GRID)
SMALL_SHAPED_ZSTD_LEVEL = 15
SMALL_GRID_SAMPLES = 3 << 16
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
    (T, T) :func:`~geoterrain.bounds.ownguess.own_codes` from its decoded heights."""
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


def pack_bounds_v2(values: np.ndarray, e: int, log8: bool, new_only: bool,
                   cctx: zstandard.ZstdCompressor) -> bytes:
    """A version-2 blob of one tile: ``values`` are log8 codes (uint8) or scaled float16.

    Examples
    --------
    >>> a = np.abs(np.random.default_rng(0).normal(size=(5, 5)))
    >>> from geoterrain.bounds.log8codes import log8_codes, log8_exponent
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

"""Residual compression of the height pyramid (geometry-clipmap style).

Seed 000, section 2.9 (Losasso & Hoppe): finer data come from coarser data plus a
residual, ``R_l = T_l - U(T_{l-1})``, and the runtime rebuilds ``T~_l = U(T~_{l-1}) + R~_l``.
Here the pyramid is the vertex-aligned one of ``docs/conventions.md`` (level L keeps
``[::2**L, ::2**L]``, tiles of ``T = 2**t + 1`` samples sharing borders) and the coding
is *closed loop* on integer codes, so errors never accumulate down the pyramid:

1. every height becomes an int64 code ``q`` (:class:`geoterrain.quantize.Quantizer`);
2. the top tile ``(Lmax, 0, 0)`` stores its codes directly (raster-order delta);
3. every finer tile stores only the samples that are new at its level (those not on the
   parent level's grid), as residuals ``q - pred``; ``pred`` is the floor-mean of the 2
   (row / column midpoints) or 4 (cell centres, both diagonals) neighbouring samples of
   the PARENT tile's decoded codes. Samples of the parent level are copied.

Invalid samples get residual 0 (their decoded code is the prediction; in the top tile
they repeat the previous code), so they cost almost nothing.

Blob format (version 1), one blob per stored tile::

    byte 0   version (1)
    byte 1   flags: bit 0 = top tile (direct codes); bits 1-2 = mask kind
             (0 all valid, 1 all invalid, 2 mask stored); bit 3 = cubic predictor
    byte 2   t (tile size T = 2**t + 1)
    byte 3   residual stream: low nibble w = byte width (0, 1, 2, 4, 8), high nibble
             k = symbol bits (0, 1, 2, 4)
    rest     one zstd frame of: [np.packbits(valid (T, T), C order) if mask kind == 2]
             + the residual stream of the K zigzag residuals (K = T*T for the top tile,
             3h^2 + 2h otherwise):
             k = 0: the K values as w-byte little-endian ints, byte-shuffled (all byte 0s,
                    then all byte 1s, ...); nothing when w = 0 (all residuals zero);
             k > 0: ceil(K / (8 // k)) bytes of k-bit symbols min(zz, 2**k - 1), 8 // k per
                    byte from the low bits up, then for each symbol equal to 2**k - 1 (an
                    escape) zz - (2**k - 1) in the byte-shuffled w-byte form above.

Residual order: top tile, the T*T codes in raster order (delta from the previous code,
first from 0); other tiles, with h = 2**(t-1): class A (even rows, odd columns, (h+1, h)),
then class B (odd rows, even columns, (h, h+1)), then class C (odd rows, odd columns,
(h, h)), each in raster order. Arithmetic is int64 modulo 2**64.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import zstandard

from geoterrain import zstdsafe
from geoterrain.grid import footprint_counts, level_tiles
from geoterrain.predict import cubic_child, fill_level, linear_child, predict, tile_zigzag
from geoterrain.quantize import Quantizer, codes_to_heights, roundtrip, valid_codes
from geoterrain.symbols import (
    PACK_BITS,
    UINTS,
    choose_stream,
    pack_symbols,
    packed_is_tried,
    pick_stream,
    read_residuals,
    shuffled_streams,
    stream_candidates,
    zigzag,
)
from geoterrain.threads import cores_for
from geoterrain.zstdsafe import compress_many

__all__ = [
    "BLOB_VERSION",
    "encode_pyramid",
    "decode_tile",
    "decode_tile_valid",
    "tile_valid",
    "decoded_codes",
    "decoded_heights",
    "pyramid_shape",
]

BLOB_VERSION = 1
_HEADER = 4
_MASK_ALL_VALID, _MASK_ALL_INVALID, _MASK_STORED = 0, 1, 2

def _forward_fill(codes: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Invalid entries (raster order) repeat the previous valid code; leading ones the first."""
    flat, v = codes.ravel(), valid.ravel()
    if not v.any():
        return np.zeros_like(codes)
    idx = np.where(v, np.arange(v.size), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(v))
    idx[:first] = first
    return flat[idx].reshape(codes.shape)


def pyramid_shape(n_samples: int, t: int) -> tuple[int, int]:
    """Return ``(n, t_eff)`` for an N x N grid (N = 2**n + 1) and requested tile exponent t.

    Examples
    --------
    >>> pyramid_shape(4097, 6)
    (12, 6)
    >>> pyramid_shape(5, 6)
    (2, 2)
    """
    n = int(n_samples - 1).bit_length() - 1
    if n < 1 or (1 << n) + 1 != n_samples:
        raise ValueError(f"grid size {n_samples} is not 2**n + 1 with n >= 1")
    if t < 1:
        raise ValueError("t must be >= 1")
    return n, min(t, n)


def _header(top: bool, mask_kind: int, t: int, w: int, cubic: bool) -> bytes:
    return bytes((BLOB_VERSION, int(top) | (mask_kind << 1) | (int(cubic) << 3), t, w))


def _resolve_predictor(
    predictor: str, q: np.ndarray, valid: np.ndarray, te: int, lmax: int
) -> bool:
    """True for the cubic predictor. ``"auto"`` compares the zero-order entropy of the
    finest level's residuals under both predictors (on a central crop of at most
    1025 x 1025 samples) and keeps the smaller."""
    if predictor not in ("linear", "cubic", "auto"):
        raise ValueError(f"unknown predictor {predictor!r}")
    if predictor != "auto" or lmax == 0 or te < 2:
        return predictor == "cubic" and te >= 2 and lmax > 0
    a, crop = _predictor_crop(q.shape[0], te)
    return _predictor_bits(q[a : a + crop, a : a + crop], valid[a : a + crop, a : a + crop], te)


def _predictor_crop(size: int, te: int) -> tuple[int, int]:
    # the central crop of at most 1025² samples "auto" compares the predictors on
    crop = min(size, 1025)
    return ((size - crop) // 2) & ~((1 << te) - 1), crop  # tile-aligned: keeps fallbacks


def _predictor_bits(qq: np.ndarray, vv: np.ndarray, te: int) -> bool:
    # True when the cubic predictor's finest residuals have the smaller zero-order entropy
    bits = []
    for period in (None, 1 << te):
        preds = predict(qq[::2, ::2], period)
        h = 0.0
        for sl, p in zip(_CLASSES, preds, strict=True):
            zz = zigzag(np.ascontiguousarray(qq[sl] - p)[vv[sl]])
            cnt = np.bincount(np.minimum(zz, 1 << 16).astype(np.int64))
            pr = cnt[cnt > 0] / zz.size
            h += float(-(cnt[cnt > 0] * np.log2(pr)).sum())
        bits.append(h)
    return bits[1] < bits[0]


_CLASSES = (
    (slice(0, None, 2), slice(1, None, 2)),
    (slice(1, None, 2), slice(0, None, 2)),
    (slice(1, None, 2), slice(1, None, 2)),
)


# --------------------------------------------------------------------------- whole grid


def decoded_codes(
    z: np.ndarray, valid: np.ndarray, t: int, quantizer: Quantizer, predictor: str = "auto"
) -> np.ndarray:
    """Codes (N, N) int64 that decoding every tile gives, invalid samples included.

    Vectorised level by level on the full grid: valid samples keep their code; invalid
    samples of the top level repeat the previous code (raster order), invalid samples of
    finer levels get the prediction from the coarser level. ``predictor`` as for
    :func:`encode_pyramid`.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[1, 1] = False
    >>> int(decoded_codes(z, v, 6, Quantizer("int"))[1, 1])  # top tile: previous code
    3
    """
    valid = np.asarray(valid, dtype=bool)
    n, te = pyramid_shape(valid.shape[0], t)
    lmax = n - te
    d = valid_codes(z, valid, quantizer)  # heights_to_codes(where(valid, z, 0))
    return _decoded_codes(d, valid, te, lmax, _resolve_predictor(predictor, d, valid, te, lmax))


def _decoded_codes(d: np.ndarray, valid: np.ndarray, te: int, lmax: int, cubic: bool):
    """In place on the codes ``d``: what tile decoding gives at invalid samples."""
    s = 1 << lmax
    d[::s, ::s] = _forward_fill(d[::s, ::s], valid[::s, ::s])
    for lev in range(lmax - 1, -1, -1):  # compiled: the rule of predict, in place
        fill_level(d, valid, 1 << lev, (1 << te) if cubic else 0)
    return d


def decoded_heights(
    z: np.ndarray,
    valid: np.ndarray,
    quantizer: Quantizer,
    t: int | None = None,
    predictor: str = "auto",
) -> np.ndarray:
    """Heights (N, N) float64 exactly as decoding every tile gives them.

    Valid samples decode to ``codes_to_heights(heights_to_codes(z))`` whatever the
    pyramid (closed-loop coding). Invalid samples are NaN, unless ``t`` is given: then
    they hold exactly the (meaningless) values tile decoding produces (with the same
    ``predictor`` as the encoding).

    Examples
    --------
    >>> qz = Quantizer("quantized", 0.2, 0.0, 0.1)
    >>> decoded_heights(np.array([[0.33]]), np.array([[True]]), qz).round(6).tolist()
    [[0.4]]
    """
    valid = np.asarray(valid, dtype=bool)
    if t is not None:
        d = decoded_codes(z, valid, t, quantizer, predictor)
        return codes_to_heights(d, quantizer)
    return roundtrip(z, valid, quantizer)  # the same values, in one compiled pass


# --------------------------------------------------------------------------- encoding


def encode_pyramid(
    z: np.ndarray,
    valid: np.ndarray,
    t: int,
    quantizer: Quantizer,
    level: int = 19,
    progress: Callable[[int, int], None] | None = None,
    predictor: str = "auto",
) -> dict[tuple[int, int, int], bytes]:
    """Encode every stored tile of the pyramid.

    Parameters
    ----------
    z : (N, N) float64
        Heights (source units); values at invalid samples are ignored.
    valid : (N, N) bool
    t : int
        Tile exponent (T = 2**t + 1; shrinks to n when n < t).
    quantizer : Quantizer
    level : int
        zstd level (19 for preprocessing; 3-9 are 5-10x faster for ~2 % more bytes).
        Each level's tiles are compressed in one zstd call on every core.
    progress : callable, optional
        ``progress(done_levels, total_levels)`` after each level.
    predictor : {"auto", "linear", "cubic"}
        U(.) of the residuals (:mod:`geoterrain.predict`): linear floor-means, or 4-point
        interpolatory weights (better on rough, high-entropy data); ``"auto"`` picks the
        one with the smaller estimated residual entropy. Recorded in every blob.

    Returns
    -------
    dict
        ``{(L, x, y): blob}`` for every tile whose footprint holds a valid sample.

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> sorted(encode_pyramid(z, v, 1, Quantizer("int")))
    [(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 0)]
    """
    valid = np.asarray(valid, dtype=bool)
    z = np.asarray(z, dtype=np.float64)
    if z.shape != valid.shape or z.ndim != 2 or z.shape[0] != z.shape[1]:
        raise ValueError("z and valid must be the same square (N, N) shape")
    n, te = pyramid_shape(z.shape[0], t)
    lmax = n - te
    out: dict[tuple[int, int, int], bytes] = {}
    if not valid.any():
        return out
    d = valid_codes(z, valid, quantizer)  # heights_to_codes(where(valid, z, 0))
    cubic = _resolve_predictor(predictor, d, valid, te, lmax)
    d = _decoded_codes(d, valid, te, lmax, cubic)

    out[(lmax, 0, 0)] = _encode_top(d, valid, te, lmax, cubic, level)
    with cores_for(d.size):  # small grids on one thread (geoterrain/threads.py)
        _encode_levels(out, d, valid, n, te, lmax, cubic, level, progress)
    return out


def _encode_top(d, valid, te, lmax, cubic, level) -> bytes:
    # the top tile: raster-order delta of the (forward-filled) decoded codes
    s = 1 << lmax
    r = np.diff(d[::s, ::s].ravel(), prepend=np.int64(0))
    head, payload = _pack(r, valid[::s, ::s], True, te, cubic)
    return head + _compressor(level).compress(payload)


def _encode_levels(out, d, valid, n, te, lmax, cubic, level, progress, counts=None) -> None:
    """Blobs of every non-top stored tile into ``out`` (stream choice per tile, then zstd
    of the whole level on every core). ``counts``: which tiles are stored (> 0), per
    level (default :func:`footprint_counts` of ``valid``)."""
    tt = (1 << te) + 1
    period = (1 << te) if cubic else None
    if progress is not None:
        progress(1, lmax + 1)

    if counts is None:
        counts = footprint_counts(valid, te)
    h = 1 << (te - 1)
    for lev in range(lmax - 1, -1, -1):
        s = 1 << lev
        nt = 1 << (n - lev - te)
        zz = np.empty((nt, nt, 2 * h * (h + 1) + h * h), np.uint64)
        zmax = np.empty((nt, nt), np.uint64)
        esc = np.empty((nt, nt, len(PACK_BITS)), np.int64)  # the kernel counts k = 1, 2, 4
        tile_zigzag(d, s, h, period or 0, zz, zmax, esc)  # the residuals of predict
        # k-bit packs only for the tiles where choose_stream would try them
        packs = {}
        for c, k in enumerate(PACK_BITS):
            ys, xs = np.nonzero(packed_is_tried(esc[..., c], zz.shape[2]))
            rows = {}
            if len(ys):
                packed, _ = pack_symbols(zz[ys, xs], k)
                rows = dict(zip(zip(ys.tolist(), xs.tolist(), strict=True), packed,
                                strict=True))
            packs[k] = (rows, esc[..., c])
        vt = level_tiles(valid, te, lev)
        nvalid = vt.sum(axis=(2, 3))
        bulk = shuffled_streams(zz, zmax, esc, (counts[lev] > 0) & (nvalid == tt * tt))

        keys, heads, payloads, pending = [], [], [], []
        for y, x in zip(*np.nonzero(counts[lev]), strict=True):
            yx = (int(y), int(x))
            if yx in bulk:  # all valid, nothing to compare: the shuffled stream
                code, stream = bulk[yx]
                keys.append((lev, int(x), int(y)))
                heads.append(_header(False, _MASK_ALL_VALID, te, code, cubic))
                payloads.append(stream)
                continue
            kind = (
                _MASK_ALL_VALID
                if nvalid[y, x] == tt * tt
                else _MASK_ALL_INVALID
                if nvalid[y, x] == 0
                else _MASK_STORED
            )
            cands = stream_candidates(zz[y, x], int(zmax[y, x]),
                                      {k: (p[0].get(yx), p[1][y, x]) for k, p in packs.items()})
            mask = np.packbits(vt[y, x]).tobytes() if kind == _MASK_STORED else b""
            pending.append((len(keys), kind, mask, cands))
            keys.append((lev, int(x), int(y)))
            heads.append(b"")
            payloads.append(b"")
        # choose_stream's probes (zstd level 3) of the whole level in one call, every core
        probes = iter(len(f) for f in compress_many(
            [c[1] for *_, cands in pending if len(cands) > 1 for c in cands], 3))
        for pos, kind, mask, cands in pending:
            code, stream = cands[0] if len(cands) == 1 else \
                pick_stream(cands, [next(probes) for _ in cands])
            heads[pos] = _header(False, kind, te, code, cubic)
            payloads[pos] = mask + stream
        # zstd of the whole level in one call, on every core (identical to one by one)
        frames = compress_many(payloads, level)
        out.update((k, h + f) for k, h, f in zip(keys, heads, frames, strict=True))
        del zz, packs, vt
        if progress is not None:
            progress(lmax - lev + 1, lmax + 1)


_TLS = threading.local()


def _compressor(level: int) -> zstandard.ZstdCompressor:
    """This thread's zstd compressor at ``level`` (a compressor is not thread-safe)."""
    cache = getattr(_TLS, "cctx", None)
    if cache is None:
        cache = _TLS.cctx = {}
    c = cache.get(level)
    if c is None:
        c = cache[level] = zstandard.ZstdCompressor(level=level)
    return c


def _pack(r: np.ndarray, vt: np.ndarray, top: bool, te: int, cubic: bool) -> tuple[bytes, bytes]:
    nv = int(vt.sum())
    kind = _MASK_ALL_VALID if nv == vt.size else _MASK_ALL_INVALID if nv == 0 else _MASK_STORED
    zz = zigzag(np.ascontiguousarray(r.ravel()))
    packs = {k: pack_symbols(zz, k) for k in PACK_BITS}
    code, stream = choose_stream(zz, int(zz.max()) if zz.size else 0, packs, _compressor(3))
    payload = (np.packbits(vt).tobytes() if kind == _MASK_STORED else b"") + stream
    return _header(top, kind, te, code, cubic), payload


# --------------------------------------------------------------------------- decoding


def _parse(blob: bytes, t: int | None = None) -> tuple[bool, int, int, int, bytes]:
    """Header fields and the decompressed payload, refusing anything malformed.

    The payload's size is bounded before it is allocated (mask bytes + at most 9
    bytes per residual), and ``t``, when given, must match the blob's tile size.
    """
    if len(blob) < _HEADER or blob[0] != BLOB_VERSION:
        raise ValueError(f"not a version-{BLOB_VERSION} tile blob")
    top, kind, te, w = bool(blob[1] & 1), (blob[1] >> 1) & 3, blob[2], blob[3]
    if blob[1] & ~0b1111 or kind > _MASK_STORED or not 1 <= te <= 15 or (t is not None and te != t):
        raise ValueError("tile blob header does not match the store's grid")
    if (w & 15) not in UINTS and (w & 15) != 0 or (w >> 4) not in (0, *PACK_BITS):
        raise ValueError("tile blob names an unknown residual stream")
    tt = (1 << te) + 1
    # the largest payload: the mask, k-bit symbols and 8-byte escapes for every residual
    limit = (tt * tt + 7) // 8 + tt * tt + 8 * tt * tt
    payload = zstdsafe.decompress(blob[_HEADER:], limit)
    return top, kind, te, w, payload


def tile_valid(blob: bytes, t: int | None = None) -> np.ndarray:
    """The tile's (T, T) valid mask stored in its blob.

    Examples
    --------
    >>> z = np.zeros((3, 3)); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> blob = encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)]
    >>> tile_valid(blob).sum()
    np.int64(8)
    """
    _, kind, te, _, payload = _parse(blob, t)
    return _mask(kind, te, payload)


def _mask(kind: int, te: int, payload: bytes) -> np.ndarray:
    tt = (1 << te) + 1
    if kind == _MASK_ALL_VALID:
        return np.ones((tt, tt), bool)
    if kind == _MASK_ALL_INVALID:
        return np.zeros((tt, tt), bool)
    nb = (tt * tt + 7) // 8
    bits = np.unpackbits(np.frombuffer(payload, np.uint8, nb), count=tt * tt)
    return bits.reshape(tt, tt).astype(bool)


def decode_tile(
    blob: bytes,
    parent_codes: np.ndarray | None,
    quantizer: Quantizer,
    tile_xy_parity: tuple[int, int] = (0, 0),
    t: int | None = None,
) -> np.ndarray:
    """Decode one tile's (T, T) int64 codes.

    Parameters
    ----------
    blob : bytes
        The tile's blob (from :func:`encode_pyramid`).
    parent_codes : (T, T) int64 or None
        The parent tile's decoded codes (the whole tile: the cubic predictor reads one
        sample beyond the child's quadrant); None for the top tile.
    quantizer : Quantizer
        Same as for encoding (codes are quantizer-independent, kept for symmetry).
    tile_xy_parity : (int, int)
        ``(x % 2, y % 2)`` of the tile: which quadrant of the parent it covers.
    t : int or None
        The store's tile exponent; a blob of another tile size is refused.

    Returns
    -------
    (T, T) int64 codes; heights via :func:`codes_to_heights`.

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> blobs = encode_pyramid(z, v, 1, Quantizer("int"))
    >>> top = decode_tile(blobs[(1, 0, 0)], None, Quantizer("int"))
    >>> decode_tile(blobs[(0, 1, 0)], top, Quantizer("int"), (1, 0)).tolist()
    [[2, 3, 4], [7, 8, 9], [12, 13, 14]]
    """
    del quantizer
    return _decode_codes(blob, parent_codes, tile_xy_parity, *_parse(blob, t))


def decode_tile_valid(blob: bytes, parent_codes: np.ndarray | None,
                      tile_xy_parity: tuple[int, int] = (0, 0), t: int | None = None,
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The tile's codes (:func:`decode_tile`) and valid mask (:func:`tile_valid`), its
    payload decompressed once.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> codes, valid = decode_tile_valid(encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)],
    ...                                  None)
    >>> codes[1].tolist(), int(valid.sum())
    ([3, 4, 5], 8)
    """
    top, kind, te, w, payload = _parse(blob, t)
    return (_decode_codes(blob, parent_codes, tile_xy_parity, top, kind, te, w, payload),
            _mask(kind, te, payload))


def _decode_codes(blob: bytes, parent_codes: np.ndarray | None, tile_xy_parity: tuple[int, int],
                  top: bool, kind: int, te: int, w: int, payload: bytes) -> np.ndarray:
    tt = (1 << te) + 1
    off = ((tt * tt + 7) // 8) if kind == _MASK_STORED else 0
    body = payload[off:]
    if top:
        r = read_residuals(body, w, tt * tt)
        return np.cumsum(r).reshape(tt, tt)
    if parent_codes is None:
        raise ValueError("a non-top tile needs its parent's decoded codes")
    h = 1 << (te - 1)
    px, py = int(tile_xy_parity[0]) & 1, int(tile_xy_parity[1]) & 1
    parent = np.asarray(parent_codes, np.int64)
    if parent.shape != (tt, tt):
        raise ValueError(f"parent codes must be ({tt}, {tt})")
    r = read_residuals(body, w, 3 * h * h + 2 * h)
    out = np.empty((tt, tt), np.int64)
    if blob[1] & 8:  # cubic: the parent tile's own predictions (with its edge fallbacks)
        cubic_child(np.ascontiguousarray(parent), py * h, px * h, h, r, out)
        return out
    c = np.ascontiguousarray(parent[py * h: py * h + h + 1, px * h: px * h + h + 1])
    linear_child(c, h, r, out)
    return out

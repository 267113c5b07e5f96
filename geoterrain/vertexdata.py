"""Compact, conservative storage of per-vertex bounds (δ and r) in tile blobs.

Each value is stored as float16 times a per-tile power-of-two scale, rounded
*up*, so a stored δ or r is never smaller than the computed one: every bound
stays a bound (and δ = +inf, the mixed-diamond marker, stays +inf). float16
keeps 11 significant bits, so a stored bound exceeds the exact one by at most
2^-10 relative. The preprocess uses one scale per store and kind, so rounding
is a single monotone map and saturation survives it; sphere nesting holds to
2^-10 relative (the LOD's upward-closure pass keeps meshes conforming anyway).
Blob: version byte, int8 scale exponent, then the byte-shuffled float16 array
compressed with zstd.
"""

from __future__ import annotations

import numpy as np
import zstandard

from geoterrain import zstdsafe
from geoterrain.rounding import round_up

VERSION = 1
_F16_MAX = 32768.0  # keep the scaled maximum well inside float16's finite range


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


def decode_bounds(blob: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`encode_bounds`: float32 values ≥ the encoded ones."""
    if len(blob) < 2 or blob[0] != VERSION:
        raise ValueError("not a bounds blob of a known version")
    k = int(np.int8(np.uint8(blob[1])))
    n = int(np.prod(shape))
    raw = zstdsafe.decompress(blob[2:], 2 * n, exact=True)  # bounded: never a bomb
    planes = np.frombuffer(raw, np.uint8).reshape(2, n)
    h = planes.T.copy().view(np.float16).reshape(shape)
    # float32 output: round up again so the bound survives the cast
    return round_up(h.astype(np.float64) * 2.0**k, np.float32)

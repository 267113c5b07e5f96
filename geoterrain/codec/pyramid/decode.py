"""The height pyramid's decoder (:mod:`geoterrain.codec.pyramid`): one tile's codes and
valid mask from its blob and its parent's decoded codes (:func:`decode_tile_valid`, the
reader's one call), its mask alone, and the predictor a blob records.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.codec import entropy
from geoterrain.codec.entropy import MASK_ALL_VALID, MASK_STORED
from geoterrain.codec.predict import cubic_child, linear_child
from geoterrain.codec.pyramid.layout import _EDGES, _FILLED, _parse, top_bins
from geoterrain.codec.quantize import Quantizer


def blob_predictor(blob: bytes) -> str:
    """The predictor a tile blob records: ``"cubic"`` or ``"linear"`` (every blob of a
    store records the same).

    Examples
    --------
    >>> from geoterrain.codec.pyramid import encode_root
    >>> from geoterrain.codec.quantize import valid_codes
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> c = valid_codes(z, v, Quantizer("int"))
    >>> blob_predictor(encode_root(c, v, 2, True)), blob_predictor(encode_root(c, v, 2, False))
    ('cubic', 'linear')
    """
    return "cubic" if _parse(blob)[3] else "linear"


_NOT_A_STREAM = "tile blob's stream has bytes past its end (not one the encoder writes)"


def tile_valid(blob: bytes, t: int | None = None) -> np.ndarray:
    """The tile's (T, T) valid mask stored in its blob.

    Examples
    --------
    >>> from geoterrain.codec.pyramid import encode_pyramid
    >>> z = np.zeros((3, 3)); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> blob = encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)]
    >>> tile_valid(blob).sum()
    np.int64(8)
    """
    _, kind, te, _, w, data = _parse(blob, t)
    if w >= 0:
        return _wide_mask(kind, te, data)
    return entropy.decode_mask(data, (1 << te) + 1, kind)


def _wide_mask(kind: int, te: int, data: np.ndarray) -> np.ndarray:
    tt = (1 << te) + 1
    if kind != MASK_STORED:
        return np.full((tt, tt), kind == MASK_ALL_VALID)
    return np.unpackbits(data[:(tt * tt + 7) // 8], count=tt * tt).reshape(tt, tt).astype(bool)


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
        Same as for encoding (its residual bins).
    tile_xy_parity : (int, int)
        ``(x % 2, y % 2)`` of the tile: which quadrant of the parent it covers.
    t : int or None
        The store's tile exponent; a blob of another tile size is refused.

    Returns
    -------
    (T, T) int64 codes; heights via :func:`codes_to_heights`.

    Examples
    --------
    >>> from geoterrain.codec.pyramid import encode_pyramid
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> blobs = encode_pyramid(z, v, 1, Quantizer("int"))
    >>> top = decode_tile(blobs[(1, 0, 0)], None, Quantizer("int"))
    >>> decode_tile(blobs[(0, 1, 0)], top, Quantizer("int"), (1, 0)).tolist()
    [[2, 3, 4], [7, 8, 9], [12, 13, 14]]
    """
    return decode_tile_valid(blob, parent_codes, tile_xy_parity, t, quantizer.bins)[0]


def decode_tile_valid(blob: bytes, parent_codes: np.ndarray | None,
                      tile_xy_parity: tuple[int, int] = (0, 0), t: int | None = None,
                      bins: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The tile's codes (:func:`decode_tile`) and valid mask (:func:`tile_valid`), its
    payload decompressed once; ``bins``: the quantizer's residual bins.

    Examples
    --------
    >>> from geoterrain.codec.pyramid import encode_pyramid
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> codes, valid = decode_tile_valid(encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)],
    ...                                  None)
    >>> codes[1].tolist(), int(valid.sum())
    ([3, 4, 5], 8)
    """
    top, kind, te, cubic, w, data = _parse(blob, t)
    if top:
        codes, valid, exact = entropy.decode_top(data, te, cubic, kind, top_bins(bins),
                                                 bool(blob[1] & _FILLED),
                                                 bool(blob[1] & _EDGES))
        if not exact:
            raise ValueError(_NOT_A_STREAM)
        return codes, valid
    if parent_codes is None:
        raise ValueError("a non-top tile needs its parent's decoded codes")
    tt, h = (1 << te) + 1, 1 << (te - 1)
    px, py = int(tile_xy_parity[0]) & 1, int(tile_xy_parity[1]) & 1
    parent = np.ascontiguousarray(parent_codes, np.int64)
    if parent.shape != (tt, tt):
        raise ValueError(f"parent codes must be ({tt}, {tt})")
    if w < 0:  # range-coded: the predictions are applied as the residuals are decoded
        out, valid, exact = entropy.decode_tile(data, parent, px, py, cubic, kind, bins)
        if not exact:
            raise ValueError(_NOT_A_STREAM)
        return out, valid
    # a wide blob: every residual, then the predictions (one compiled call)
    valid = _wide_mask(kind, te, data)
    off = (tt * tt + 7) // 8 if kind == MASK_STORED else 0
    out = np.empty((tt, tt), np.int64)
    _wide_child(data, off, w, 3 * h * h + 2 * h, parent, py, px, h, cubic, out)
    return out, valid


@njit(cache=True, nogil=True)
def _wide_child(data, off, w, n, parent, py, px, h, cubic, out):
    """A wide blob's child codes: its n residuals, each stored as w little-endian bytes
    in w byte planes (``data[off + b·n + k]`` the b-th byte of residual k), zig-zag
    coded, added to the parent's predictions (cubic: the parent tile's own, with its
    edge fallbacks; linear: from the quadrant the child covers)."""
    r = np.empty(n, np.int64)
    d = data[off:off + w * n]
    if w == 8:  # a residual may fill 64 bits: unsigned, shifted logically
        one = np.uint64(1)
        for k in range(n):
            v = np.uint64(0)
            for b in range(8):
                v |= np.uint64(d[b * n + k]) << np.uint64(8 * b)
            r[k] = np.int64(v >> one) ^ -np.int64(v & one)
    elif w == 0:
        r[:] = 0
    else:  # 1, 2 or 4 bytes: each plane read in order (a loop over the bytes of one
        # residual, w unknown to the compiler, took 8× as long)
        for k in range(n):
            v = np.int64(d[k])
            if w >= 2:
                v |= np.int64(d[n + k]) << 8
            if w == 4:
                v |= (np.int64(d[2 * n + k]) << 16) | (np.int64(d[3 * n + k]) << 24)
            r[k] = (v >> 1) ^ -(v & 1)
    if cubic:
        cubic_child(parent, py * h, px * h, h, r, out)
    else:
        linear_child(np.ascontiguousarray(parent[py * h:py * h + h + 1,
                                                 px * h:px * h + h + 1]), h, r, out)

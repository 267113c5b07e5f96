"""The height pyramid's layout: its shape (a square of 2**n + 1 samples, or a grid of
root tiles sharing their borders; tiles of T = 2**t + 1 samples), the top tile's residual
bins, and a tile blob's header, written and parsed (the encoder's and the decoder's
common ground: :mod:`geoterrain.codec.pyramid`).

Blob format (version 3), one blob per stored tile::

    byte 0   version (3; version 2, of store schemas 5 to 7, predicted a cell centre
             along its column only, and is refused)
    byte 1   flags: bit 0 = top tile; bits 1-2 = mask kind (0 all valid, 1 all
             invalid, 2 mask stored); bit 3 = cubic predictor; bit 4 = wide; bit 5
             = filled (a top tile with a stored mask: its invalid samples filled
             outward after each of its levels; always set now, absent in older
             stores, whose invalid samples keep their predictions); bit 6 = edges
             (with bit 5, a root of a grid of several root tiles: each level's edges
             filled along themselves first, so two roots decode the same codes on the
             edge they share: :func:`geoterrain.codec.predict.fill_edges_first`)
    byte 2   t (tile size T = 2**t + 1)
    rest     the range-coded stream of :mod:`geoterrain.codec.entropy`: the (T, T) valid mask
             when stored, then the zigzag residuals: for the top tile the 4 corners
             (deltas, raster order) and then its levels of stride 2**(t-1) … 1; for the
             other tiles, with h = 2**(t-1), class A (even rows, odd columns, (h+1, h)),
             class B (odd rows, even columns, (h, h+1)), class C (odd rows, odd columns,
             (h, h)), each in raster order, invalid samples skipped.
    wide     (a non-top tile of a lossless float store, whose residuals are float bit
             patterns of 10-30 bits: the range coder's ~7 % saving there costs 3 times
             zstd's time, docs/lab/height-codec.md) byte 3 = w, the residuals' byte width
             (0, 1, 2, 4, 8); then one zstd frame of [np.packbits(mask) when stored] +
             the 3h² + 2h zigzag residuals (0 at invalid samples) as w-byte
             little-endian values, byte-shuffled (all byte 0s, then all byte 1s, ...).

Arithmetic is int64 modulo 2**64.
"""

from __future__ import annotations

import numpy as np

from geoterrain.codec.entropy import MASK_ALL_INVALID, MASK_ALL_VALID, MASK_STORED
from geoterrain.core.zstdsafe import decompress

BLOB_VERSION = 3  # 2: cell centres predicted along their column only (schemas 5-7)


_HEADER = 3


_WIDE, _WIDE_LEVEL = 16, 6  # the wide blobs' flag bit and zstd level


_FILLED = 32  # the top tile's flag bit: its invalid samples filled outward (_top_fill)


_EDGES = 64  # with _FILLED: a root of several, its edges filled first (fill_edges_first)


def top_bins(bins: int) -> int:
    """The residual bins of the top tile's own grids: the largest odd width ≤ 3/4 of the
    other tiles' ``bins``. Every finer
    sample is predicted from the top tile's, which are few: SZ3 halves its error bound
    on its coarse levels for the same reason. On the six shared DEMs at ε = 0.5, 1 and
    2 (docs/lab/height-codec.md): fewer bytes than 1/2 or 1/4 in 14 cells, as many in 4;
    against no tightening, 16–20 % fewer on the smallest pyramid (St Helens, whose top
    tile holds a sixteenth of the samples) and at most 2.8 % more elsewhere.

    Examples
    --------
    >>> [top_bins(w) for w in (1, 3, 5, 9, 15, 39)]
    [1, 1, 3, 5, 11, 29]
    """
    return max(1, ((3 * bins) // 4 - 1) | 1)


def _period(te: int, cubic: bool) -> int:
    # fill_level's P: the parent tile's intervals for the cubic predictor, 0 for linear
    return (1 << te) if cubic else 0


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


def roots_shape(shape: tuple[int, int], t: int,
                roots: tuple[int, int] | None = None) -> tuple[int, int]:
    """``(n, t_eff)`` of a grid of ``roots`` (across, down) root tiles of 2**n samples a
    side, sharing their borders: ``shape`` = (down·2**n + 1, across·2**n + 1), the roots'
    extent (:attr:`geoterrain.core.grid.Grid.extent`); None: one square
    (:func:`pyramid_shape`).

    Examples
    --------
    >>> roots_shape((1025, 2049), 6, (2, 1))
    (10, 6)
    """
    rx, ry = roots or (1, 1)
    R, C = shape
    if rx < 1 or ry < 1 or (R - 1) % ry or (C - 1) % rx or (R - 1) // ry != (C - 1) // rx:
        raise ValueError(f"a {R} × {C} grid is not {rx} × {ry} square roots sharing borders")
    return pyramid_shape((R - 1) // ry + 1, t)


def _root_windows(a: np.ndarray, roots: tuple[int, int], te: int):
    """(x, y, window) of each root in the top level ``a`` (views), row by row."""
    T = 1 << te
    for y in range(roots[1]):
        for x in range(roots[0]):
            yield x, y, a[y * T:(y + 1) * T + 1, x * T:(x + 1) * T + 1]


def _header(top: bool, mask_kind: int, t: int, cubic: bool, w: int | None = None,
            edges: bool = False) -> bytes:
    # a top tile with invalid samples always has them filled outward (_top_fill), edges
    # first for a root of several
    flags = int(top) | (mask_kind << 1) | (int(cubic) << 3)
    if top and edges and mask_kind != MASK_ALL_VALID:
        flags |= _FILLED | _EDGES
    elif top and mask_kind == MASK_STORED:
        flags |= _FILLED
    if w is None:
        return bytes((BLOB_VERSION, flags, t))
    return bytes((BLOB_VERSION, flags | _WIDE, t, w))  # a wide blob


def _parse(blob: bytes, t: int | None = None) -> tuple[bool, int, int, bool, int, np.ndarray]:
    """Header fields (top, mask kind, t, cubic, w: -1 unless wide) and the stream,
    refusing a malformed header; ``t``, when given, must match the blob's tile size.
    Any range-coded stream decodes to some codes, in bounded time; the decoders then
    refuse one with bytes past its end. A wide blob's frame must hold exactly its size."""
    if len(blob) < _HEADER or blob[0] != BLOB_VERSION:
        raise ValueError(f"not a version-{BLOB_VERSION} tile blob")
    top, kind, te = bool(blob[1] & 1), (blob[1] >> 1) & 3, blob[2]
    edges = bool(blob[1] & _EDGES)
    filled_ok = not blob[1] & _FILLED or (top and (kind == MASK_STORED or edges
                                                  and kind == MASK_ALL_INVALID))
    filled_ok = filled_ok and (not edges or bool(blob[1] & _FILLED))
    if blob[1] & ~0b1111111 or kind > MASK_STORED or not 1 <= te <= 15 or not filled_ok \
            or (t is not None and te != t):
        raise ValueError("tile blob header does not match the store's grid")
    if not blob[1] & _WIDE:
        return top, kind, te, bool(blob[1] & 8), -1, np.frombuffer(blob, np.uint8,
                                                                   offset=_HEADER)
    if top or len(blob) < _HEADER + 1 or blob[_HEADER] not in (0, 1, 2, 4, 8):
        raise ValueError("tile blob header does not match the store's grid")
    w, tt, h = blob[_HEADER], (1 << te) + 1, 1 << (te - 1)
    size = ((tt * tt + 7) // 8 if kind == MASK_STORED else 0) + w * (3 * h * h + 2 * h)
    payload = decompress(blob[_HEADER + 1:], size, exact=True)  # bounded: never a bomb
    return top, kind, te, bool(blob[1] & 8), w, np.frombuffer(payload, np.uint8)

"""Bounded zstd decompression: a stored frame never decodes to more than expected.

A zstd frame may declare its content size, and the decompressor then allocates
that much whatever ``max_output_size`` says: a 0.5 MB "bomb" can ask for 16 GiB.
Every blob of a store has a size known from the grid and its kind, so the
declared size is checked first, and frames without one are decoded with a cap.
"""

from __future__ import annotations

import zstandard

__all__ = ["decompress"]


def decompress(data: bytes, limit: int, exact: bool = False) -> bytes:
    """Decompress one zstd frame of at most ``limit`` bytes (exactly, if ``exact``).

    Raises ``ValueError`` (before allocating) when the frame declares or
    produces more, and for a damaged frame.

    Examples
    --------
    >>> frame = zstandard.ZstdCompressor().compress(bytes(1000))
    >>> len(decompress(frame, 1000, exact=True))
    1000
    >>> try:
    ...     decompress(frame, 999)
    ... except ValueError as e:
    ...     print(e)
    zstd frame declares 1000 bytes, more than the 999 expected
    """
    limit = int(limit)
    try:
        declared = zstandard.frame_content_size(data)
    except zstandard.ZstdError:
        raise ValueError("not a zstd frame") from None
    if declared > limit:
        raise ValueError(f"zstd frame declares {declared} bytes, more than the {limit} expected")
    try:
        out = zstandard.ZstdDecompressor().decompress(data, max_output_size=max(limit, 1))
    except zstandard.ZstdError as exc:
        raise ValueError(f"damaged zstd frame ({exc})") from None
    if len(out) > limit or (exact and len(out) != limit):
        raise ValueError(f"zstd frame holds {len(out)} bytes, expected "
                         f"{'exactly' if exact else 'at most'} {limit}")
    return out

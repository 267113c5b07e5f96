"""zstd for stores: bounded decompression, and many frames compressed in one call.

Decompression: a stored frame never decodes to more than expected.

A zstd frame may declare its content size, and the decompressor then allocates
that much whatever ``max_output_size`` says: a 0.5 MB "bomb" can ask for 16 GiB.
Every blob of a store has a size known from the grid and its kind, so the
declared size is checked first, and frames without one are decoded with a cap.

Frames are written without zstd's 4-byte magic number (:func:`compress_one`,
:func:`compress_many`; store schema 10, issue 51): a store frames every blob and
catalog row itself, with a checksum, so the magic only cost 4 bytes a blob (0.2–0.8 % of
the shared DEMs' stores); the metadata's row alone keeps it (docs/store.md). The rest
of the frame is zstd's own format unchanged (zstd's "magicless" format is exactly a
frame less its magic), and :func:`decompress` reads both: a frame that starts with the
magic as it is, any other with the magic put back. No frame without the magic starts
with it: its first byte, the frame header descriptor, would have the reserved bit 3
set, and zstd refuses that.
"""

from __future__ import annotations

import os
import threading

import zstandard

__all__ = ["MAGIC", "compress_many", "compress_one", "decompress", "strip_magic"]

MAGIC = b"\x28\xb5\x2f\xfd"  # zstd's frame magic number, little-endian 0xFD2FB528


def decompress(data: bytes, limit: int, exact: bool = False) -> bytes:
    """Decompress one zstd frame of at most ``limit`` bytes (exactly, if ``exact``).

    Raises ``ValueError`` (before allocating) when the frame declares or
    produces more, and for a damaged frame.

    Examples
    --------
    >>> frame = zstandard.ZstdCompressor().compress(bytes(1000))
    >>> len(decompress(frame, 1000, exact=True)), len(decompress(frame[4:], 1000))
    (1000, 1000)
    >>> try:
    ...     decompress(frame, 999)
    ... except ValueError as e:
    ...     print(e)
    zstd frame declares 1000 bytes, more than the 999 expected
    """
    limit = int(limit)
    if bytes(data[:4]) != MAGIC:  # a frame as a store writes it: the magic put back
        data = MAGIC + bytes(data)
    try:
        declared = zstandard.frame_content_size(data)
    except zstandard.ZstdError:
        raise ValueError("not a zstd frame") from None
    if declared > limit:
        raise ValueError(f"zstd frame declares {declared} bytes, more than the {limit} expected")
    try:
        out = _decompressor().decompress(data, max_output_size=max(limit, 1))
    except zstandard.ZstdError as exc:
        raise ValueError(f"damaged zstd frame ({exc})") from None
    if len(out) > limit or (exact and len(out) != limit):
        raise ValueError(f"zstd frame holds {len(out)} bytes, expected "
                         f"{'exactly' if exact else 'at most'} {limit}")
    return out


_TLS = threading.local()


def _decompressor() -> zstandard.ZstdDecompressor:
    """This thread's decompressor (one is not thread-safe; making one for each frame
    read took about 13 of the 18 µs a 65² tile's payload took to parse)."""
    d = getattr(_TLS, "dctx", None)
    if d is None:
        d = _TLS.dctx = zstandard.ZstdDecompressor()
    return d


def compress_one(payload: bytes, level: int = 3) -> bytes:
    """One zstd frame of ``payload`` at ``level``, without the magic number.

    Examples
    --------
    >>> f = compress_one(b"abc" * 100)
    >>> f == zstandard.ZstdCompressor(level=3).compress(b"abc" * 100)[4:]
    True
    >>> decompress(f, 300) == b"abc" * 100
    True
    """
    return strip_magic(_compressor(level).compress(payload))


def _compressor(level: int) -> zstandard.ZstdCompressor:
    """This thread's compressor at ``level`` (one is not thread-safe). Each
    ``compress`` starts a fresh frame with the same parameters, so its bytes are a new
    compressor's; making one took about 40 µs of an edit's 19 small calls."""
    got = getattr(_TLS, "cctx", None)
    if got is None:
        got = _TLS.cctx = {}
    c = got.get(level)
    if c is None:
        c = got[level] = zstandard.ZstdCompressor(level=level)
    return c


# below this many payload bytes a batch is compressed on the calling thread: an edit's
# batches (1-8 payloads, 1-19 kB in all) took 2.1 ms of CPU and 6.9 of wall an edit on
# the worker threads, 1.3 and 1.3 here (threads started for each call)
SERIAL_BYTES = 1 << 18


def strip_magic(frame: bytes) -> bytes:
    """A standard zstd frame as a store holds it: without its magic number."""
    if frame[:4] != MAGIC:  # never: the compressor writes the standard format
        raise AssertionError("zstd wrote a frame without its magic number")
    return frame[4:]


def compress_many(payloads: list[bytes], level: int = 3, threads: int | None = None
                  ) -> list[bytes]:
    """One zstd frame per payload at ``level``, without the magic number, compressed in
    one call on ``threads`` cores (default: the usable ones; a batch of under
    ``SERIAL_BYTES`` on this thread); byte-identical to :func:`compress_one` on each alone.

    Examples
    --------
    >>> frames = compress_many([b"abc" * 100, b"", b"x"])
    >>> [decompress(f, 300) for f in frames][1:]
    [b'', b'x']
    >>> frames[0] == compress_one(b"abc" * 100)
    True
    """
    cctx = _compressor(level)
    if threads is None:
        aff = getattr(os, "sched_getaffinity", None)
        threads = len(aff(0)) if aff else (os.cpu_count() or 1)
    full = [i for i, p in enumerate(payloads) if len(p)]
    out = [b""] * len(payloads)
    small = threads == 1 or sum(len(payloads[i]) for i in full) < SERIAL_BYTES
    if hasattr(cctx, "multi_compress_to_buffer") and full and not small:  # C backend
        got = cctx.multi_compress_to_buffer([payloads[i] for i in full], threads=threads)
        for k, i in enumerate(full):
            out[i] = strip_magic(got[k].tobytes())
    else:
        for i in full:
            out[i] = strip_magic(cctx.compress(payloads[i]))
    for i, p in enumerate(payloads):
        if not len(p):
            out[i] = strip_magic(cctx.compress(p))  # empty (the batch call refuses empties)
    return out

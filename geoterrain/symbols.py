"""The symbol stage of the height codec: residuals as bytes a zstd coder compresses well.

Zigzag residuals are either byte-shuffled at their byte width, or packed as k-bit
symbols (k ∈ {1, 2, 4}, several per byte, with escapes for large values); a fast
zstd probe picks the smaller stream per tile. :func:`read_stream` inverts it.

Examples
--------
>>> zz = zigzag(np.array([0, -1, 3, 2], np.int64))
>>> code, stream = choose_stream(zz, int(zz.max()), {k: pack_symbols(zz, k) for k in PACK_BITS})
>>> unzigzag(read_stream(stream, code, 4)).tolist()
[0, -1, 3, 2]
"""

from __future__ import annotations

import numpy as np
import zstandard
from numba import njit


def zigzag(r: np.ndarray) -> np.ndarray:
    return ((r << 1) ^ (r >> 63)).view(np.uint64)


def unzigzag(u: np.ndarray) -> np.ndarray:
    u = u.astype(np.uint64)
    return ((u >> np.uint64(1)) ^ (np.uint64(0) - (u & np.uint64(1)))).view(np.int64)


def byte_width(maxval: int) -> int:
    if maxval == 0:
        return 0
    for w in (1, 2, 4):
        if maxval < 1 << (8 * w):
            return w
    return 8


UINTS = {1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}


def shuffle(u: np.ndarray, w: int) -> bytes:
    """Byte-shuffle (all byte 0s, then all byte 1s, ...) little-endian values of width w."""
    if w == 0:
        return b""
    a = u.astype(np.dtype(UINTS[w]).newbyteorder("<"))
    return np.ascontiguousarray(a.view(np.uint8).reshape(-1, w).T).tobytes()


def unshuffle(buf: bytes, w: int, count: int) -> np.ndarray:
    if w == 0:
        return np.zeros(count, np.uint64)
    a = np.frombuffer(buf, np.uint8, count * w).reshape(w, count).T
    return np.ascontiguousarray(a).view(np.dtype(UINTS[w]).newbyteorder("<")).ravel()


def pack_symbols(zz: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """k-bit symbols min(zz, 2**k - 1) packed 8 // k per byte (little-endian bit order)
    along the last axis, and the escape counts (symbols equal to 2**k - 1)."""
    zz = np.asarray(zz, np.uint64)
    lead, n = zz.shape[:-1], zz.shape[-1]
    per = 8 // k
    rows = np.ascontiguousarray(zz).reshape(-1, n)
    packed = np.empty((rows.shape[0], -(-n // per)), np.uint8)
    esc = np.empty(rows.shape[0], np.int64)
    _pack_nb(rows, k, packed, esc)  # compiled, one pass (padding symbols are 0)
    return packed.reshape(*lead, -1), esc.reshape(lead)


@njit(cache=True, nogil=True)
def _pack_nb(rows, k, packed, esc):
    m = np.uint64((1 << k) - 1)
    per = 8 // k
    for r in range(rows.shape[0]):
        e = 0
        for b in range(packed.shape[1]):
            byte = 0
            for i in range(per):
                c = b * per + i
                if c < rows.shape[1]:
                    u = rows[r, c]
                    if u >= m:
                        e += 1
                        u = m
                    byte |= np.int64(u) << (i * k)
            packed[r, b] = byte
        esc[r] = e


def unpack_symbols(buf: bytes, k: int, count: int) -> np.ndarray:
    per = 8 // k
    nbytes = -(-count // per)
    packed = np.frombuffer(buf, np.uint8, nbytes)
    shifts = (np.arange(per) * k).astype(np.uint8)
    sym = (packed[:, None] >> shifts) & np.uint8((1 << k) - 1)
    return sym.ravel()[:count].astype(np.uint64)


PACK_BITS = (1, 2, 4)


def choose_stream(zz: np.ndarray, zmax: int, packs: dict,
                  probe: zstandard.ZstdCompressor | None = None) -> tuple[int, bytes]:
    """Pick the residual stream: byte-shuffled zigzag values, or k-bit packed symbols
    with escapes (several samples per byte let zstd's byte-wise literal coder go below
    one bit per sample on flat data). Candidates are compared with a fast zstd probe.

    Returns the header byte (low nibble: byte width of the shuffled stream, high nibble:
    k, 0 = unpacked) and the stream.
    """
    cands = stream_candidates(zz, zmax, packs)
    if len(cands) == 1:
        return cands[0]  # nothing to compare: no probe
    probe = probe or zstandard.ZstdCompressor(level=3)
    return pick_stream(cands, [len(probe.compress(c[1])) for c in cands])


def packed_is_tried(escapes, count):
    """Whether a k-bit packed stream is a candidate: at most one escape per 4 samples,
    else it is never smaller (numbers or arrays).

    Examples
    --------
    >>> packed_is_tried(3, 12), packed_is_tried(4, 12)
    (True, False)
    """
    return escapes * 4 <= count


def byte_widths(zmax: np.ndarray) -> np.ndarray:
    """:func:`byte_width` of every value of an array of maxima.

    Examples
    --------
    >>> byte_widths(np.array([0, 255, 256, 2**40], np.uint64)).tolist()
    [0, 1, 2, 8]
    """
    zmax = np.asarray(zmax, np.uint64)
    return np.select([zmax == 0, zmax < 2**8, zmax < 2**16, zmax < 2**32], [0, 1, 2, 4], 8)


def shuffled_streams(zz: np.ndarray, zmax: np.ndarray, esc: np.ndarray,
                     where: np.ndarray) -> dict:
    """What :func:`choose_stream` returns without comparing anything, for many tiles at
    once: tiles of ``where`` whose values are all 0, or for which no packed stream is
    tried (``esc[..., c]``: the escapes of ``PACK_BITS[c]``), get their byte-shuffled
    values at their width. ``zz`` (ny, nx, K). Returns {(y, x): (code, stream)}.

    Examples
    --------
    >>> zz = np.array([[[0, 0], [300, 1]]], np.uint64)  # (1, 2, 2)
    >>> esc = np.array([[[0, 0, 0], [2, 1, 1]]])
    >>> s = shuffled_streams(zz, zz.max(axis=2), esc, np.ones((1, 2), bool))
    >>> s[(0, 0)], s[(0, 1)][0]
    ((0, b''), 2)
    """
    width = byte_widths(zmax)
    none = ~packed_is_tried(esc, zz.shape[2]).any(axis=2)
    out: dict = {}
    for w in (0, 1, 2, 4, 8):
        ys, xs = np.nonzero(where & (width == w) & (none | (w == 0)))
        if not len(ys):
            continue
        if w == 0:
            rows = [b""] * len(ys)
        else:  # all byte 0s, then all byte 1s, ... (:func:`shuffle`), row by row
            a = zz[ys, xs].astype(np.dtype(UINTS[w]).newbyteorder("<"))
            a = np.ascontiguousarray(a.view(np.uint8).reshape(len(ys), -1, w)
                                     .transpose(0, 2, 1)).reshape(len(ys), -1)
            rows = [r.tobytes() for r in a]
        out.update(zip(zip(ys.tolist(), xs.tolist(), strict=True),
                       ((w, r) for r in rows), strict=True))
    return out


def stream_candidates(zz: np.ndarray, zmax: int, packs: dict) -> list[tuple[int, bytes]]:
    """The streams :func:`choose_stream` compares, the shuffled one first: (code, bytes)."""
    w = byte_width(zmax)
    out = [(w, shuffle(zz, w))]
    if w == 0:
        return out
    for k, (packed, n) in packs.items():
        if not packed_is_tried(int(n), zz.size):
            continue
        m = (1 << k) - 1
        if zmax < m:  # no escapes: the packed symbols say everything
            ew, exc = 0, b""
        else:
            e = zz[zz >= np.uint64(m)] - np.uint64(m)
            ew = byte_width(int(e.max()))
            exc = shuffle(e, ew)
        out.append(((k << 4) | ew, np.ascontiguousarray(packed).tobytes() + exc))
    return out


def pick_stream(cands: list[tuple[int, bytes]], probed: list[int]) -> tuple[int, bytes]:
    """The candidate with the shortest probe (the first of equals), as choose_stream."""
    best, best_len = cands[0], probed[0]
    for c, n in zip(cands[1:], probed[1:], strict=True):
        if n < best_len:
            best, best_len = c, n
    return best


def read_stream(body: bytes, code: int, count: int) -> np.ndarray:
    """Inverse of :func:`choose_stream`: the ``count`` zigzag values (uint64)."""
    w, k = code & 15, code >> 4
    if k == 0:
        return unshuffle(body, w, count)
    m = (1 << k) - 1
    zz = unpack_symbols(body, k, count)
    esc = zz == m
    nesc = int(esc.sum())
    if nesc:
        off = -(-count // (8 // k))
        zz[esc] += unshuffle(body[off:], w, nesc)
    return zz


def read_residuals(body: bytes, code: int, count: int) -> np.ndarray:
    """``unzigzag(read_stream(body, code, count))`` in one compiled pass: the ``count``
    residuals (int64) a tile decodes (the composition spent about 20 µs of a 65² tile's
    decode in its array steps). A ``body`` too short for its stream raises ValueError,
    as :func:`read_stream` does.

    Examples
    --------
    >>> code, stream = choose_stream(zigzag(np.array([0, -1, 5, 300])), 600, {})
    >>> read_residuals(stream, code, 4).tolist()
    [0, -1, 5, 300]
    """
    w, k = code & 15, code >> 4
    buf = np.frombuffer(body, np.uint8)
    out = np.empty(count, np.int64)
    if w not in (0, 1, 2, 4, 8) or k not in (0, *PACK_BITS) \
            or _residuals_nb(buf, w, k, count, out) < 0:
        raise ValueError("residual stream shorter than its header says")
    return out


@njit(cache=True, nogil=True)
def _residuals_nb(buf, w, k, count, out):  # pragma: no cover - compiled
    """Residuals of a shuffled (k = 0) or k-bit packed stream with shuffled escapes, as
    :func:`read_stream` then :func:`unzigzag`; −1 if ``buf`` is too short."""
    if k == 0:
        if len(buf) < count * w:
            return -1
        for i in range(count):
            u = np.uint64(0)
            for b in range(w):  # byte b of every value, then byte b + 1 (shuffled)
                u |= np.uint64(buf[b * count + i]) << np.uint64(8 * b)
            out[i] = np.int64(u >> np.uint64(1)) ^ -np.int64(u & np.uint64(1))
        return 0
    per = 8 // k
    m = (1 << k) - 1
    off = (count + per - 1) // per
    if len(buf) < off:
        return -1
    nesc = 0
    for i in range(count):
        if (buf[i // per] >> ((i % per) * k)) & m == m:
            nesc += 1
    if nesc and len(buf) < off + nesc * w:
        return -1
    e = 0
    for i in range(count):
        u = np.uint64((buf[i // per] >> ((i % per) * k)) & m)
        if u == m and nesc:  # an escape: the symbol plus its shuffled remainder
            for b in range(w):
                u += np.uint64(buf[off + b * nesc + e]) << np.uint64(8 * b)
            e += 1
        out[i] = np.int64(u >> np.uint64(1)) ^ -np.int64(u & np.uint64(1))
    return 0


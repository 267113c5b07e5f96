"""The range coder of schema 20's guessed δ payloads (:mod:`geoterrain.bounds.ownguess`).

:func:`encode_gaps` codes values 0 … 255 in the contexts of their gaps (the gap between
a vertex's upper bound, its parents', and the code of its own error, bucketed by
:func:`_gap_bucket`): a zero flag, the bit length in unary, the bit below the leading
one (adaptive, the range coder of :mod:`geoterrain.codec.entropy`), the rest as
equiprobable bits. :class:`GapDecoder` decodes one in parts and refuses bytes the
encoder would not have written.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.codec import entropy
from geoterrain.codec.entropy import _bit, _canonical, _direct, _finish, _start

#: contexts of a schema-20 δ payload's values: the gap between a vertex's bounds,
#: bucketed (:func:`_gap_bucket`)
GAP_BUCKETS = 14
_GAP_ROWS = GAP_BUCKETS * 17  # per bucket: zero flag, 7 length steps, 9 mantissa bits


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


def _decoding_twin():
    # _gap_values compiled again for decoding, as entropy's decoder twins are: its code
    # object with globals that name the decoders' _bit and _direct (calls, not inlined:
    # a first compile of 0.5-0.9 s, not 1.6; codec/entropy.py's compile_twin)
    g = dict(globals())
    g.update({n: entropy._DEC_GLOBALS[n] for n in ("_bit", "_direct")})
    return entropy.compile_twin(_gap_values, g)


_gap_values_dec = _decoding_twin()


@njit(cache=True, nogil=True)
def _gap_decode(S, buf, m, r, gap):
    # the decoding twin for a literal False: the encoder's branches folded away (the
    # coder's state stays in registers), 4-5 times faster a value than _gap_values
    # with its run-time flag (docs/lab/editing.md, 2026-12-08). GapDecoder.take's
    # kernel: a reader loads this one, a writer _encode_gaps_rows
    return _gap_values_dec(False, S, buf, m, r, gap)


@njit(cache=True, nogil=True)
def _encode_gaps_rows(r, gap, buf, lens):
    # each row of r (k, n) in the contexts of gap's, into its row of buf; lens: each
    # payload's length (-1: past its row of buf). One kernel for one payload and for a
    # level's, in one call without the GIL (no Python between a level's tiles)
    for i in range(r.shape[0]):
        m = np.zeros((_GAP_ROWS, 2), np.int64)
        b = buf[i]
        S = _start(True, b)
        # a bool, not a literal True: one specialisation of the encoder (a literal one
        # codes no faster; the decoder's twin for a literal False does, _gap_decode)
        S = _gap_values(np.bool_(True), S, b, m, r[i], gap[i])
        lens[i] = _finish(S, b)


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
    r = np.asarray(r).reshape(1, -1)
    (out,) = encode_gaps_rows(r, gap, slot=16 * r.shape[1] + 64)  # > 12 bytes a value
    return out


def encode_gaps_rows(r: np.ndarray, gap: np.ndarray, slot: int | None = None) -> list[bytes]:
    """:func:`encode_gaps` of each row of ``r`` (k, n) in the contexts of the same row of
    ``gap`` (k, n): the same bytes, in one compiled call that releases the GIL (a level's
    tiles without Python between them). ``slot``: the bytes a row may take in that call
    (default n + 64, a byte a value and more); a row past it is coded again alone.

    Examples
    --------
    >>> r = np.array([[0, 3, 1], [200, 0, 7]]); gap = np.array([[0, 5, 1], [255, 40, 9]])
    >>> encode_gaps_rows(r, gap) == [encode_gaps(r[0], gap[0]), encode_gaps(r[1], gap[1])]
    True
    """
    r = np.array(r, np.int64, order="C", ndmin=2)  # a copy: the coder writes values back
    gap = np.ascontiguousarray(gap, np.int64).reshape(r.shape)
    k, n = r.shape
    big = 16 * n + 64  # > 12 bytes a value at the worst odds
    # else a byte a value and a little more per row (a payload is mostly well under it:
    # a level-0 ring's a few bytes; uniform values cost about 8.2 bits); a row past it
    # (the coder stops writing there and says so) is coded again with the bound above
    buf = np.empty((k, n + 64 if slot is None else min(slot, big)), np.uint8)
    lens = np.empty(k, np.int64)
    _encode_gaps_rows(r, gap, buf, lens)
    if buf.shape[1] >= big and k and lens.min() < 0:
        raise ValueError("a range-coded bounds payload overflowed its buffer")
    return [buf[i, :m].tobytes() if m >= 0 else
            encode_gaps_rows(r[i:i + 1], gap[i:i + 1], slot=big)[0]
            for i, m in enumerate(lens.tolist())]


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
        self.S = _gap_decode(self.S, self.buf, self.m, r, np.ascontiguousarray(gap, np.int64))
        return r

    def check(self) -> None:
        """ValueError unless the bytes were exactly the encoder's stream: every byte read
        (a spliced, padded or foreign payload has bytes past it) and the last one not a
        zero the encoder drops (:mod:`geoterrain.codec.entropy`'s rule)."""
        if not _canonical(self.buf, self.S):
            raise ValueError("a range-coded bounds payload is not the encoder's stream")

"""The height codec's entropy stage: an adaptive binary range coder with contexts.

A tile's residuals (the codec's order: classes A, B and C, each in raster order) are
binarised as a zero flag, the bit length of the zigzag value in unary, and its bits
below the leading one. Each binary decision is coded with an adaptive model: counts
``n0, n1`` (halved past :data:`LIMIT`) give ``P(0) = (n0 + 1/2) / (n0 + n1 + 1)``
(the Krichevsky–Trofimov estimate). The zero flags and the unary length are modelled
per context, the class and the log2 bucket of an activity that the decoder knows
before the sample: the zigzag residuals already decoded around it (its 8 neighbours
and the samples two to its left and two above) plus the parents' height difference
along its predicted span. This is the context modelling of lossless image coders
(CALIC, LOCO-I) over seed 000 §2.9's residual pyramid; SZ3 codes its interpolation
residuals with one Huffman table per array instead.

The models start afresh in every tile, so a tile still decodes from its own bytes and
its parent's codes. The coder is the byte-oriented range coder of LZMA (16-bit
probabilities, carries through a cached byte): its always-zero first byte is not
stored, and trailing zero bytes are dropped (the decoder reads zeros past the end).

A stream is ``[the valid mask, T·T bits, when stored] + [the values]``; the mask bits
are modelled on their left, upper and upper-left neighbours.

Examples
--------
>>> import numpy as np
>>> parent = np.arange(25, dtype=np.int64).reshape(5, 5) * 4
>>> child = np.arange(25, dtype=np.int64).reshape(5, 5) * 2 + 3; ok = np.ones((5, 5), bool)
>>> data = encode_tile(child, ok, parent, (0, 0), False, MASK_ALL_VALID)
>>> out, _, exact = decode_tile(np.frombuffer(data, np.uint8), parent, 0, 0, False,
...                             MASK_ALL_VALID)
>>> out[1::2].tolist() == child[1::2].tolist(), out[0, 0], exact  # even samples: the parent's
(True, np.int64(0), True)
"""

from __future__ import annotations

import types

import numpy as np
from numba import njit, prange

from geoterrain.codec.predict import (
    _centre,
    _fmean,
    _mid16,
    _pred,
    fill_edges_first,
    fill_outward,
)
from geoterrain.core.threads import parallel_kernel

__all__ = [
    "LIMIT",
    "MASK_ALL_INVALID",
    "MASK_ALL_VALID",
    "MASK_STORED",
    "decode_mask",
    "decode_tile",
    "decode_top",
    "encode_level",
    "level_zigzag",
    "encode_tile",
    "encode_top",
]

LIMIT = 1023  # counts are halved past this total (adapts to a tile's changing statistics)
_NB = 16  # activity buckets per class
_J = 8  # steps of the length away from its expected value modelled apart
# offsets of the model groups in one (rows, 2) count array
_Z0 = 0  # zero flags: class × bucket × 3 phases
_G0 = _Z0 + 3 * _NB * 3  # "length ≥ expected": class × bucket
_UP0 = _G0 + 3 * _NB  # "length > expected + j": class × bucket × j
_DN0 = _UP0 + 3 * _NB * _J  # "length < expected - 1 - j": class × bucket × j
_M0 = _DN0 + 3 * _NB * _J  # the bit below the leading one, per length
_S0 = _M0 + 65  # the sign: class × the signs two to the left and two above × 5 phases
_K0 = _S0 + 27 * 5  # mask bits: 8 neighbour patterns
_ROWS = _K0 + 8
_HALF = 1 << 15  # P(0) of a raw bit
_TOP = 1 << 24


# ----------------------------------------------------------------------- range coder


# 2^32 / (2n + 2) for every count total n ≤ LIMIT + 1: P(0) without a division
_INV = np.array([(1 << 32) // (2 * n + 2) for n in range(LIMIT + 2)], np.int64)


# The coder's state is five int64 scalars S = (x, range, cache, cache size, position),
# passed and returned (never an array: kept in registers, a decision costs ~4 ns, not
# ~15); x is the encoder's low or the decoder's code. Past ``buf`` the encoder writes
# nothing and :func:`_finish` reports the overflow. Only the per-decision functions are
# inlined: inlining the per-value ones too made a cold compile 3–20 times longer.


@njit(cache=True, nogil=True)
def _shift_low(S, buf):
    x, rng, cache, csize, pos = S
    if x < 0xFF000000 or x >= (1 << 32):
        carry = x >> 32
        temp = cache
        while True:
            if 1 <= pos <= buf.size:  # byte 0 (always 0) is not stored
                buf[pos - 1] = (temp + carry) & 0xFF
            pos += 1
            temp = 0xFF
            csize -= 1
            if csize == 0:
                break
        cache = (x >> 24) & 0xFF
    return ((x & 0x00FFFFFF) << 8, rng, cache, csize + 1, pos)


@njit(cache=True, nogil=True, inline="always")
def _renorm(enc, S, buf):
    # bring the range back to ≥ 2^24, a byte at a time
    x, rng, cache, csize, pos = S
    while rng < _TOP:
        rng <<= 8
        if enc:
            x, _, cache, csize, pos = _shift_low((x, rng, cache, csize, pos), buf)
        else:
            x = ((x << 8) | (buf[pos] if pos < buf.size else 0)) & 0xFFFFFFFF
            pos += 1
    return (x, rng, cache, csize, pos)


@njit(cache=True, nogil=True, inline="always")
def _code(enc, S, buf, p0, bit):
    """Encode ``bit`` (enc) or decode one, with P(0) = p0 / 65536: (bit, state)."""
    x, rng, cache, csize, pos = S
    bound = (rng >> 16) * p0
    if enc:
        if bit == 0:
            rng = bound
        else:
            x += bound
            rng -= bound
    elif x < bound:
        rng = bound
        bit = 0
    else:
        x -= bound
        rng -= bound
        bit = 1
    return bit, _renorm(enc, (x, rng, cache, csize, pos), buf)


@njit(cache=True, nogil=True, inline="always")
def _bit(enc, S, buf, m, k, bit):
    """Code ``bit`` with the adaptive model ``m[k]`` and update it: Krichevsky–Trofimov,
    P(0) = (n0 + 1/2) / (n + 1), counts halved past ``LIMIT``. (bit, state)."""
    n0, n1 = m[k, 0], m[k, 1]
    b, S = _code(enc, S, buf, ((2 * n0 + 1) * _INV[n0 + n1]) >> 16, bit)
    if b:
        n1 += 1
    else:
        n0 += 1
    if n0 + n1 > LIMIT:
        n0, n1 = (n0 + 1) >> 1, (n1 + 1) >> 1
    m[k, 0] = n0
    m[k, 1] = n1
    return b, S


@njit(cache=True, nogil=True)
def _start(enc, buf):
    if enc:
        return (np.int64(0), np.int64(0xFFFFFFFF), np.int64(0), np.int64(1), np.int64(0))
    x = np.int64(0)
    for p in range(4):
        x = (x << 8) | (buf[p] if p < buf.size else 0)
    return (x, np.int64(0xFFFFFFFF), np.int64(0), np.int64(0), np.int64(4))


@njit(cache=True, nogil=True)
def _finish(S, buf):
    """Flush the encoder; the stored length (trailing zeros dropped), -1 on overflow."""
    for _ in range(5):
        S = _shift_low(S, buf)
    n = S[4] - 1
    if n > buf.size:
        return -1
    while n > 0 and buf[n - 1] == 0:
        n -= 1
    return n


# ----------------------------------------------------------------------- binarisation


@njit(cache=True, nogil=True, inline="always")
def _bitlen(x):
    """The bit length of the uint64 ``x`` (0 for 0), in six halvings."""
    b = 0
    for w in (32, 16, 8, 4, 2, 1):
        if x >> np.uint64(w):
            x >>= np.uint64(w)
            b += w
    return b + np.int64(x != 0)


@njit(cache=True, nogil=True, inline="always")
def _direct(enc, S, buf, c, v):
    """Code (or decode) the ``c`` ≤ 16 equiprobable bits ``v`` at once: (v, state)."""
    x, rng, cache, csize, pos = S
    r = rng >> c
    if enc:
        x += r * v
    else:
        v = min(x // r, (1 << c) - 1)  # a stranger's stream may hold any code
        x -= r * v
    return v, _renorm(enc, (x, r, cache, csize, pos), buf)


@njit(cache=True, nogil=True)
def _length(enc, S, buf, m, kk, ctx, ke, kmin):
    """The bit length k ≥ ``kmin`` (``kk`` when encoding) as steps up or down from the
    expected length ``ke``, each step modelled per ``ctx`` and its distance: (k, state)."""
    up, S = _bit(enc, S, buf, m, _G0 + ctx, np.int64(kk >= ke))
    if up == 1:
        k = ke
        while k < 64:  # 1 = longer
            b, S = _bit(enc, S, buf, m, _UP0 + ctx * _J + min(k - ke, _J - 1),
                        np.int64(kk > k))
            if b == 0:
                break
            k += 1
    else:
        k = ke - 1
        while k > kmin:  # 1 = shorter
            b, S = _bit(enc, S, buf, m, _DN0 + ctx * _J + min(ke - 1 - k, _J - 1),
                        np.int64(kk < k))
            if b == 0:
                break
            k -= 1
    return k, S


@njit(cache=True, nogil=True)
def _bits(enc, S, buf, w, n):
    """The ``n`` low bits of ``w`` (uint64) as equiprobable bits, 16 at a time."""
    v = np.uint64(0)
    while n > 0:
        c = min(n, 16)
        n -= c
        x = np.int64((w >> np.uint64(n)) & np.uint64((1 << c) - 1)) if enc else np.int64(0)
        x, S = _direct(enc, S, buf, c, x)
        v = (v << np.uint64(c)) | np.uint64(x)
    return v, S


@njit(cache=True, nogil=True)
def _value(enc, S, buf, m, u, ctx, sctx, ke, ph):
    """Code the zigzag value ``u`` (uint64) as a zero flag (context ``ctx`` and the
    prediction's phase ``ph``, 0 … 4), a sign (context ``sctx`` and ``ph``) and a
    magnitude: its bit length k as steps up or down from the expected length ``ke``
    (adaptive, per ``ctx`` and step), the bit below its leading one (adaptive, per k),
    the rest as equiprobable bits. (The value, state.)"""
    zph = 0 if ph == 2 else 1 if ph == 1 or ph == 3 else 2  # |phase|: 0, small, large
    nz, S = _bit(enc, S, buf, m, _Z0 + ctx * 3 + zph, np.int64(u != 0))
    if nz == 0:
        return np.uint64(0), S
    neg, S = _bit(enc, S, buf, m, _S0 + sctx * 5 + ph, np.int64(u & np.uint64(1)))
    mag = (u >> np.uint64(1)) + (u & np.uint64(1))  # |r|, 2^63 included
    k, S = _length(enc, S, buf, m, _bitlen(mag) if enc else 0, ctx, ke, np.int64(1))
    v = np.uint64(1)
    if k >= 2:
        b = np.int64((mag >> np.uint64(k - 2)) & np.uint64(1)) if enc else np.int64(0)
        b, S = _bit(enc, S, buf, m, _M0 + k, b)
        v = (v << np.uint64(1)) | np.uint64(b)
        low, S = _bits(enc, S, buf, mag, k - 2)  # the bits below: equiprobable
        v = (v << np.uint64(k - 2)) | low
    return (v << np.uint64(1)) - np.uint64(neg), S  # back to zigzag: 2|r| - (r < 0)


_FAST = 8  # from this expected length on, zero flag, sign and mantissa are not modelled


@njit(cache=True, nogil=True)
def _value_wide(enc, S, buf, m, u, ctx, ke):
    """:func:`_value` where the expected length ``ke`` ≥ ``_FAST`` (rough data: a zero or
    a skewed sign is rare there): the length k ≥ 0 of |r| from ``ke`` (k = 0: r = 0),
    then the sign and the bits below the leading one as k equiprobable bits. Half the
    modelled decisions of :func:`_value`, for a fraction of a bit more."""
    mag = (u >> np.uint64(1)) + (u & np.uint64(1))
    k, S = _length(enc, S, buf, m, _bitlen(mag) if enc else 0, ctx, ke, np.int64(0))
    if k == 0:
        return np.uint64(0), S
    # k bits: the mantissa below the leading one, then the sign
    w = ((mag ^ (np.uint64(1) << np.uint64(k - 1))) << np.uint64(1)) | (u & np.uint64(1)) \
        if enc else np.uint64(0)
    v, S = _bits(enc, S, buf, w, k)
    mag = (v >> np.uint64(1)) | (np.uint64(1) << np.uint64(k - 1))
    return (mag << np.uint64(1)) - (v & np.uint64(1)), S


@njit(cache=True, nogil=True)
def _mask(enc, S, buf, m, ok):
    # the valid mask, raster order, each bit modelled on its left, up and up-left bits
    t = ok.shape[0]
    for i in range(t):
        for j in range(t):
            c = 0
            if j > 0 and ok[i, j - 1]:
                c |= 1
            if i > 0 and ok[i - 1, j]:
                c |= 2
            if i > 0 and j > 0 and ok[i - 1, j - 1]:
                c |= 4
            b, S = _bit(enc, S, buf, m, _K0 + c, np.int64(ok[i, j]))
            ok[i, j] = b == 1
    return S


@njit(cache=True, nogil=True, inline="always")
def _absdiff(a, b):
    d = a - b
    if d < 0:
        d = -d
    return d if d >= 0 else np.int64(1) << 62  # wrapped: "very large"


@njit(cache=True, nogil=True, inline="always")
def _class_shape(cls, h):
    """Rows, columns and the first sample's (row, column) of class ``cls`` in a child
    tile of 2h + 1: A (h + 1, h) from (0, 1), B (h, h + 1) from (1, 0), C (h, h)
    from (1, 1)."""
    if cls == 0:
        return h + 1, h, 0, 1
    if cls == 1:
        return h, h + 1, 1, 0
    return h, h, 1, 1


@njit(cache=True, nogil=True, inline="always")
def _phase(v16):
    """The bucket of where the unrounded prediction ``v16`` / 16 lies against the
    rounded one ((v16 + 8) >> 4): well below, below, on it, above, well above. On a
    grid coarser than the data (codes of 2ε) the residual leans that way."""
    o = ((v16 + 8) & 15) - 8
    return 0 if o <= -5 else 1 if o < 0 else 2 if o == 0 else 3 if o < 5 else 4


@njit(cache=True, nogil=True)
def _child(enc, S, buf, m, parent, oy, ox, h, cubic, out, ok, W):
    """Code (or decode into ``out``) a child tile's new samples, classes A, B, C in
    raster order, given its parent tile ``parent`` (the child is the quadrant at rows
    ``oy``…, columns ``ox``…, h + 1 parent samples a side) and its valid mask ``ok``.

    The predictions are U(.) of :mod:`geoterrain.codec.predict` (``cubic``: 4-point inside the
    parent tile for A and B, inside this tile for C; else floor-means), each sample's
    from the values before it: A and B from the parent, C from this tile's A samples
    above and below and B samples beside (the mean of the two directions). An invalid
    sample is not coded: its value is its prediction (the encoder's ``out`` is set so
    too). Contexts: the class, the activity bucket of the
    coded residuals around the sample and the parents' difference along its span, the
    prediction's phase (:func:`_phase`), and for the sign the signs two to the left
    and two above. ``W`` > 1: residual bins (:attr:`geoterrain.codec.quantize.Quantizer.bins`);
    the encoder's codes are already binned (:func:`geoterrain.codec.predict.fill_level`), a
    multiple of ``W`` from their prediction, and that multiple is coded.
    """
    mp = parent.shape[0]
    t = 2 * h + 1
    z, u1 = np.int64(0), np.int64(1)  # _mid16's steps as predict.cubic_child passes them
    for a in range(h + 1):
        for b in range(h + 1):
            out[2 * a, 2 * b] = parent[oy + a, ox + b]
    e = np.zeros((t + 4, t + 4), np.uint64)
    for cls in range(3):
        ra, rb, oi, oj = _class_shape(cls, h)
        for a in range(ra):
            for b in range(rb):
                li, lj = 2 * a + oi, 2 * b + oj
                # the prediction (cubic: from v16, 16 times it unrounded; linear: the
                # floor-mean of the two neighbours, C's rounded mean of four), its
                # phase, the parents' span
                if cls == 0:
                    p0, p1 = parent[oy + a, ox + b], parent[oy + a, ox + b + 1]
                    v16 = _mid16(parent, oy + a, z, z, u1, ox + b, mp) if cubic else 0
                    g = _absdiff(p0, p1)
                elif cls == 1:
                    p0, p1 = parent[oy + a, ox + b], parent[oy + a + 1, ox + b]
                    v16 = _mid16(parent, z, ox + b, u1, z, oy + a, mp) if cubic else 0
                    g = _absdiff(p0, p1)
                else:  # both directions: the A samples above and below, the B beside
                    p0, p1 = out[li - 1, lj], out[li + 1, lj]
                    q0, q1 = out[li, lj - 1], out[li, lj + 1]
                    cv = cubic and 1 <= a <= h - 2
                    cw = cubic and 1 <= b <= h - 2
                    pred, v16 = _centre(p0, p1, out[li - 3, lj] if cv else p0,
                                        out[li + 3, lj] if cv else p1, cv,
                                        q0, q1, out[li, lj - 3] if cw else q0,
                                        out[li, lj + 3] if cw else q1, cw)
                    v16 >>= 1  # 16 times the prediction, modulo 16: the phase's
                    g = max(_absdiff(parent[oy + a, ox + b], parent[oy + a + 1, ox + b + 1]),
                            _absdiff(parent[oy + a, ox + b + 1], parent[oy + a + 1, ox + b]))
                if cls == 2:
                    ph = _phase(v16)
                elif cubic:
                    pred, ph = (v16 + 8) >> 4, _phase(v16)
                else:  # a half-way mean lies half a code above its floor
                    pred, ph = _fmean(p0, p1), 4 if (p0 ^ p1) & 1 else 2
                if W > 1:  # in bins centred on the prediction: no phase
                    g //= W
                    ph = 2
                if not ok[li, lj]:
                    out[li, lj] = pred
                    continue
                y, x = li + 2, lj + 2
                s = (e[y - 1, x - 1] + e[y - 1, x] + e[y - 1, x + 1] + e[y, x - 1]
                     + e[y, x + 1] + e[y + 1, x - 1] + e[y + 1, x] + e[y + 1, x + 1]
                     + e[y, x - 2] + e[y - 2, x])
                bits = _bitlen(np.uint64(2 * s + min(g, np.int64(1) << 44)))
                bk = min(bits, _NB - 1)
                # the expected bit length of |r|: 2·s holds about 12 zigzag values
                ke = max(1, bits - 3)
                u = _zig((out[li, lj] - pred) // W) if enc else np.uint64(0)
                if ke >= _FAST:
                    u, S = _value_wide(enc, S, buf, m, u, cls * _NB + bk, ke)
                else:
                    sl, su = e[y, x - 2], e[y - 2, x]
                    sc = cls * 9 + 3 * (0 if sl == 0 else 1 + (sl & 1)) \
                        + (0 if su == 0 else 1 + (su & 1))
                    # the phase matters where residuals are small (a coarse code grid)
                    u, S = _value(enc, S, buf, m, u, cls * _NB + bk, sc, ke,
                                  ph if bits <= 6 else 2)
                if not enc:
                    out[li, lj] = pred + W * _unzig(u)
                e[y, x] = min(u, np.uint64(1 << 40))
    return S


# ----------------------------------------------------------------------- tiles

MASK_ALL_VALID, MASK_ALL_INVALID, MASK_STORED = 0, 1, 2


# _tile and _top are inlined into their entry points: numba optimises each compiled
# function's LLVM module with its callees linked in, so a thin wrapper over the chain
# paid the whole chain's optimisation once more (about 1.5 s a direction, a cold compile)
@njit(cache=True, nogil=True, inline="always")
def _tile(enc, buf, parent, py, px, h, cubic, out, ok, kind, W):
    S = _start(enc, buf)
    m = np.zeros((_ROWS, 2), np.int64)
    if kind == MASK_STORED:
        S = _mask(enc, S, buf, m, ok)
    return _child(enc, S, buf, m, parent, py * h, px * h, h, cubic, out, ok, W)


@njit(cache=True, nogil=True)
def _encode_tile(buf, parent, py, px, h, cubic, out, ok, kind, W):
    # the coder called with a literal True, as encode_level and the decoders (False) call
    # it: a bool argument from Python would compile every coder function a third time
    return _tile(True, buf, parent, py, px, h, cubic, out, ok, kind, W)


def encode_tile(child: np.ndarray, ok: np.ndarray, parent: np.ndarray, parity: tuple[int, int],
                cubic: bool, kind: int, W: int = 1) -> bytes:
    """The stream of one child tile: its codes ``child`` ((2h + 1)²; invalid samples are
    not coded), its valid mask ``ok`` (stored when ``kind`` is :data:`MASK_STORED`),
    its parent tile's codes ``parent`` (same size) and ``parity`` = (x % 2, y % 2), the
    quadrant it covers; ``W``: the residual bins (``child``'s new samples already binned
    against the predictions). See the module's example."""
    ok = np.ascontiguousarray(ok, np.bool_)
    t = ok.shape[0]
    cap = 64 + 2 * t * t
    while True:
        buf = np.zeros(cap, np.uint8)
        st = _encode_tile(buf, np.ascontiguousarray(parent, np.int64), parity[1] & 1,
                          parity[0] & 1, t // 2, cubic, np.array(child, np.int64), ok.copy(),
                          kind, W)
        n = _finish(st, buf)
        if n >= 0:
            return buf[:n].tobytes()
        cap *= 8


@njit(cache=True, nogil=True)
def _canonical(data, S):
    # the encoder's stream exactly: the decoder read every byte (and the zeros the
    # encoder dropped after them), and the last byte is not a dropped zero
    return data.size <= S[4] and (data.size == 0 or data[data.size - 1] != 0)


@njit(cache=True, nogil=True)
def decode_tile(data, parent, px, py, cubic, kind, W=1):
    """The codes ((2h + 1)²) and the valid mask of the child tile (x % 2, y % 2) =
    (``px``, ``py``) of ``parent`` whose stream is ``data`` (uint8), and whether ``data``
    is exactly a stream the encoder writes (any bytes decode to some codes; bytes past
    the stream's end, as a spliced or padded blob has, are caught)."""
    t = parent.shape[0]
    ok = np.full((t, t), kind != MASK_ALL_INVALID)
    out = np.empty((t, t), np.int64)
    buf = data.copy()  # writeable, as the gap decoder's: one _canonical
    st = _tile_dec(False, buf, parent, py, px, t // 2, cubic, out, ok, kind, W)
    return out, ok, _canonical(buf, st)


@njit(cache=True, nogil=True)
def decode_mask(data, t, kind):
    """Only the valid mask (t × t) of a stream (the mask comes first)."""
    ok = np.full((t, t), kind != MASK_ALL_INVALID)
    if kind == MASK_STORED:
        buf = data.copy()
        _mask_dec(False, _start(False, buf), buf, np.zeros((_ROWS, 2), np.int64), ok)
    return ok


@njit(cache=True, nogil=True, inline="always")
def _zig(r):
    return np.uint64((r << 1) ^ (r >> 63))


@njit(cache=True, nogil=True, inline="always")
def _unzig(u):
    return np.int64(u >> np.uint64(1)) ^ -np.int64(u & np.uint64(1))


@njit(cache=True, nogil=True)
def _level_zigzag(d, s, h, P, i0, j0, zz):
    # the residuals of the child tile at level-grid (i0, j0) of d[::s, ::s], codec order
    n = 0
    for cls in range(3):
        ra, rb, oi, oj = _class_shape(cls, h)
        for a in range(ra):
            for b in range(rb):
                i, j = i0 + 2 * a + oi, j0 + 2 * b + oj
                zz[n] = _zig(d[i * s, j * s] - _pred(d, s, i, j, P))
                n += 1


@parallel_kernel(cache=True, nogil=True)
def encode_level(d, valid, s, h, cubic, ys, xs, kinds, buf, lens, W):
    """Encode the child tiles (ys[q], xs[q]) of level ``d[::s, ::s]`` (their parents
    on ``d[::2s, ::2s]``) into rows of ``buf``; ``lens`` gets each stream's length, -1
    where a row was too short. On every core."""
    t = 2 * h + 1
    for q in prange(ys.size):
        i0, j0 = ys[q] * 2 * h, xs[q] * 2 * h  # the tile, on the level's grid
        pi0, pj0 = (ys[q] >> 1) * 2 * h, (xs[q] >> 1) * 2 * h  # its parent, a level up
        out = np.empty((t, t), np.int64)
        ok = np.empty((t, t), np.bool_)
        parent = np.empty((t, t), np.int64)
        for a in range(t):
            for b in range(t):
                out[a, b] = d[(i0 + a) * s, (j0 + b) * s]
                ok[a, b] = valid[(i0 + a) * s, (j0 + b) * s]
                parent[a, b] = d[(pi0 + a) * 2 * s, (pj0 + b) * 2 * s]
        st = _tile(True, buf[q], parent, ys[q] & 1, xs[q] & 1, h, cubic, out, ok, kinds[q], W)
        lens[q] = _finish(st, buf[q])


@parallel_kernel(cache=True, nogil=True)
def level_zigzag(d, s, h, P, ys, xs, zz, zmax):
    """The zigzag residuals (codec order) of the child tiles (ys[q], xs[q]) of level
    ``d[::s, ::s]`` into rows of ``zz``, and each row's largest value, on every core
    (the wide blobs of :mod:`geoterrain.codec.pyramid`)."""
    for q in prange(ys.size):
        _level_zigzag(d, s, h, P, ys[q] * 2 * h, xs[q] * 2 * h, zz[q])
        zm = np.uint64(0)
        for u in zz[q]:
            zm = max(zm, u)
        zmax[q] = zm


# ----------------------------------------------------------------------- the top tile


@njit(cache=True, nogil=True, inline="always")
def _top(enc, buf, top, ok, te, cubic, kind, W, filled, edges=False):
    """The top tile coarse to fine inside itself: its 4 corners (deltas), then each
    level of its own grid (stride 2^k, residual bins ``W``) as a child of the next
    coarser (:func:`_child`, the whole of it), one set of models throughout; with
    ``filled``, each level's invalid samples then filled outward (``fill_outward``; with
    ``edges``, a root of a root grid: ``fill_edges_first``, each edge from itself)."""
    S = _start(enc, buf)
    m = np.zeros((_ROWS, 2), np.int64)
    if kind == MASK_STORED:
        S = _mask(enc, S, buf, m, ok)
    last = top.shape[0] - 1
    prev = np.int64(0)
    for q in range(4):
        i, j = (q >> 1) * last, (q & 1) * last
        u = _zig(top[i, j] - prev) if enc else np.uint64(0)
        u, S = _value(enc, S, buf, m, u, _NB - 1, np.int64(0), np.int64(1), np.int64(2))
        if not enc:
            top[i, j] = prev + _unzig(u)
        prev = top[i, j]
    known = ok.copy()
    known[::last, ::last] = True
    filled = filled and (kind == MASK_STORED or edges and kind == MASK_ALL_INVALID)
    for k in range(te - 1, -1, -1):
        s, h = 1 << k, 1 << (te - k - 1)
        parent = np.ascontiguousarray(top[::2 * s, ::2 * s])
        out = np.ascontiguousarray(top[::s, ::s])
        S = _child(enc, S, buf, m, parent, np.int64(0), np.int64(0), h, cubic, out,
                   np.ascontiguousarray(ok[::s, ::s]), W)
        if filled and edges:
            fill_edges_first(out, np.ascontiguousarray(known[::s, ::s]))
        elif filled:
            fill_outward(out, np.ascontiguousarray(known[::s, ::s]))
        # top[::s, ::s] = out, as a loop: numba's array-to-slice assignment compiles its
        # shape-mismatch message (string formatting, about 1 s of CPU), and numba's own
        # functions are not cached: again in every command that compiles such a kernel
        for i in range(out.shape[0]):
            for j in range(out.shape[1]):
                top[i * s, j * s] = out[i, j]
    return S


@njit(cache=True, nogil=True)
def _encode_top(buf, top, ok, te, cubic, kind, W, filled, edges):
    # a literal True, as _encode_tile says
    return _top(True, buf, top, ok, te, cubic, kind, W, filled, edges)


def encode_top(top: np.ndarray, ok: np.ndarray, te: int, cubic: bool, kind: int,
               W: int = 1, filled: bool = False, edges: bool = False) -> bytes:
    """The stream of the top tile ``top`` ((2^te + 1)² codes, as
    :func:`geoterrain.codec.pyramid.decoded._top_fill` leaves them: binned, invalid corners filled;
    other invalid samples are not coded), mask ``ok``, bins ``W``, ``filled`` and
    ``edges`` (:func:`_top`).

    Examples
    --------
    >>> top = np.arange(25, dtype=np.int64).reshape(5, 5) ** 2; ok = np.ones((5, 5), bool)
    >>> data = encode_top(top, ok, 2, True, MASK_ALL_VALID)
    >>> back, _, exact = decode_top(np.frombuffer(data, np.uint8), 2, True, MASK_ALL_VALID)
    >>> back.tolist() == top.tolist(), exact
    (True, True)
    """
    top = np.ascontiguousarray(top, np.int64)
    cap = 64 + 2 * top.size
    while True:
        buf = np.zeros(cap, np.uint8)
        st = _encode_top(buf, top.copy(), np.ascontiguousarray(ok, np.bool_).copy(), te,
                         cubic, kind, W, filled, edges)
        n = _finish(st, buf)
        if n >= 0:
            return buf[:n].tobytes()
        cap *= 8


@njit(cache=True, nogil=True)
def decode_top(data, te, cubic, kind, W=1, filled=False, edges=False):
    """The top tile's codes and valid mask from its stream (:func:`encode_top`, the same
    residual bins ``W``), and whether ``data`` is exactly a stream the encoder writes (as
    :func:`decode_tile`)."""
    t = (1 << te) + 1
    ok = np.full((t, t), kind != MASK_ALL_INVALID)
    top = np.zeros((t, t), np.int64)
    buf = data.copy()
    st = _top_dec(False, buf, top, ok, te, cubic, kind, W, filled, edges)
    return top, ok, _canonical(buf, st)


# ----------------------------------------------------------------------- the decoder's twin

# The decoders run a twin of the coder's chain: the same functions (their code objects),
# compiled again with globals that name the twins, where the per-decision helpers
# ``_code``, ``_bit`` and ``_direct`` are calls, not ``inline="always"``: numba types and
# lowers each once, not at each of its call sites (the decoders' first compile about 2 s
# shorter; LLVM still inlines the small decoding paths). The encoder keeps them inlined
# (as calls its larger ``_bit`` made encoding 1.9x slower). Same code, same codes.
_DEC_CALLS = ("_code", "_bit", "_direct")
_DEC_CHAIN = ("_length", "_bits", "_value", "_value_wide", "_mask", "_child", "_tile", "_top")
_DEC_GLOBALS = dict(globals())


def compile_twin(f, g: dict, inline: str = "never"):
    """The compiled kernel ``f`` compiled again from its code object over the globals
    ``g`` (``<name>_dec``, its own cache entry): how a decoder runs the coder's code with
    the decoding helpers (here, and ``bounds/gapcoder.py``'s range decoder)."""
    py = f.py_func
    twin = types.FunctionType(py.__code__, g, py.__name__ + "_dec", py.__defaults__,
                              py.__closure__)
    twin.__qualname__ = py.__qualname__ + "_dec"  # its own cache entry
    return njit(cache=True, nogil=True, inline=inline)(twin)


def _decoder_twin(name: str):
    f = globals()[name]
    inline = "never" if name in _DEC_CALLS else f.targetoptions.get("inline", "never")
    return compile_twin(f, _DEC_GLOBALS, inline)


_DEC_GLOBALS.update({n: _decoder_twin(n) for n in _DEC_CALLS + _DEC_CHAIN})
_tile_dec, _top_dec, _mask_dec = (_DEC_GLOBALS[n] for n in ("_tile", "_top", "_mask"))

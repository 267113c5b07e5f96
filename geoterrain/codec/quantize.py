"""Heights ↔ int64 codes: the quantizer the codec and the store share.

Every height becomes an int64 code ``q`` before residual coding
(:mod:`geoterrain.codec.pyramid`): losslessly for integer data and bit-exactly for floats, or
within a chosen bound ε (``|decoded - z| <= ε``). Which quantizer a raster's heights get
is :mod:`geoterrain.codec.quantchoice`'s (and :mod:`geoterrain.preprocessing.bands.quantize`'s,
band by band).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoterrain.codec.quantizer import (  # noqa: F401 - the quantizer is this module's API
    _I32_MAX,
    _I64_MAX,
    DECIMAL_STEPS,
    FINE_STEPS,
    MAX_BINS,
    Quantizer,
)
from geoterrain.core.threads import parallel_kernel, serial_for

__all__ = ["Quantizer", "codes_to_heights", "heights_to_codes", "roundtrip", "tile_heights",
           "valid_codes"]


@njit(cache=True, nogil=True, inline="always")
def _decimal_value(r, div, f32):
    # "decimal" mode's decode: the code over 10^d (both exact: one correctly rounded
    # division, the double nearest the decimal), then to float32 if the source was
    h = np.float64(r) / div
    return np.float64(np.float32(h)) if f32 else h


@njit(cache=True, nogil=True, inline="always")
def _rounded(x, step, offset):
    """rint((x − offset) / step), 0 where that is not finite (:func:`heights_to_codes`)."""
    r = np.rint((x - offset) / step)
    return r if np.isfinite(r) else 0.0


def heights_to_codes(z: np.ndarray, quantizer: Quantizer) -> np.ndarray:
    """Map heights to int64 codes (non-finite inputs give arbitrary codes).

    Examples
    --------
    >>> heights_to_codes(np.array([1.0, -2.0]), Quantizer("int")).tolist()
    [1, -2]
    """
    z = np.asarray(z, dtype=np.float64)
    if quantizer.mode == "float":
        if quantizer.float_bits == 32:
            b = z.astype(np.float32).view(np.int32).astype(np.int64)
            return np.where(b < 0, b ^ _I32_MAX, b)
        b = np.ascontiguousarray(z).view(np.int64)
        # order-preserving map of the IEEE bit pattern (sign-magnitude -> two's complement)
        return np.where(b < 0, b ^ _I64_MAX, b)
    with np.errstate(invalid="ignore"):
        r = np.rint((z - quantizer.offset) / quantizer.step)
        r = np.where(np.isfinite(r), r, 0.0)
    if r.size and float(np.max(np.abs(r))) >= 2.0**62:
        raise ValueError("heights out of range for the quantizer step")
    return r.astype(np.int64)


def codes_to_heights(codes: np.ndarray, quantizer: Quantizer) -> np.ndarray:
    """Map int64 codes back to float64 heights (``offset + q * step``).

    Examples
    --------
    >>> qz = Quantizer("int", 0.1, -10000.0)
    >>> float(codes_to_heights(np.array([100000]), qz)[0])
    0.0
    """
    codes = np.asarray(codes, dtype=np.int64)
    if quantizer.mode == "decimal":
        h = codes.astype(np.float64) / quantizer.divisor
        return h.astype(np.float32).astype(np.float64) if quantizer.float_bits == 32 else h
    if quantizer.mode == "float":
        if quantizer.float_bits == 32:
            c = codes.astype(np.int32)
            b = np.where(c < 0, c ^ np.int32(_I32_MAX), c).astype(np.int32)
            return b.view(np.float32).astype(np.float64)
        b = np.ascontiguousarray(np.where(codes < 0, codes ^ _I64_MAX, codes))
        return b.view(np.float64).copy()
    return quantizer.offset + codes * quantizer.step


def tile_heights(codes: np.ndarray, valid: np.ndarray, quantizer: Quantizer, factor: float
                 ) -> tuple[np.ndarray, float, float, int]:
    """A decoded tile's heights: :func:`codes_to_heights` with NaN where not ``valid``,
    and the smallest and largest valid height × ``factor`` (scene z; NaN if one is not
    finite) and the valid count, in one compiled pass (the same float64 arithmetic as
    the numpy expressions).

    Examples
    --------
    >>> h, lo, hi, n = tile_heights(np.array([[1, 2]]), np.array([[True, False]]),
    ...                             Quantizer("int", 0.5, 10.0), 2.0)
    >>> h.tolist(), lo, hi, n
    ([[10.5, nan]], 21.0, 21.0, 1)
    """
    codes = np.ascontiguousarray(codes, dtype=np.int64)
    valid = np.ascontiguousarray(valid, dtype=np.bool_)
    if quantizer.mode == "float":  # bit patterns (codes_to_heights' map, compiled)
        h = np.empty(codes.shape, np.float64)
        _bits_to_heights_nb(codes, quantizer.float_bits == 32, h)
        lo, hi, n = _finish_nb(h, valid, float(factor), 0, 0.0, 0.0, codes)
    else:
        h = np.empty(codes.shape, np.float64)
        dec = quantizer.mode == "decimal"  # 2: code / 10^d, 3: the same to float32
        how = (2 + (quantizer.float_bits == 32)) if dec else 1
        lo, hi, n = _finish_nb(h, valid, float(factor), how,
                               quantizer.divisor if dec else float(quantizer.step),
                               float(quantizer.offset), codes)
    return h, lo, hi, int(n)


@njit(cache=True, nogil=True)
def _bits_to_heights_nb(codes, f32, out):  # pragma: no cover - compiled
    # codes_to_heights of the float modes: the order-preserving integer back to its IEEE
    # bit pattern (two's complement -> sign-magnitude), viewed as float32 or float64
    cf, of = codes.reshape(-1), out.reshape(-1)
    if f32:
        b = np.empty(cf.size, np.int32)
        for k in range(cf.size):
            c = np.int32(cf[k])  # astype(np.int32): the low 32 bits
            b[k] = c ^ np.int32(0x7FFFFFFF) if c < 0 else c
        fv = b.view(np.float32)
        for k in range(cf.size):
            of[k] = np.float64(fv[k])
    else:
        b = np.empty(cf.size, np.int64)
        for k in range(cf.size):
            c = cf[k]
            b[k] = c ^ np.int64(0x7FFFFFFFFFFFFFFF) if c < 0 else c
        fv = b.view(np.float64)
        for k in range(cf.size):
            of[k] = fv[k]


@njit(cache=True, nogil=True)
def _finish_nb(h, valid, factor, from_codes, step, offset, codes):  # pragma: no cover
    # from_codes 1: h = offset + code * step (codes_to_heights' int arithmetic); 2 and 3:
    # "decimal" mode, code / step (step holds 10^d), 3 rounded to float32; then NaN
    # where invalid and the valid scene z range (h * factor, as Frame.z)
    lo, hi, n, bad = np.inf, -np.inf, 0, False
    hf, vf, cf = h.reshape(-1), valid.reshape(-1), codes.reshape(-1)
    for k in range(hf.size):
        if from_codes == 1:
            hf[k] = offset + np.float64(cf[k]) * step
        elif from_codes >= 2:
            hf[k] = _decimal_value(np.float64(cf[k]), step, from_codes == 3)
        if vf[k]:
            z = hf[k] * factor
            if not np.isfinite(z):
                bad = True
            lo = min(lo, z)
            hi = max(hi, z)
            n += 1
        else:
            hf[k] = np.nan
    if bad:  # a valid height that is not finite: no range (a caller's check fails)
        return np.nan, np.nan, n
    return lo, hi, n


@parallel_kernel(cache=True, nogil=True)
def _roundtrip_nb(z, valid, mode, step, offset, out):
    """``codes_to_heights(heights_to_codes(z))`` where valid, NaN elsewhere, in one pass
    (mode 0: int/quantized, 1: float32, 2: float64, 3 and 4: decimal to float32 and
    float64), rows on every core. Returns the largest |code| seen (invalid samples count
    as height 0, as :func:`heights_to_codes` sees them)."""
    peaks = np.zeros(z.shape[0])
    div = np.float64(np.rint(1.0 / step))
    for i in prange(z.shape[0]):
        peak = 0.0
        for j in range(z.shape[1]):
            ok = valid[i, j]
            x = z[i, j] if ok else 0.0
            if mode == 1:
                h = np.float64(np.float32(x))
            elif mode == 2:
                h = x
            else:  # integer codes, decoded as int/quantized (0) or as decimals (3, 4)
                r = _rounded(x, step, offset)
                peak = max(peak, abs(r))
                c = np.float64(np.int64(r))
                h = _decimal_value(c, div, mode == 3) if mode >= 3 else offset + c * step
            out[i, j] = h if ok else np.nan
        peaks[i] = peak
    return peaks.max() if peaks.size else 0.0


def roundtrip(z: np.ndarray, valid: np.ndarray, quantizer: Quantizer) -> np.ndarray:
    """Heights as decoding gives them: ``codes_to_heights(heights_to_codes(z))`` where
    ``valid``, NaN elsewhere (compiled, no temporaries).

    Examples
    --------
    >>> qz = Quantizer("quantized", 0.2, 0.0, 0.1)
    >>> roundtrip(np.array([[0.33, 1.0]]), np.array([[True, False]]), qz).round(6).tolist()
    [[0.4, nan]]
    """
    return _whole_grid(_roundtrip_nb, np.float64, z, valid, quantizer)


def _whole_grid(kernel, dtype, z, valid, quantizer: Quantizer) -> np.ndarray:
    """Run ``kernel`` (:func:`_roundtrip_nb` or :func:`_codes_nb`) over ``z`` of any shape;
    raise as :func:`heights_to_codes` does when a code is out of range."""
    z = np.asarray(z, np.float64)
    valid = np.asarray(valid, bool)
    out = np.empty(z.shape, dtype)
    mode = (1 if quantizer.float_bits == 32 else 2) if quantizer.mode == "float" else 0
    if quantizer.mode == "decimal":  # codes as the int modes'; decoded as decimals
        mode = 3 if quantizer.float_bits == 32 else 4
    z2, v2, o2 = (a.reshape(1, -1) if a.ndim != 2 else a for a in (z, valid, out))
    # rows on every core for a whole grid, on this thread for a tile (threads.py)
    run = kernel.serial if serial_for(z.size) else kernel.parallel
    peak = run(z2, v2, mode, float(quantizer.step), float(quantizer.offset), o2)
    if peak >= 2.0**62:
        raise ValueError("heights out of range for the quantizer step")
    return out


@parallel_kernel(cache=True, nogil=True)
def _codes_nb(z, valid, mode, step, offset, out):
    """:func:`heights_to_codes` of ``where(valid, z, 0)`` in one pass (modes as in
    :func:`_roundtrip_nb`), rows on every core; returns the largest |rounded code| of
    modes int/quantized."""
    peaks = np.zeros(z.shape[0])
    for i in prange(z.shape[0]):
        f32 = np.empty(1, np.float32)
        i32 = f32.view(np.int32)
        f64 = np.empty(1, np.float64)
        i64 = f64.view(np.int64)
        peak = 0.0
        for j in range(z.shape[1]):
            x = z[i, j] if valid[i, j] else 0.0
            if mode == 1:  # (modes 3 and 4, decimal, code as mode 0)
                f32[0] = np.float32(x)
                b = np.int64(i32[0])
                out[i, j] = b ^ 0x7FFFFFFF if b < 0 else b
            elif mode == 2:
                f64[0] = x
                b = i64[0]
                out[i, j] = b ^ 0x7FFFFFFFFFFFFFFF if b < 0 else b
            else:
                r = _rounded(x, step, offset)
                peak = max(peak, abs(r))
                out[i, j] = np.int64(r) if abs(r) < 2.0**62 else 0
        peaks[i] = peak
    return peaks.max() if peaks.size else 0.0


def valid_codes(z: np.ndarray, valid: np.ndarray, quantizer: Quantizer) -> np.ndarray:
    """``heights_to_codes(where(valid, z, 0), quantizer)`` (compiled, no temporaries).

    Examples
    --------
    >>> valid_codes(np.array([[1.0, 7.0]]), np.array([[True, False]]), Quantizer("int")).tolist()
    [[1, 0]]
    """
    return _whole_grid(_codes_nb, np.int64, z, valid, quantizer)

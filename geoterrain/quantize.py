"""Heights ↔ int64 codes: the quantizer the codec and the store share.

Every height becomes an int64 code ``q`` before residual coding
(:mod:`geoterrain.codec`): losslessly for integer data and bit-exactly for floats, or
within a chosen bound ε (``|decoded - z| <= ε``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["Quantizer", "choose_quantizer", "codes_to_heights", "heights_to_codes", "roundtrip",
           "tile_heights", "valid_codes"]

_I64_MAX = np.int64(np.iinfo(np.int64).max)
# lossless steps finer than 1 tried on float sources, coarsest first, and whether each
# is a decimal ("decimal" mode) or binary ("int" mode, exact in floats): the first under
# which every height decodes to itself is taken (fine_quantizer)
FINE_STEPS = tuple(sorted([(2.0 ** -m, False) for m in range(1, 9)]
                          + [(10.0 ** -d, True) for d in range(1, 5)], reverse=True))
DECIMAL_STEPS = tuple(s for s, d in FINE_STEPS if d)
MAX_BINS = (1 << 20) - 1
FLOAT_BINS = 15  # the residual bins of a lossy float source: codes of 2ε / 15


def fine_candidates(dt: np.dtype) -> tuple[tuple[float, bool, bool], ...]:
    """The lossless grids tried on a float source of dtype ``dt``, coarsest first:
    (step, decimal, to float32). A decimal decodes as ``code / 10^d`` rounded to float32
    for a source of at most 4 bytes. A float64 source tries each decimal twice, as
    float64 and then rounded to float32: a float64 raster written from float32 decimals
    (a conversion that widened 1238.6f) holds the float32 nearest each decimal.

    Examples
    --------
    >>> [c for c in fine_candidates(np.dtype("float64")) if c[0] == 0.1]
    [(0.1, True, False), (0.1, True, True)]
    >>> [c for c in fine_candidates(np.dtype("float32")) if c[0] == 0.1]
    [(0.1, True, True)]
    """
    if np.dtype(dt).itemsize <= 4:
        return tuple((s, d, d) for s, d in FINE_STEPS)
    return tuple(c for s, d in FINE_STEPS
                 for c in ([(s, d, False), (s, d, True)] if d else [(s, d, False)]))


def _candidate_arrays(dt: np.dtype) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # the kernel's view of fine_candidates: steps, divisors (0: binary), to-float32 flags
    c = fine_candidates(dt)
    return (np.array([s for s, _, _ in c], np.float64),
            np.array([float(round(1.0 / s)) if d else 0.0 for s, d, _ in c], np.float64),
            np.array([f for _, _, f in c], np.bool_))


_I32_MAX = np.int64(np.iinfo(np.int32).max)


@dataclass(frozen=True)
class Quantizer:
    """How heights map to int64 codes.

    Attributes
    ----------
    mode : {"int", "decimal", "quantized", "float"}
        ``"int"``: lossless, heights are exactly ``offset + q * step`` (integer DEMs,
        Terrain-RGB's 0.1 m). ``"decimal"``: lossless, heights are exactly the decimal
        ``q / 10^d`` (``step`` = 10^-d, offset 0) rounded to ``float_bits`` (32 for a
        source of at most 4 bytes): a float DEM written with d decimal places, as many LiDAR and
        survey products are (1238.6 ft is the float32 nearest 12386 / 10, not
        ``12386 * 0.1``). ``"quantized"``: ``q = round((z - offset) / step)`` with
        ``step`` slightly below ``2 * codec_error`` so ``|decoded - z| <= codec_error``.
        ``"float"``: lossless bit-exact floats; codes are the float bit patterns mapped to
        order-preserving integers (``float_bits`` = 32 or 64).
    step, offset : float
        Code spacing and origin (unused in ``"float"`` mode).
    codec_error : float
        Guaranteed bound on ``|decoded - z|`` (0 for lossless modes).
    float_bits : int
        Width of the source float in ``"float"`` and ``"decimal"`` modes.
    bins : int
        ``"quantized"`` mode: the odd width, in codes, of the codec's residual bins (SZ3's
        quantisation of each residual against its prediction from decoded codes: a
        decoded code is the prediction plus a multiple of ``bins``, within ``(bins - 1)
        / 2`` codes of the sample's own). 1: every code decodes to itself
        (``|decoded - z| <= step / 2``); above 1, ``step / 2 + (bins - 1) / 2 · step <=
        codec_error`` and decoded heights depend on the pyramid
        (:func:`geoterrain.codec.decoded_codes`).

    Examples
    --------
    >>> Quantizer("int", 1.0, 0.0, 0.0).mode
    'int'
    """

    mode: str
    step: float = 1.0
    offset: float = 0.0
    codec_error: float = 0.0
    float_bits: int = 64
    bins: int = 1

    @classmethod
    def from_json(cls, d: dict) -> Quantizer:
        """From a store's metadata (older stores call ε ``max_error``).

        Examples
        --------
        >>> Quantizer.from_json({"mode": "quantized", "step": 0.9, "max_error": 0.5}).codec_error
        0.5
        """
        d = dict(d)
        if "max_error" in d:
            d.setdefault("codec_error", d.pop("max_error"))
        return cls(**d)

    def to_json(self) -> dict:
        """For a store's metadata: every field, ``bins`` only when above 1 (a store
        without residual bins reads as before; code that predates them refuses one with).

        Examples
        --------
        >>> Quantizer("int").to_json()
        {'mode': 'int', 'step': 1.0, 'offset': 0.0, 'codec_error': 0.0, 'float_bits': 64}
        """
        d = dataclasses.asdict(self)
        if self.bins == 1:
            del d["bins"]
        return d

    def __post_init__(self) -> None:
        if self.mode not in ("int", "decimal", "quantized", "float"):
            raise ValueError(f"unknown quantizer mode {self.mode!r}")
        if self.mode != "float" and not self.step > 0:
            raise ValueError("quantizer step must be > 0")
        if self.float_bits not in (32, 64):
            raise ValueError("float_bits must be 32 or 64")
        if self.mode == "decimal" and (self.offset != 0.0 or self.step not in DECIMAL_STEPS):
            raise ValueError("a decimal quantizer has a step of 10^-d (d = 1 to 4) and offset 0")
        if not (isinstance(self.bins, int) and 1 <= self.bins <= MAX_BINS and self.bins & 1):
            raise ValueError(f"quantizer bins must be an odd integer in 1 … {MAX_BINS}")
        if self.bins > 1 and self.mode != "quantized":
            raise ValueError("only a quantized (lossy) quantizer has residual bins")

    @property
    def divisor(self) -> float:
        """``"decimal"`` mode: 10^d, the exact integer its codes are divided by."""
        return float(round(1.0 / self.step))


@njit(cache=True, nogil=True)
def _grid_checks(v, step, offset):
    """One pass over the finite values of ``v`` (1-D float64): (all on the grid
    ``offset + k step`` with |k| < 2^52, all exactly float32-representable)."""
    on_grid, f32 = True, True
    for x in v:
        if not np.isfinite(x):
            continue
        if on_grid:
            k = np.rint((x - offset) / step)
            if not (abs(k) < 2.0**52) or offset + k * step != x:
                on_grid = False
        if f32 and np.float64(np.float32(x)) != x:
            f32 = False
        if not (on_grid or f32):
            break
    return on_grid, f32


def choose_quantizer(
    values: np.ndarray,
    src_dtype: np.dtype | type | str,
    codec_error: float | None = None,
    scale: float | None = None,
    offset: float | None = None,
) -> Quantizer:
    """Pick the quantizer for a DEM.

    Integer sources, and float sources whose values are all exactly ``k * scale + offset``
    (``scale`` defaults to 1, i.e. integer-valued floats are detected), are coded
    losslessly as integers. Without a given ``scale`` and ``offset``, float sources whose
    values all lie on a finer grid are coded losslessly as integers of the coarsest grid
    that decodes every value bit for bit (:func:`fine_quantizer`: steps 2^-1 to 2^-8, or
    decimals of 1 to 4 places rounded to the source float, as 1238.6 ft in a float32;
    float32 for a float16 source).
    Other floats are coded **bit-exactly at the source float precision** (``"float"``
    mode: lossless, but measured at 14-21 bits per sample on float32 DEMs, about 2.5x a
    0.1-unit quantized code, because the low mantissa bits are incompressible noise)
    unless ``codec_error`` is given, in which case they are quantized
    with ``|decoded - z| <= codec_error``.
    Lossless integer coding is kept when ``2 * codec_error <= scale``.

    Parameters
    ----------
    values : array
        The valid heights (any shape; non-finite values are ignored).
    src_dtype : dtype
        The source raster's dtype.
    codec_error : float, optional
        Vertical error bound epsilon (source units). ``None`` or 0 means lossless.
    scale, offset : float, optional
        A known code spacing and origin (e.g. Terrain-RGB: 0.1 and -10000).

    Returns
    -------
    Quantizer

    Examples
    --------
    >>> choose_quantizer(np.array([1.0, 5.0]), np.int16).mode
    'int'
    >>> choose_quantizer(np.array([1.2345678, 5.5]), np.float64).mode
    'float'
    >>> q = choose_quantizer(np.array([1.25, 5.5]), np.float32, codec_error=0.5)
    >>> q.mode, q.step < 1.0
    ('quantized', True)
    >>> q = choose_quantizer(np.float32([1238.6, 1245.15]), np.float32)
    >>> q.mode, q.step, q.float_bits
    ('decimal', 0.01, 32)
    >>> choose_quantizer(np.array([1.25, 5.5]), np.float32).step
    0.25
    """
    dt = np.dtype(src_dtype)
    v = np.ascontiguousarray(values, dtype=np.float64).ravel()
    sc = 1.0 if scale is None else float(scale)
    off = 0.0 if offset is None else float(offset)
    exact, f32 = _grid_checks(v, sc, off)  # over the finite values (compiled, one pass)
    lossy = codec_error is not None and codec_error > 0
    if exact and (not lossy or 2.0 * float(codec_error) <= sc):
        return Quantizer("int", sc, off, 0.0)
    if exact:  # a lossy bound on a known grid: bins of its codes
        fin = v[np.isfinite(v)]
        return grid_bins_quantizer(float(codec_error), sc, off,
                                   float(np.abs(fin).max()) if fin.size else 0.0,
                                   lambda k: _roundtrip_error(fin, sc, off, k)[0])
    fine = (fine_quantizer(fine_steps_ok(v, dt), dt, codec_error)
            if fine_grids_apply(scale, offset, codec_error) else None)
    if fine is not None:
        return fine
    if lossy:
        v, vmax = _finite_copy(v)  # the finite values (a copy) and max |v|, one pass
        eps = float(codec_error)
        if offset is None:
            off = float(np.round(_median_in_place(v))) if v.size else 0.0
        return lossy_quantizer(eps, off, vmax, v.size > 0,
                               lambda step: _roundtrip_error(v, step, off))
    return float_quantizer(dt, f32)


def fine_steps_ok(v: np.ndarray, dt: np.dtype, ok: np.ndarray | None = None) -> np.ndarray:
    """For each of :func:`fine_candidates`: does every finite value of ``v`` decode to
    itself under it (code ``rint(x / step)``; a binary step decodes ``code × step``, a
    decimal one ``code / 10^d``, rounded to float32 where the candidate says), bit for bit
    but for a −0, which decodes as +0 (as in the ``"int"`` mode)? ``ok`` (the flags of
    earlier values, updated in place) lets a caller check a raster band by band.
    Examples: :func:`fine_quantizer`."""
    if ok is None:
        ok = np.ones(len(fine_candidates(dt)), np.bool_)
    if ok.any():
        _fine_steps_nb(np.ascontiguousarray(v, np.float64).ravel(), *_candidate_arrays(dt),
                       ok)
    return ok


def fine_grids_apply(scale: float | None, offset: float | None,
                     codec_error: float | None) -> bool:
    """Whether :func:`choose_quantizer` looks for a finer grid: no known grid is given,
    and a bound ε, if any, lets a lossless code win (2ε ≤ the coarsest fine step)."""
    lossy = codec_error is not None and codec_error > 0
    return scale is None and offset is None and (
        not lossy or 2.0 * float(codec_error) <= FINE_STEPS[0][0])


def fine_quantizer(ok: np.ndarray, dt: np.dtype, codec_error: float | None = None
                   ) -> Quantizer | None:
    """The lossless quantizer of the coarsest step that :func:`fine_steps_ok` passed (a
    binary one as ``"int"``, a decimal one as ``"decimal"``), or None; None too when a
    bound ``codec_error`` is given and the step is finer than 2ε (the lossy quantizer
    then codes fewer levels). For float sources whose heights are not integers: heights
    on a finer grid, as survey and LiDAR products write them, cost a few bits a sample
    as codes, against 14–21 as floats.

    Examples
    --------
    >>> dt = np.dtype("float32")
    >>> fine_quantizer(fine_steps_ok(np.float32([1238.6, 1245.1]), dt), dt)
    Quantizer(mode='decimal', step=0.1, offset=0.0, codec_error=0.0, float_bits=32, bins=1)
    >>> fine_quantizer(fine_steps_ok(np.array([0.25, 7.5]), dt), dt).mode
    'int'
    >>> fine_quantizer(fine_steps_ok(np.array([np.pi]), dt), dt) is None
    True
    """
    dt = np.dtype(dt)
    if dt.kind != "f":
        return None
    for (step, decimal, f32), good in zip(fine_candidates(dt), ok, strict=True):
        if good:
            if codec_error is not None and codec_error > 0 and 2.0 * codec_error > step:
                return None
            if decimal:
                return Quantizer("decimal", step, 0.0, 0.0, 32 if f32 else 64)
            return Quantizer("int", step, 0.0, 0.0)
    return None


@njit(cache=True, nogil=True)
def _fine_steps_nb(v, steps, divs, f32s, ok):  # pragma: no cover - compiled
    left = 0
    for s in range(ok.size):
        left += ok[s]
    for x in v:
        if left == 0:
            return
        if not np.isfinite(x):
            continue
        for s in range(ok.size):
            if not ok[s]:
                continue
            r = np.rint(x / steps[s])
            if divs[s] > 0:
                h = _decimal_value(r, divs[s], f32s[s])
            else:
                h = r * steps[s]
            if not abs(r) < 2.0**52 or h != x:
                ok[s] = False
                left -= 1


@njit(cache=True, nogil=True, inline="always")
def _decimal_value(r, div, f32):
    # "decimal" mode's decode: the code over 10^d (both exact: one correctly rounded
    # division, the double nearest the decimal), then to float32 if the source was
    h = np.float64(r) / div
    return np.float64(np.float32(h)) if f32 else h


def float_quantizer(dt: np.dtype, f32: bool) -> Quantizer:
    """The bit-exact float quantizer: 32 bits when every height is a float32 of a source
    of at most 4 bytes, else 64."""
    bits = 64
    if (dt == np.float32 or dt.kind in "iub" or dt.itemsize <= 4) and f32:
        bits = 32
    return Quantizer("float", 1.0, 0.0, 0.0, bits)


def grid_bins_quantizer(eps: float, sc: float, off: float, vmax: float,
                        bins_error: Callable[[int], float]) -> Quantizer:
    """The ε quantizer of heights on the grid ``off + k · sc`` (every one of them, as
    :func:`choose_quantizer` checks) with 2ε > ``sc``: the grid's own codes, residual
    bins of the largest odd width W = 2k + 1 with k · sc ≤ ε whose extreme codes decode
    within ε of every height in float64 (``bins_error(k)``: the largest |off + (c ± k)
    · sc − x|, :func:`_roundtrip_error`). A decoded code lies within k of the height's
    own c, and the codes between decode within (k − 1) · sc plus a few ulps, which is
    under ε while ``sc`` exceeds the float64 rounding margin of :func:`lossy_quantizer`
    (else no bins).

    Examples
    --------
    >>> v = np.array([147.0, 298.0])  # SRTM metres at ε = 2
    >>> grid_bins_quantizer(2.0, 1.0, 0.0, 298.0, lambda k: _roundtrip_error(v, 1.0, 0.0, k)[0]
    ...                     ).bins
    5
    """
    margin = 8.0 * float(np.finfo(np.float64).eps * (2.0 * vmax + 2.0 * abs(off) + eps))
    k = int(np.floor(eps / sc * (1 + 1e-12))) if sc > margin else 0
    while k > 0 and k * sc > eps:
        k -= 1
    k = min(k, (MAX_BINS - 1) // 2)
    for _ in range(4):  # the float64 decode of the extreme codes, on the data itself
        if k == 0 or bins_error(k) <= eps:
            break
        k -= 1
    else:
        k = 0
    if k == 0:
        return Quantizer("int", sc, off, 0.0)
    return Quantizer("quantized", sc, off, eps, bins=2 * k + 1)


def lossy_quantizer(eps: float, off: float, vmax: float, any_values: bool,
                    roundtrip_error: Callable[[float], tuple[float, float]]) -> Quantizer:
    """The ε quantizer of heights within ±``vmax`` around the offset ``off``: codes of
    about 2ε / :data:`FLOAT_BINS` and residual bins of :data:`FLOAT_BINS` codes. The
    step is 2ε / W less the float64 rounding margin, shrunk until
    ``roundtrip_error(step)`` → (the largest |code · step + off − height|, the largest
    |code|) is within ε / W (8 tries); a decoded code lies at most (W − 1) / 2 codes
    from the sample's own, so within ε / W + (W − 1) / 2 · 2ε / W = ε."""
    W = FLOAT_BINS
    e = eps / W  # each code's own rounding
    # float64 rounding of (z - off)/step, q*step and off + q*step: a few ulps of the
    # magnitudes involved; shrink the step by that margin (seed 000 has no formula).
    margin = 8.0 * float(np.finfo(np.float64).eps * (2.0 * vmax + 2.0 * abs(off) + e))
    step = 2.0 * (e - margin)
    if step <= 0:
        raise ValueError(f"codec_error {eps} is below the float64 resolution of the data")
    for _ in range(8):
        if not any_values:
            break
        err, peak = roundtrip_error(step)  # of codes_to_heights(heights_to_codes)
        if peak >= 2.0**62:
            raise ValueError("heights out of range for the quantizer step")
        if err <= e:
            break
        step *= 1.0 - 1e-9
    return Quantizer("quantized", step, off, eps, bins=W)


@njit(cache=True, nogil=True)
def _finite_copy(v):
    n = 0
    for x in v:
        n += np.isfinite(x)
    out = np.empty(n, np.float64)
    peak = 0.0
    k = 0
    for x in v:
        if np.isfinite(x):
            out[k] = x
            peak = max(peak, abs(x))
            k += 1
    return out, peak


def _median_in_place(v: np.ndarray) -> float:
    """``np.median(v)`` (the same value), partitioning ``v`` in place instead of a copy."""
    n = v.size
    k = n // 2
    if n % 2:
        v.partition(k)
        return float(v[k])
    v.partition([k - 1, k])
    return float((v[k - 1] + v[k]) / 2.0)  # np.median: the mean of the two middle values


@njit(cache=True, nogil=True, inline="always")
def _rounded(x, step, offset):
    """rint((x − offset) / step), 0 where that is not finite (:func:`heights_to_codes`)."""
    r = np.rint((x - offset) / step)
    return r if np.isfinite(r) else 0.0


@njit(cache=True, nogil=True)
def _roundtrip_error(v, step, offset, shift=0):
    """max |offset + (rint((x - offset)/step) ± ``shift``)·step − x| over ``v`` (the
    codes' decode, as :func:`codes_to_heights` of :func:`heights_to_codes`, moved by
    ``shift`` codes), and the largest |code|."""
    err, peak = 0.0, 0.0
    for x in v:
        r = _rounded(x, step, offset)
        peak = max(peak, abs(r))
        if abs(r) < 2.0**62:
            for c in (np.int64(r) - shift, np.int64(r) + shift):
                err = max(err, abs(offset + np.float64(c) * step - x))
    return err, peak


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


@njit(cache=True, nogil=True)
def _roundtrip_nb(z, valid, mode, step, offset, out):
    """``codes_to_heights(heights_to_codes(z))`` where valid, NaN elsewhere, in one pass
    (mode 0: int/quantized, 1: float32, 2: float64, 3 and 4: decimal to float32 and
    float64). Returns the largest |code| seen (invalid samples count as height 0, as
    :func:`heights_to_codes` sees them)."""
    peak = 0.0
    div = np.float64(np.rint(1.0 / step))
    for i in range(z.shape[0]):
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
    return peak


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
    peak = kernel(z2, v2, mode, float(quantizer.step), float(quantizer.offset), o2)
    if peak >= 2.0**62:
        raise ValueError("heights out of range for the quantizer step")
    return out


@njit(cache=True, nogil=True)
def _codes_nb(z, valid, mode, step, offset, out):
    """:func:`heights_to_codes` of ``where(valid, z, 0)`` in one pass (modes as in
    :func:`_roundtrip_nb`); returns the largest |rounded code| of modes int/quantized."""
    f32 = np.empty(1, np.float32)
    i32 = f32.view(np.int32)
    f64 = np.empty(1, np.float64)
    i64 = f64.view(np.int64)
    peak = 0.0
    for i in range(z.shape[0]):
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
    return peak


def valid_codes(z: np.ndarray, valid: np.ndarray, quantizer: Quantizer) -> np.ndarray:
    """``heights_to_codes(where(valid, z, 0), quantizer)`` (compiled, no temporaries).

    Examples
    --------
    >>> valid_codes(np.array([[1.0, 7.0]]), np.array([[True, False]]), Quantizer("int")).tolist()
    [[1, 0]]
    """
    return _whole_grid(_codes_nb, np.int64, z, valid, quantizer)

"""Which quantizer (:class:`geoterrain.codec.quantize.Quantizer`) a raster's heights get.

:func:`choose_quantizer` looks at the heights themselves: a known grid (integers,
Terrain-RGB's 0.1 m) is coded as it is, a float raster on a finer binary or decimal grid
losslessly on that grid (:func:`fine_quantizer`), other floats as their bit patterns;
with a bound ε, a grid's own codes in residual bins (:func:`grid_bins_quantizer`) or
codes of 2ε / :data:`FLOAT_BINS` in bins of :data:`FLOAT_BINS` (:func:`lossy_quantizer`).
:mod:`geoterrain.preprocessing.bands.quantize` makes the same choice a band of rows at a time.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

from geoterrain.codec.quantize import FINE_STEPS, MAX_BINS, Quantizer, _decimal_value, _rounded
from geoterrain.exceptions import UsageError

__all__ = ["FLOAT_BINS", "choose_quantizer", "fine_quantizer", "float_quantizer",
           "grid_bins_quantizer", "lossy_quantizer"]

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


def _too_fine(eps: float, margin: float) -> UsageError:
    # a bound below what float64 codes of these heights can hold (a one-line usage error)
    least = f"{4 * FLOAT_BINS * margin:.3g}"
    return UsageError(f"codec_error {eps:g} is below the float64 resolution of these heights; "
                      f"give at least {least}, or none for a lossless store",
                      cli=f"--codec-error {eps:g} is below the float64 resolution of these "
                          f"heights; give at least {least}, or leave it out for a lossless "
                          "store")


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
        raise _too_fine(eps, margin)
    for _ in range(8):
        if not any_values:
            break
        err, peak = roundtrip_error(step)  # of codes_to_heights(heights_to_codes)
        if peak >= 2.0**62:
            raise _too_fine(eps, margin)
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


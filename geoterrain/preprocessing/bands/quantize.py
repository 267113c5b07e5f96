"""The height quantizer of a grid read in row bands (issue 12's streaming preprocess; the
whole-grid twin is :func:`geoterrain.codec.quantchoice.choose_quantizer`).

The same choice from the same statistics, each gathered over bands: whether every
finite height lies on the code grid and is a float32 (an AND), their count and largest
magnitude, the median for a lossy code's offset, and the roundtrip error of a step (a
max). The median is exact: histograms of the heights narrow each middle rank to one
bin, and a last pass sorts only that bin's heights (a bin of equal heights needs no
sort), so a few passes read the grid.
"""

from __future__ import annotations

import numpy as np

from geoterrain.codec.quantchoice import (
    _grid_checks,
    _roundtrip_error,
    fine_candidates,
    fine_grids_apply,
    fine_quantizer,
    fine_steps_ok,
    float_quantizer,
    grid_bins_quantizer,
    lossy_quantizer,
)
from geoterrain.codec.quantize import Quantizer
from geoterrain.core.orderstat import Bands, _finite, _kth

__all__ = ["band_quantizer"]

def band_quantizer(bands: Bands, src_dtype: np.dtype | type | str,
                   codec_error: float | None = None, scale: float | None = None,
                   offset: float | None = None) -> Quantizer:
    """:func:`~geoterrain.codec.quantchoice.choose_quantizer` of the heights that ``bands()``
    yields (arrays of any shape, a fresh iterator per call; non-finite values ignored).

    Examples
    --------
    >>> from geoterrain.codec.quantchoice import choose_quantizer
    >>> z = np.random.default_rng(0).normal(100, 30, (64, 64))
    >>> bands = lambda: (z[i:i + 8] for i in range(0, 64, 8))
    >>> band_quantizer(bands, np.float32, 0.5) == choose_quantizer(z, np.float32, 0.5)
    True
    """
    dt = np.dtype(src_dtype)
    sc = 1.0 if scale is None else float(scale)
    off = 0.0 if offset is None else float(offset)
    exact, f32, n, vmax = True, True, 0, 0.0
    lo, hi = np.inf, -np.inf
    # finer grids (quantchoice.fine_quantizer), checked only once the heights have left
    # the integers: an integer passes a binary or float64 decimal step exactly when
    # |x| / step < 2^52, so the integer bands before count through their largest |x|
    # (vmax so far); a candidate rounded to float32 also needs every value to be a
    # float32 (an odd integer above 2^24 is not), which f32 tracks over every band
    cands = fine_candidates(dt)
    fine = np.ones(len(cands) if fine_grids_apply(scale, offset, codec_error) else 0,
                   np.bool_)
    to_f32 = np.array([c[2] for c in cands], np.bool_)[:fine.size]
    for v in bands():
        v = _finite(v)
        if v.size:
            e, f = _grid_checks(v, sc, off)
            was = exact
            exact, f32 = exact and e, f32 and f
            if not f32:
                fine &= ~to_f32
            if not exact and fine.any():
                if was:
                    fine_steps_ok(np.array([vmax]), dt, fine)
                fine_steps_ok(v, dt, fine)
            n += v.size
            vmax = max(vmax, float(np.abs(v).max()))
            lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
    lossy = codec_error is not None and codec_error > 0
    if exact and (not lossy or 2.0 * float(codec_error) <= sc):
        return Quantizer("int", sc, off, 0.0)
    if exact:  # a lossy bound on a known grid: bins of its codes

        def bins_error(k: int) -> float:
            return max((_roundtrip_error(_finite(v), sc, off, k)[0] for v in bands()),
                       default=0.0)

        return grid_bins_quantizer(float(codec_error), sc, off, vmax, bins_error)
    q = fine_quantizer(fine, dt, codec_error) if fine.size else None
    if q is not None:
        return q
    if lossy:
        eps = float(codec_error)
        if offset is None and n:
            k = n // 2
            if n % 2:
                med = _kth(bands, k, lo, hi)
            else:  # np.median: the mean of the two middle values
                m1, m2 = _kth(bands, k - 1, lo, hi), _kth(bands, k, lo, hi)
                med = float((np.float64(m1) + np.float64(m2)) / 2.0)
            off = float(np.round(med))
        elif offset is None:
            off = 0.0

        def roundtrip_error(step: float) -> tuple[float, float]:
            err, peak = 0.0, 0.0
            for v in bands():
                e, p = _roundtrip_error(_finite(v), step, off)
                err, peak = max(err, e), max(peak, p)
            return err, peak

        return lossy_quantizer(eps, off, vmax, n > 0, roundtrip_error)
    return float_quantizer(dt, f32)

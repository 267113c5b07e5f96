"""Rounding that keeps a bound a bound.

A bound computed in float64 and stored narrower (float32 for δ and r, float16 in the
tile blobs) must never come out smaller than the exact value, or a mesh that meets the
stored bound could miss the true one. Both helpers round to nearest and step one ulp up
where that went down. :func:`round_up` does it on arrays (numpy), :func:`round_up32` on
one float64 inside the compiled kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["round_up", "round_up32"]


def round_up(a: np.ndarray, dtype: type = np.float32) -> np.ndarray:
    """``a`` as ``dtype`` (float32 or float16), rounded up: every result ≥ its input.

    Infinities and values already representable are kept exactly.

    Examples
    --------
    >>> a = np.array([0.1, 1.0, np.inf])
    >>> b = round_up(a)
    >>> b.dtype, bool((b.astype(float) >= a).all()), float(b[1])
    (dtype('float32'), True, 1.0)
    >>> float(round_up(np.array([1000.1]), np.float16)[0])
    1000.5
    """
    a = np.asarray(a, dtype=np.float64)
    f = a.astype(dtype)
    low = f.astype(np.float64) < a  # rounding went down: step up one ulp
    f[low] = np.nextafter(f[low], dtype(np.inf))
    return f


@njit(cache=True)
def round_up32(a):
    """One float64 ``a`` ≥ 0 to float32, rounded up (compiled; same result as
    :func:`round_up`).

    Avoids a library call: when rounding went down, ff * (1 + 2**-24) lies in
    [f + ulp/2, f + ulp) and rounds to f + ulp, unless f is a power of two (tie to even)
    or subnormal, which the two fallbacks catch.

    Examples
    --------
    >>> float(round_up32(0.1)) >= 0.1, float(round_up32(0.5))
    (True, 0.5)
    """
    f = np.float32(a)
    ff = np.float64(f)
    if ff >= a:
        return f
    g = np.float32(ff * (1.0 + 2.0 ** -24))
    if g == f:
        g = np.float32(ff * (1.0 + 2.0 ** -23))
        if g == f:
            g = np.float32(ff + 2.0 ** -149)
    return g

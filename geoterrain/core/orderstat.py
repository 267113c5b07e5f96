"""Exact order statistics of values handed out in bands (a raster too large for memory).

:func:`kth_smallest` narrows a histogram of the values to one bin around the rank, pass
after pass, then sorts only that bin's values (a bin of equal values needs no sort); a
few passes read the data. :func:`median` is ``np.median``'s value, exactly.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

__all__ = ["kth_smallest", "median"]

Bands = Callable[[], Iterator[np.ndarray]]
BINS = 1 << 16
SORT_MAX = 1 << 22  # heights sorted at once in the median's last pass


def _finite(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64).ravel()
    return a[np.isfinite(a)]


def _counts(bands: Bands, a: float, b: float) -> tuple[int, int, float, float]:
    # (finite heights < a, finite heights in [a, b], their min and max)
    below = inside = 0
    lo, hi = np.inf, -np.inf
    for v in bands():
        v = _finite(v)
        below += int(np.count_nonzero(v < a))
        v = v[(v >= a) & (v <= b)]
        if v.size:
            inside += v.size
            lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
    return below, inside, lo, hi


def _kth(bands: Bands, k: int, lo: float, hi: float) -> float:
    """The k-th smallest finite height (0-based), exactly, every height in [lo, hi]."""
    below, inside, a, b = _counts(bands, lo, hi)
    while a < b and inside > SORT_MAX:
        # a histogram of [a, b] finds the bin of rank k; the next interval is that bin
        # widened by one bin each side (an index computed in floats may be off by one)
        w = (b - a) / BINS
        counts = np.zeros(BINS, np.int64)
        for v in bands():
            v = _finite(v)
            v = v[(v >= a) & (v <= b)]
            counts += np.bincount(np.clip(((v - a) / w).astype(np.int64), 0, BINS - 1),
                                  minlength=BINS)
        i = int(np.searchsorted(np.cumsum(counts), k - below, side="right"))
        a2, b2 = max(a, a + (i - 1) * w), min(b, a + (i + 2) * w)
        if (a2, b2) == (a, b):  # no narrower interval in floats: sort what is left
            break
        below, inside, a, b = _counts(bands, a2, b2)  # a, b: the heights there
    if a == b:  # one height holds every rank left (a flat run): no sort
        return a
    vals = np.concatenate([v[(v >= a) & (v <= b)] for v in map(_finite, bands())])
    vals.sort()
    return float(vals[k - below])




def kth_smallest(bands: Bands, k: int) -> float:
    """The k-th smallest finite value (0-based) that ``bands()`` yields (a fresh iterator
    of arrays per call).

    Examples
    --------
    >>> z = np.random.default_rng(0).normal(size=1000)
    >>> bool(kth_smallest(lambda: iter(np.split(z, 10)), 500) == np.sort(z)[500])
    True
    """
    lo = min((float(v.min()) for v in map(_finite, bands()) if v.size), default=0.0)
    hi = max((float(v.max()) for v in map(_finite, bands()) if v.size), default=0.0)
    return float(_kth(bands, k, lo, hi))


def median(bands: Bands) -> float | None:
    """``np.median`` of the finite values ``bands()`` yields, exactly (None: no value).

    Examples
    --------
    >>> z = np.random.default_rng(1).normal(size=1000)
    >>> bool(median(lambda: iter(np.split(z, 8))) == np.median(z))
    True
    """
    n = sum(_finite(v).size for v in bands())
    if not n:
        return None
    if n % 2:
        return kth_smallest(bands, n // 2)
    m1, m2 = kth_smallest(bands, n // 2 - 1), kth_smallest(bands, n // 2)
    return float((np.float64(m1) + np.float64(m2)) / 2.0)

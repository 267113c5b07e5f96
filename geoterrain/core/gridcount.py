"""The summed-area table of a valid mask (:func:`geoterrain.core.grid.footprint_counts`),
compiled; apart from :mod:`geoterrain.core.grid` so that a store's grid loads no compiler."""

from __future__ import annotations

from numba import njit

__all__ = ["integral_nb"]


@njit(cache=True, nogil=True)
def integral_nb(v, ii):  # pragma: no cover - compiled
    """ii[i + 1, j + 1] = the count of v[:i + 1, :j + 1] (a summed-area table, one pass)."""
    for i in range(v.shape[0]):
        run = 0
        for j in range(v.shape[1]):
            run += v[i, j]
            ii[i + 1, j + 1] = ii[i, j + 1] + run

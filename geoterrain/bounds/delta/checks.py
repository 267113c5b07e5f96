"""Checks of stored δ: a tile's δ against its own vertices' errors (on read), and the
largest finite δ (the store's ``delta_max_finite``)."""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.bounds.delta.exact import vertex_errors  # noqa: F401 (the doctests')

__all__ = ["below_own_error", "delta_max_finite"]


# ------------------------------------------------------------- a check on read
@njit(cache=True, nogil=True)
def _below_own_error_nb(d, z, valid):
    """Flat index of the first vertex whose δ is below its own error (|z_v − the mean of
    its split edge's ends|), or −1. A centre vertex takes the smaller of its two
    diagonals' (the union-jack parity depends on the tile's place); only vertices whose
    corners are all valid are checked (a mixed diamond's δ is +inf)."""
    T = d.shape[0]
    h = 1
    while h < T - 1:
        for i in range(0, T, h):
            for j in range(0, T, h):
                oi = (i // h) & 1
                oj = (j // h) & 1
                if oi + oj == 0 or not valid[i, j]:
                    continue
                zv = z[i, j]
                if oi + oj == 2:  # the centre of a 2h block
                    if not (valid[i - h, j - h] and valid[i + h, j + h]
                            and valid[i - h, j + h] and valid[i + h, j - h]):
                        continue
                    a, b = z[i - h, j - h], z[i + h, j + h]
                    c, e = z[i - h, j + h], z[i + h, j - h]
                    err = min(abs(zv - 0.5 * (a + b)), abs(zv - 0.5 * (c + e)))
                    mag = abs(a) + abs(b) + abs(c) + abs(e)
                else:  # the midpoint of a row or column edge
                    if oi:
                        a, b, ok = z[i - h, j], z[i + h, j], valid[i - h, j] and valid[i + h, j]
                    else:
                        a, b, ok = z[i, j - h], z[i, j + h], valid[i, j - h] and valid[i, j + h]
                    if not ok:
                        continue
                    err = abs(zv - 0.5 * (a + b))
                    mag = abs(a) + abs(b)
                # float64 rounding of the two computations of the same error
                if d[i, j] < err - 1e-12 * (mag + abs(zv)) - 1e-300:
                    return i * T + j
        h *= 2
    return -1


def below_own_error(delta: np.ndarray, z: np.ndarray, valid: np.ndarray
                    ) -> tuple[int, int] | None:
    """The first vertex (i, j) of a tile whose δ is below its own error, or None.

    δ(v) is the largest error over v's diamond (seed 002 §2.3), which holds v itself:
    |z_v − (z_a + z_b) / 2| for its split edge (a, b). A δ table swapped with another
    tile's, or edited, fails this on almost any terrain that is not flat, which checksums
    alone (anyone can recompute them) cannot see.

    Examples
    --------
    >>> z = np.array([[0.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    >>> ok = np.ones((3, 3), bool)
    >>> d = vertex_errors(z, ok)
    >>> below_own_error(d, z, ok) is None, below_own_error(d * 0, z, ok)
    (True, (1, 1))
    """
    k = int(_below_own_error_nb(np.ascontiguousarray(delta), np.ascontiguousarray(z, np.float64),
                                np.ascontiguousarray(valid, np.bool_)))
    return None if k < 0 else divmod(k, delta.shape[1])


@njit(cache=True, nogil=True)
def _finite_max_nb(a):
    m = 0.0
    for v in a.ravel():
        if np.isfinite(v) and v > m:
            m = v
    return m


def delta_max_finite(delta: np.ndarray) -> float:
    """The largest finite δ, or 0 (the store's ``delta_max_finite``), without copying
    the finite values.

    Examples
    --------
    >>> delta_max_finite(np.array([0.5, np.inf, 2.0, np.nan], np.float32))
    2.0
    """
    return float(_finite_max_nb(delta))  # a float32 value is exact in float64

"""The rows a band reads: ``rows(i0, i1)`` callbacks over a grid held anywhere (a
rasterio window, a scratch file, memory), a padded grid's replicated edge, and a checked
window of them (:func:`geoterrain.bounds.delta.check_grid`'s rules)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["Rows", "edge_rows", "grid_shape", "rows_of"]


Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


def grid_shape(N: int | tuple[int, int]) -> tuple[int, int]:
    """(rows, cols) of a grid given as its side N (a square) or as (rows, cols).

    Examples
    --------
    >>> grid_shape(5), grid_shape((5, 9))
    ((5, 5), (5, 9))
    """
    if isinstance(N, tuple | list):
        return int(N[0]), int(N[1])
    return int(N), int(N)


def rows_of(z: np.ndarray, valid: np.ndarray) -> Rows:
    """A ``rows`` callback over in-memory arrays (tests, small grids).

    Examples
    --------
    >>> z, v = rows_of(np.arange(9.0).reshape(3, 3), np.ones((3, 3), bool))(1, 3)
    >>> z.shape
    (2, 3)
    """
    return lambda i0, i1: (z[i0:i1], valid[i0:i1])


def edge_rows(rows: Rows, data: tuple[int, int]) -> Rows:
    """The rows of :func:`geoterrain.bounds.edgepad.edge_support`'s grid: the padding of a grid
    whose data is its top-left ``data = (rows, cols)`` replicated from the data's last
    column and row (a nodata sample there makes its copies nodata).

    Examples
    --------
    >>> z = np.array([[1.0, 2.0, 0.0], [3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    >>> v = np.array([[1, 1, 0], [1, 1, 0], [0, 0, 0]], bool)
    >>> edge_rows(rows_of(z, v), (2, 2))(1, 3)[0].tolist()
    [[3.0, 4.0, 4.0], [3.0, 4.0, 4.0]]
    """
    H, W = data

    def replicated(i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
        src = np.minimum(np.arange(i0, i1), H - 1)  # rows past the data: its last one
        lo, hi = int(src.min()), int(src.max()) + 1
        z, v = rows(lo, hi)
        z = np.array(np.asarray(z, np.float64)[src - lo])
        v = np.array(np.asarray(v, bool)[src - lo])
        z[:, W:] = z[:, W - 1:W]
        v[:, W:] = v[:, W - 1:W]
        z[~v] = np.nan
        return z, v

    return replicated


def _window(rows: Rows, i0: int, i1: int, C: int) -> tuple[np.ndarray, np.ndarray]:
    # check_grid's rules on a window: non-finite heights are invalid, invalid heights 0
    z, v = rows(i0, i1)
    z = np.asarray(z, dtype=np.float64)
    v = np.asarray(v, dtype=bool)
    if z.shape != (i1 - i0, C) or v.shape != z.shape:
        raise ValueError(f"rows({i0}, {i1}) gave {z.shape} and {v.shape}, "
                         f"expected ({i1 - i0}, {C})")
    v = v & np.isfinite(z)
    z = np.where(v, z, 0.0)
    return np.ascontiguousarray(z), np.ascontiguousarray(v)

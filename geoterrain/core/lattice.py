"""Proxy positions past level 0's lattice of a geographic root grid (:meth:`Frame.xy`).

Past the lattice (R, C) (a = R − 1, b = C − 1) a sample's scene position is

    P(i, j) = P(i', j') + d_i·(P(a, j') − P(a − 1, j')) + d_j·(P(i', b) − P(i', b − 1))

with i' = min(i, a), j' = min(j, b), d_i = max(i − a, 0), d_j = max(j − b, 0): each column
continued past the lattice's last row by its last step, each row past its last column
likewise, the corner by both; pyproj's positions on the lattice. ``project(x, y)`` is the
frame's pyproj transform into the scene (x, y its own arrays), ``crs_xy(i, j)`` the CRS
coordinates of samples; ``edges`` gives :func:`lattice_edges`' arrays (made once per frame).

Examples
--------
>>> import numpy as np
>>> crs_xy = lambda i, j: (np.asarray(j, float), -np.asarray(i, float))
>>> project = lambda x, y: (2.0 * x, 2.0 * y)  # an affine stand-in for pyproj
>>> ed = lattice_edges((3, 3), project, crs_xy)
>>> X, Y = lattice_xy((3, 3), project, crs_xy, lambda: ed, np.array([1, 4]), np.array([1, 5]),
...                   *crs_xy(np.array([1, 4]), np.array([1, 5])))
>>> X.tolist(), Y.tolist()  # an affine map is its own continuation
([2.0, 10.0], [-2.0, -8.0])
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Project = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

__all__ = ["lattice_edges", "lattice_xy"]


def lattice_xy(lattice: tuple[int, int], project: Project, crs_xy: Project,
               edges: Callable[[], tuple[np.ndarray, np.ndarray]], i, j, x: np.ndarray,
               y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scene X, Y of samples (i, j) (CRS coordinates x, y): pyproj's on the lattice, the
    proxy past it (the module's formula)."""
    a, b = lattice[0] - 1, lattice[1] - 1
    i, j = np.asarray(i, np.float64), np.asarray(j, np.float64)
    if (i.ndim == j.ndim == 2 and i.shape[1] == 1 and j.shape[0] == 1 and i.size
            and j.size and i.min() >= 0 and j.min() >= 0
            and (i == np.floor(i)).all() and (j == np.floor(j)).all()):
        return _band(lattice, project, edges, i[:, 0], j[0], x, y)
    i, j = np.broadcast_arrays(i, j)
    past = (i > a) | (j > b)
    if not past.any():
        return project(x, y)
    x, y = np.broadcast_arrays(x, y)
    X, Y = np.empty(x.shape), np.empty(x.shape)
    inside = ~past
    if inside.any():
        X[inside], Y[inside] = project(x[inside], y[inside])
    ip, jp = i[past], j[past]
    di, dj = np.maximum(ip - a, 0.0), np.maximum(jp - b, 0.0)
    ic, jc = np.minimum(ip, a), np.minimum(jp, b)
    ki, kj = ic.astype(np.int64), jc.astype(np.int64)
    if (ki == ic).all() and (kj == jc).all() and ki.min() >= 0 and kj.min() >= 0:
        rows, cols = edges()  # the lattice's last two rows and columns
        ra, rb = rows[0][:, kj], rows[1][:, kj]
        ca, cb = cols[0][:, ki], cols[1][:, ki]
    else:  # fractional or negative indices: the same pyproj values, point by point
        n = len(ic)
        ii = np.concatenate([np.full(n, float(a)), np.full(n, a - 1.0), ic, ic])
        jj = np.concatenate([jc, jc, np.full(n, float(b)), np.full(n, b - 1.0)])
        ex, ey = crs_xy(ii, jj)
        ex, ey = project(ex, np.clip(ey, -90.0, 90.0))
        e = np.stack([ex, ey]).reshape(2, 4, n)
        ra, rb, ca, cb = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
    # the edge point (row a's where the point is past the last row, else column b's)
    p = np.where(di > 0, ra, ca)
    X[past] = p[0] + di * (ra[0] - rb[0]) + dj * (ca[0] - cb[0])
    Y[past] = p[1] + di * (ra[1] - rb[1]) + dj * (ca[1] - cb[1])
    return X, Y


def _band(lattice: tuple[int, int], project: Project,
          edges: Callable[[], tuple[np.ndarray, np.ndarray]], ri: np.ndarray, cj: np.ndarray,
          x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # lattice_xy of rows ``ri`` × columns ``cj`` (whole indices, a column against a row:
    # the xy pass's band, grid_xy): the same expression element by element, on the row
    # and the column instead of the broadcast pairs
    a, b = lattice[0] - 1, lattice[1] - 1
    prow, pcol = ri > a, cj > b
    if not (prow.any() or pcol.any()):
        return project(x, y)
    x, y = np.broadcast_arrays(x, y)
    X, Y = np.empty(x.shape), np.empty(x.shape)
    rin, cin = ~prow, ~pcol
    if rin.any() and cin.any():
        block = np.ix_(rin, cin)
        X[block], Y[block] = project(x[block], y[block])
    di, dj = np.maximum(ri - a, 0.0), np.maximum(cj - b, 0.0)
    ki, kj = np.minimum(ri, a).astype(np.int64), np.minimum(cj, b).astype(np.int64)
    rows, cols = edges()
    for k, V in ((0, X), (1, Y)):
        ra, rb = rows[0][k][kj], rows[1][k][kj]
        ca, cb = cols[0][k][ki], cols[1][k][ki]
        sr, sc = ra - rb, ca - cb
        if prow.any():  # past the last row: row a's point, both steps
            V[prow] = (ra[None, :] + di[prow, None] * sr[None, :]) \
                + dj[None, :] * sc[prow, None]
        if rin.any() and pcol.any():  # on the lattice's rows, past its last column
            V[np.ix_(rin, pcol)] = (ca[rin, None] + di[rin, None] * sr[None, pcol]) \
                + dj[None, pcol] * sc[rin, None]
    return X, Y


def lattice_edges(lattice: tuple[int, int], project: Project, crs_xy: Project
                  ) -> tuple[np.ndarray, np.ndarray]:
    """pyproj's X, Y of the lattice's last two rows, (2, 2, cols): [row a, row a − 1] ×
    [X, Y], and of its last two columns, (2, 2, rows): one pyproj call."""
    R, C = lattice
    a, b = R - 1, C - 1
    ii = np.concatenate([np.full(C, a), np.full(C, a - 1), np.arange(R), np.arange(R)])
    jj = np.concatenate([np.arange(C), np.arange(C), np.full(R, b), np.full(R, b - 1)])
    x, y = crs_xy(ii, jj)
    X, Y = project(x, np.clip(y, -90.0, 90.0))
    rows = np.stack([np.stack([X[:C], Y[:C]]), np.stack([X[C:2 * C], Y[C:2 * C]])])
    cols = np.stack([np.stack([X[2 * C:2 * C + R], Y[2 * C:2 * C + R]]),
                     np.stack([X[2 * C + R:], Y[2 * C + R:]])])
    return rows, cols

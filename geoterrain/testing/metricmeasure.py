"""Measured error of a mesh in the scene's metric x/y (curvilinear grids).

:mod:`geoterrain.testing.measure` interpolates a mesh in grid-index space. On a geographic grid
the scene positions of the samples are curvilinear, so what a user sees is the mesh drawn
with straight edges between the vertices' *metric* positions. This module measures that:
every valid sample is located, by its own scene (X, Y), in the triangles drawn with
their vertices' scene (X, Y), and compared with the triangle's linear interpolant there.

It is deliberately independent of the LOD and bound code (it never reads δ, the
bintree, or the grid indices of the mesh): triangles are found through a uniform hash
of the samples' positions, so it works for any mesh over any set of points.

A sample within ``tol`` metres outside every triangle but inside the ``tol`` band of one
or more is *covered* (the issue allows a small fraction of a sample spacing); its error
there is the triangle's plane, extended, at the sample. A sample farther from every
triangle is *outside*.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["MetricError", "metric_errors", "metric_vertical_error", "metric_screen_error"]

#: Barycentric tolerance for a sample strictly inside (on an edge) of a triangle.
EPS = 1e-9


class SampleHash(NamedTuple):
    """A uniform hash of sample positions: the samples in cell order (``order``), cell
    k's first at ``starts[k]`` (k = row · nx + column, ``starts`` nx·ny + 1 long), the
    grid's origin ``x0``, ``y0``, its cells ``cell`` wide, ``nx`` × ``ny`` of them."""

    order: np.ndarray
    starts: np.ndarray
    x0: float
    y0: float
    cell: float
    nx: int
    ny: int


@njit(cache=True)
def _errors_nb(fx, fy, fz, sx, sy, sz, grid, tol):
    """Per sample (``sx``, ``sy``, ``sz``, hashed in ``grid``: :class:`SampleHash`) the
    largest |plane − z| over the triangles (corners ``fx``, ``fy``, ``fz`` (F, 3)) that
    hold it, and over those within ``tol`` of it (−1: none)."""
    order, starts, x0, y0, cell, nx, ny = grid
    n = sx.shape[0]
    err_in = np.full(n, -1.0)
    err_band = np.full(n, -1.0)
    for t in range(fx.shape[0]):
        ax, bx, cx = fx[t, 0], fx[t, 1], fx[t, 2]
        ay, by, cy = fy[t, 0], fy[t, 1], fy[t, 2]
        det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if not (det != 0.0) or not np.isfinite(det):
            continue
        za, zb, zc = fz[t, 0], fz[t, 1], fz[t, 2]
        if not (np.isfinite(za) and np.isfinite(zb) and np.isfinite(zc)):
            continue
        # altitudes over the edges opposite a, b, c: barycentric λ_k·alt_k = signed distance
        la = np.hypot(cx - bx, cy - by)
        lb = np.hypot(ax - cx, ay - cy)
        lc = np.hypot(bx - ax, by - ay)
        area2 = abs(det)
        ta = tol * la / area2
        tb = tol * lb / area2
        tc = tol * lc / area2
        lo_x = min(ax, bx, cx) - tol
        hi_x = max(ax, bx, cx) + tol
        lo_y = min(ay, by, cy) - tol
        hi_y = max(ay, by, cy) + tol
        c0 = max(int(np.floor((lo_x - x0) / cell)), 0)
        c1 = min(int(np.floor((hi_x - x0) / cell)), nx - 1)
        r0 = max(int(np.floor((lo_y - y0) / cell)), 0)
        r1 = min(int(np.floor((hi_y - y0) / cell)), ny - 1)
        inv = 1.0 / det
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                k = r * nx + c
                for q in range(starts[k], starts[k + 1]):
                    s = order[q]
                    px = sx[s] - ax
                    py = sy[s] - ay
                    l1 = (px * (cy - ay) - py * (cx - ax)) * inv  # weight of b
                    l2 = ((bx - ax) * py - (by - ay) * px) * inv  # weight of c
                    l0 = 1.0 - l1 - l2
                    if l0 < -ta or l1 < -tb or l2 < -tc:
                        continue
                    e = abs(za * l0 + zb * l1 + zc * l2 - sz[s])
                    if l0 >= -EPS and l1 >= -EPS and l2 >= -EPS:
                        if e > err_in[s]:
                            err_in[s] = e
                    elif e > err_band[s]:
                        err_band[s] = e
    return err_in, err_band


def metric_errors(faces: np.ndarray, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray,
                  X: np.ndarray, Y: np.ndarray, Z: np.ndarray, valid: np.ndarray,
                  tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample |mesh − Z| located in scene x/y, and the mask of valid samples outside.

    Parameters
    ----------
    faces : (F, 3) vertex indices of the drawn triangles.
    vx, vy, vz : (V,) scene positions of the vertices (metres).
    X, Y, Z : sample scene positions and heights (any shape, the same).
    valid : samples to measure.
    tol : metres; a sample within ``tol`` of a triangle counts as covered by it.

    Returns
    -------
    err : float64 like Z, the worst error over the triangles that hold the sample (those
        within ``tol`` when none holds it strictly); NaN where invalid or outside.
    outside : bool like Z, valid samples farther than ``tol`` from every triangle.

    Examples
    --------
    >>> f = np.array([[0, 1, 2]])
    >>> vx, vy, vz = np.array([0.0, 2, 0]), np.array([0.0, 0, 2]), np.zeros(3)
    >>> X, Y = np.array([0.5, 1.5]), np.array([0.5, 1.5])
    >>> err, out = metric_errors(f, vx, vy, vz, X, Y, np.array([1.0, 0.0]), np.ones(2, bool))
    >>> err.tolist(), out.tolist()
    ([1.0, nan], [False, True])
    """
    shape = np.shape(Z)
    X, Y, Z = (np.asarray(a, np.float64).reshape(-1) for a in (X, Y, Z))
    ok = np.asarray(valid, bool).reshape(-1) & np.isfinite(X) & np.isfinite(Y) & np.isfinite(Z)
    idx = np.flatnonzero(ok)
    err = np.full(Z.size, np.nan)
    outside = np.zeros(Z.size, bool)
    fc = np.asarray(faces, np.int64).reshape(-1, 3)
    if idx.size == 0:
        return err.reshape(shape), outside.reshape(shape)
    sx, sy, sz = X[idx], Y[idx], Z[idx]
    # uniform hash of the samples, cells about one sample spacing wide
    x0, y0 = float(sx.min()), float(sy.min())
    span = max(float(sx.max()) - x0, float(sy.max()) - y0, 1e-9)
    cell = max(span / max(np.sqrt(idx.size), 1.0), 1e-9)
    nx = int((float(sx.max()) - x0) // cell) + 1
    ny = int((float(sy.max()) - y0) // cell) + 1
    key = ((sy - y0) // cell).astype(np.int64) * nx + ((sx - x0) // cell).astype(np.int64)
    order = np.argsort(key, kind="stable")
    starts = np.searchsorted(key[order], np.arange(nx * ny + 1))
    vx, vy, vz = (np.asarray(a, np.float64) for a in (vx, vy, vz))
    if fc.size:
        e_in, e_band = _errors_nb(vx[fc], vy[fc], vz[fc], sx, sy, sz,
                                  SampleHash(order, starts, x0, y0, cell, nx, ny), float(tol))
    else:
        e_in = e_band = np.full(idx.size, -1.0)
    e = np.where(e_in >= 0, e_in, e_band)
    err[idx] = np.where(e >= 0, e, np.nan)
    outside[idx] = e < 0
    return err.reshape(shape), outside.reshape(shape)


@dataclass(frozen=True)
class MetricError:
    """Statistics of a metric error (vertical metres, or pixels for a screen error) over
    the covered valid samples, and the count of valid samples outside the mesh."""

    max: float
    n_samples: int
    n_outside: int


def metric_vertical_error(faces, vx, vy, vz, X, Y, Z, valid, tol: float = 0.0,
                          among: np.ndarray | None = None) -> MetricError:
    """Vertical error in scene x/y (see :func:`metric_errors`); ``among`` restricts the
    outside count (e.g. to the samples an index-space interpolation covers).

    Examples
    --------
    >>> f = np.array([[0, 1, 2]]); v = np.array([0.0, 2, 0]), np.array([0.0, 0, 2])
    >>> metric_vertical_error(f, *v, np.zeros(3), np.array([0.5]), np.array([0.5]),
    ...                       np.array([0.25]), np.ones(1, bool))
    MetricError(max=0.25, n_samples=1, n_outside=0)
    """
    err, out = metric_errors(faces, vx, vy, vz, X, Y, Z, valid, tol)
    if among is not None:
        out = out & np.asarray(among, bool)
    e = err[np.isfinite(err)]
    return MetricError(float(e.max()) if e.size else 0.0, int(e.size), int(out.sum()))


def metric_screen_error(faces, vx, vy, vz, X, Y, Z, valid, eye, planes, lam: float,
                        tol: float = 0.0) -> MetricError:
    """Screen-space error ρ = lam·|mesh − Z| / ‖(X, Y, Z) − eye‖ in scene x/y, over valid
    samples inside the frustum (``planes``: (6, 4) inward planes); ``n_outside`` counts
    the in-frustum valid samples outside the mesh.

    Examples
    --------
    >>> f = np.array([[0, 1, 2]]); v = np.array([0.0, 2, 0]), np.array([0.0, 0, 2])
    >>> planes = np.zeros((6, 4)); planes[:, 3] = 1.0
    >>> metric_screen_error(f, *v, np.zeros(3), np.array([0.5]), np.array([0.5]),
    ...                     np.array([1.0]), np.ones(1, bool), np.array([0.5, 0.5, 11.0]),
    ...                     planes, 10.0)
    MetricError(max=1.0, n_samples=1, n_outside=0)
    """
    X, Y, Z = (np.asarray(a, np.float64) for a in (X, Y, Z))
    planes = np.asarray(planes, np.float64).reshape(-1, 4)
    inside = np.asarray(valid, bool) & np.isfinite(Z)
    with np.errstate(invalid="ignore"):
        for a, b, c, d in planes:
            inside &= (a * X + b * Y + c * Z + d) >= 0.0
    err, out = metric_errors(faces, vx, vy, vz, X, Y, Z, inside, tol)
    eye = np.asarray(eye, np.float64).reshape(3)
    dist = np.sqrt((X - eye[0]) ** 2 + (Y - eye[1]) ** 2 + (Z - eye[2]) ** 2)
    ok = np.isfinite(err)
    rho = float(lam) * err[ok] / np.maximum(dist[ok], 1e-300)
    return MetricError(float(rho.max()) if rho.size else 0.0, int(rho.size), int(out.sum()))

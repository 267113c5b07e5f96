"""Measured error of a triangle mesh against the full-resolution DEM.

This module is deliberately independent of the LOD and error-bound code: it
rasterises the drawn mesh back onto the integer grid samples and compares it
with the true heights, so it can be used to check those bounds.

The mesh lives in grid-parameter space: ``vertices_ij`` holds (row ``i``,
column ``j``) grid coordinates, ``faces`` indexes three vertices per triangle
and ``vertex_z`` gives each vertex's height. The surface is the linear
(barycentric) interpolant on every triangle. Triangles are closed: a sample on
an edge or a corner is covered by every triangle that touches it (with a small
tolerance). Where several triangles cover one sample with different heights
(a crack or a T-junction), the error there is the worst over those triangles.
Degenerate triangles and triangles with a non-finite corner are not drawn.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import pyvista as pv

__all__ = [
    "ScreenError",
    "VerticalError",
    "mesh_height_range_on_grid",
    "mesh_heights_on_grid",
    "picture_coordinates",
    "picture_displacement",
    "screen_space_change",
    "screen_space_error",
    "vertical_error",
    "vertical_error_polydata",
]

#: Barycentric tolerance: a sample is inside when every coordinate is >= -EPS.
EPS = 1e-9
#: Maximum number of (triangle, bbox-sample) candidates evaluated at once.
_CHUNK_ELEMENTS = 1 << 17


def _size_classes(limit: int) -> np.ndarray:
    """Bounding-box side classes: 1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, ... up to ``limit``."""
    sizes = {1, 2, 3}
    k = 1
    while True:
        a, b = (1 << k) + 1, 3 * (1 << (k - 1)) + 1
        sizes.update((a, b))
        if a >= limit:
            break
        k += 1
    return np.array(sorted(sizes), dtype=np.int64)


def _rasterise(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    shape: tuple[int, int],
    sink: Callable[[np.ndarray, np.ndarray], None],
) -> None:
    """Rasterise triangles, calling ``sink(flat_sample_index, z)`` on chunks of hits.

    A sample is hit once by every closed triangle that contains it.
    """
    H, W = int(shape[0]), int(shape[1])
    vij = np.asarray(vertices_ij, dtype=np.float64).reshape(-1, 2)
    fc = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    vz = np.asarray(vertex_z, dtype=np.float64).reshape(-1)
    if vz.shape[0] != vij.shape[0]:
        raise ValueError("vertex_z must have one height per vertex")
    if fc.size == 0 or H == 0 or W == 0:
        return
    if fc.min() < 0 or fc.max() >= vij.shape[0]:
        raise ValueError("faces index a vertex that does not exist")

    vi = np.ascontiguousarray(vij[:, 0])
    vj = np.ascontiguousarray(vij[:, 1])
    f0, f1, f2 = (np.ascontiguousarray(fc[:, k]) for k in range(3))
    i0, i1, i2 = vi.take(f0), vi.take(f1), vi.take(f2)
    j0, j1, j2 = vj.take(f0), vj.take(f1), vj.take(f2)
    z0, z1, z2 = vz.take(f0), vz.take(f1), vz.take(f2)
    tol = 1e-7
    bi = np.ceil(np.minimum(np.minimum(i0, i1), i2) - tol)
    np.maximum(bi, 0, out=bi)
    bj = np.ceil(np.minimum(np.minimum(j0, j1), j2) - tol)
    np.maximum(bj, 0, out=bj)
    hi_i = np.floor(np.maximum(np.maximum(i0, i1), i2) + tol)
    np.minimum(hi_i, H - 1, out=hi_i)
    hi_j = np.floor(np.maximum(np.maximum(j0, j1), j2) + tol)
    np.minimum(hi_j, W - 1, out=hi_j)
    with np.errstate(invalid="ignore"):
        ni = hi_i - bi + 1  # bbox sample counts (rows, cols), as floats
        nj = hi_j - bj + 1
        e1i, e1j, e2i, e2j = i1 - i0, j1 - j0, i2 - i0, j2 - j0
        det = e1i * e2j - e1j * e2i
        keep = (det != 0) & np.isfinite(det) & (ni > 0) & (nj > 0)
        keep &= np.isfinite(z0) & np.isfinite(z1) & np.isfinite(z2)
    if not keep.any():
        return
    ni = np.where(keep, ni, 1).astype(np.int64)
    nj = np.where(keep, nj, 1).astype(np.int64)
    sizes = _size_classes(int(max(ni[keep].max(), nj[keep].max(), 1)))
    ci = np.searchsorted(sizes, ni)
    cj = np.searchsorted(sizes, nj)
    cls = ci * len(sizes) + cj
    cls[~keep] = -1
    order = np.argsort(cls, kind="stable")
    order = order[np.count_nonzero(~keep) :]  # dropped triangles sort first
    cls = cls.take(order)
    starts = np.r_[0, np.flatnonzero(np.diff(cls)) + 1]
    ends = np.r_[starts[1:], cls.size]

    # Permute every per-triangle quantity so that each size class is a contiguous slice.
    i0, j0, z0 = i0.take(order), j0.take(order), z0.take(order)
    e1i, e1j, e2i, e2j = e1i.take(order), e1j.take(order), e2i.take(order), e2j.take(order)
    dz1, dz2 = z1.take(order) - z0, z2.take(order) - z0
    det, bi, bj = det.take(order), bi.take(order), bj.take(order)
    ni, nj, ci, cj = ni.take(order), nj.take(order), ci.take(order), cj.take(order)

    # Barycentrics as affine functions of the offsets (di, dj) from the bbox origin.
    ri = bi - i0
    rj = bj - j0
    inv = 1.0 / det
    a1 = (ri * e2j - rj * e2i) * inv
    b1 = e2j * inv
    c1 = -e2i * inv
    a2 = (e1i * rj - e1j * ri) * inv
    b2 = -e1j * inv
    c2 = e1i * inv
    az = z0 + dz1 * a1 + dz2 * a2
    bz = dz1 * b1 + dz2 * b2
    cz = dz1 * c1 + dz2 * c2
    rowbase = bi.astype(np.int64) * W
    colbase = bj.astype(np.int64)

    for g0, g1 in zip(starts.tolist(), ends.tolist(), strict=True):
        sh = int(sizes[ci[g0]])
        sw = int(sizes[cj[g0]])
        dj = np.arange(sw, dtype=np.float64)[:, None]
        rj = np.arange(sw)[:, None]
        step = max(1, _CHUNK_ELEMENTS // (sh * sw))  # triangles per chunk
        rstep = min(sh, max(1, _CHUNK_ELEMENTS // sw))  # bbox rows per chunk (big triangles)
        for s in range(g0, g1, step):
            t = slice(s, min(s + step, g1))
            row_pad = bool((ni[t] < sh).any())
            col_pad = bool((nj[t] < sw).any())
            for r0 in range(0, sh, rstep):
                ri = np.arange(r0, min(r0 + rstep, sh))[:, None]
                di = ri.astype(np.float64)
                _rasterise_chunk(
                    sink, W, di, dj, ri, rj, a1[t], b1[t], c1[t], a2[t], b2[t], c2[t],
                    az[t], bz[t], cz[t], rowbase[t], colbase[t],
                    ni[t] if row_pad else None, nj[t] if col_pad else None,
                )


def _rasterise_chunk(
    sink: Callable[[np.ndarray, np.ndarray], None],
    W: int,
    di: np.ndarray,
    dj: np.ndarray,
    ri: np.ndarray,
    rj: np.ndarray,
    a1: np.ndarray,
    b1: np.ndarray,
    c1: np.ndarray,
    a2: np.ndarray,
    b2: np.ndarray,
    c2: np.ndarray,
    az: np.ndarray,
    bz: np.ndarray,
    cz: np.ndarray,
    rowbase: np.ndarray,
    colbase: np.ndarray,
    ni: np.ndarray | None,
    nj: np.ndarray | None,
) -> None:
    """Evaluate one chunk: rows ``di`` x columns ``dj`` of the bboxes of some triangles.

    Layout (row offset, col offset, triangle): the long triangle axis is innermost.
    """
    l1 = (a1 + b1 * di)[:, None, :] + (c1 * dj)[None, :, :]
    l2 = (a2 + b2 * di)[:, None, :] + (c2 * dj)[None, :, :]
    mask = l1 >= -EPS
    mask &= l2 >= -EPS
    l1 += l2
    mask &= l1 <= 1.0 + EPS
    if ni is not None:
        mask &= (ri < ni)[:, None, :]
    if nj is not None:
        mask &= (rj < nj)[None, :, :]
    hit = np.flatnonzero(mask)
    if hit.size == 0:
        return
    zf = (az + bz * di)[:, None, :] + (cz * dj)[None, :, :]
    ff = (rowbase + ri * W)[:, None, :] + (colbase + rj)[None, :, :]
    sink(ff.ravel().take(hit), zf.ravel().take(hit))


def mesh_height_range_on_grid(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    shape: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest mesh height at every grid sample over all covering triangles.

    They differ only where triangles overlap with different heights (cracks,
    T-junctions, folded meshes); on a conforming mesh they agree to rounding.

    Parameters
    ----------
    vertices_ij : (V, 2) array of (row, col) grid coordinates (float or int).
    faces : (F, 3) int array of vertex indices.
    vertex_z : (V,) heights.
    shape : (H, W) of the grid.

    Returns
    -------
    zmin, zmax : float64 (H, W); NaN where no triangle covers the sample.

    Examples
    --------
    >>> import numpy as np
    >>> v = np.array([[0, 0], [0, 2], [2, 0]]); f = np.array([[0, 1, 2]])
    >>> zmin, zmax = mesh_height_range_on_grid(v, f, np.array([0.0, 2.0, 4.0]), (3, 3))
    >>> zmin[1, 1], zmax[1, 1], bool(np.isnan(zmin[2, 2]))
    (np.float64(3.0), np.float64(3.0), True)
    """
    H, W = int(shape[0]), int(shape[1])
    zlo = np.full(H * W, np.inf)
    zhi = np.full(H * W, -np.inf)

    def sink(f: np.ndarray, z: np.ndarray) -> None:
        np.minimum.at(zlo, f, z)
        np.maximum.at(zhi, f, z)

    _rasterise(vertices_ij, faces, vertex_z, (H, W), sink)
    empty = zhi == -np.inf
    zlo[empty] = np.nan
    zhi[empty] = np.nan
    return zlo.reshape(H, W), zhi.reshape(H, W)


def mesh_heights_on_grid(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    shape: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """Rasterise a grid-space triangle mesh onto the integer samples of a grid.

    Every triangle is evaluated (barycentric interpolation) on the integer
    samples of its closed area, including edges and corners (tolerance
    ``EPS`` on the barycentric coordinates). Where several triangles cover a
    sample the height of one of them is kept; on a conforming mesh they agree.
    Use :func:`mesh_height_range_on_grid` for the spread where they may not.

    Parameters
    ----------
    vertices_ij : (V, 2) array of (row, col) grid coordinates (float or int).
    faces : (F, 3) int array of vertex indices.
    vertex_z : (V,) heights.
    shape : (H, W) of the grid.

    Returns
    -------
    zmesh : float64 (H, W), NaN where no triangle covers the sample.
    covered : bool (H, W), True where at least one triangle covers the sample.

    Examples
    --------
    >>> import numpy as np
    >>> v = np.array([[0, 0], [0, 2], [2, 0], [2, 2]])
    >>> f = np.array([[0, 1, 2], [1, 3, 2]])
    >>> z, cov = mesh_heights_on_grid(v, f, np.array([0.0, 2.0, 4.0, 6.0]), (3, 3))
    >>> z[1, 1], bool(cov.all())
    (np.float64(3.0), True)
    """
    H, W = int(shape[0]), int(shape[1])
    zmesh = np.full(H * W, np.nan)

    def sink(f: np.ndarray, z: np.ndarray) -> None:
        zmesh[f] = z

    _rasterise(vertices_ij, faces, vertex_z, (H, W), sink)
    zmesh = zmesh.reshape(H, W)
    return zmesh, ~np.isnan(zmesh)


def _worst_abs_error(
    vertices_ij: np.ndarray, faces: np.ndarray, vertex_z: np.ndarray, Z: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample worst |z_triangle - Z| over covering triangles (NaN if uncovered)."""
    Z = np.asarray(Z, dtype=np.float64)
    zf = np.ascontiguousarray(Z).reshape(-1)
    err = np.full(zf.size, -1.0)

    def sink(f: np.ndarray, z: np.ndarray) -> None:
        z -= zf.take(f)
        np.maximum.at(err, f, np.abs(z, out=z))

    _rasterise(vertices_ij, faces, vertex_z, Z.shape, sink)
    covered = err >= 0.0  # NaN heights count as uncovered
    err[~covered] = np.nan
    return err.reshape(Z.shape), covered.reshape(Z.shape)


def _stats(values: np.ndarray) -> tuple[float, float, float]:
    if values.size == 0:
        return 0.0, 0.0, 0.0
    return float(values.max()), float(np.percentile(values, 99)), float(values.mean())


@dataclass(frozen=True)
class VerticalError:
    """Vertical error statistics |zmesh - Z| over valid, covered samples.

    ``max``, ``p99`` and ``mean`` are 0.0 when ``n_samples`` is 0.
    """

    max: float
    p99: float
    mean: float
    n_samples: int
    n_uncovered_valid: int


@dataclass(frozen=True)
class ScreenError:
    """Screen-space error statistics ρ = lam·|zmesh - Z| / distance to the eye.

    ``n_samples`` counts valid, covered samples inside the frustum; ``n_uncovered``
    counts valid samples inside the frustum that no triangle covers.
    """

    max: float
    p99: float
    mean: float
    n_samples: int
    n_uncovered: int = 0


def vertical_error(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    Z: np.ndarray,
    valid: np.ndarray | None = None,
) -> VerticalError:
    """Measured vertical error of a mesh against the true heights ``Z``.

    Parameters
    ----------
    vertices_ij, faces, vertex_z : the mesh in grid space (see module docstring).
    Z : (H, W) true heights, in the same units as ``vertex_z``.
    valid : (H, W) bool; invalid samples are ignored. Default: all valid.

    Returns
    -------
    VerticalError
        Statistics of |zmesh - Z| (worst over covering triangles at each sample)
        over valid covered samples, and the number of valid uncovered samples.

    Examples
    --------
    >>> import numpy as np
    >>> Z = np.zeros((3, 3)); Z[1, 1] = 1.0
    >>> v = np.array([[0, 0], [0, 2], [2, 0], [2, 2]]); f = np.array([[0, 1, 2], [1, 3, 2]])
    >>> e = vertical_error(v, f, np.zeros(4), Z, np.ones((3, 3), bool))
    >>> e.max, e.n_samples, e.n_uncovered_valid
    (1.0, 9, 0)
    """
    Z = np.asarray(Z, dtype=np.float64)
    valid = np.ones(Z.shape, bool) if valid is None else np.asarray(valid, dtype=bool)
    if valid.shape != Z.shape:
        raise ValueError("valid and Z must have the same shape")
    err, covered = _worst_abs_error(vertices_ij, faces, vertex_z, Z)
    sel = valid & covered
    e = err[sel]
    mx, p99, mean = _stats(e)
    return VerticalError(mx, p99, mean, int(e.size), int(np.count_nonzero(valid & ~covered)))


def screen_space_error(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    Z: np.ndarray,
    valid: np.ndarray | None,
    eye: np.ndarray,
    planes: np.ndarray,
    lam: float,
) -> ScreenError:
    """Measured screen-space error ρ = lam·|zmesh - Z| / ‖(X, Y, Z) - eye‖.

    Parameters
    ----------
    vertices_ij, faces, vertex_z : the mesh in grid space; ``vertex_z`` in scene units.
    X, Y, Z : (H, W) scene positions of every full-resolution sample.
    valid : (H, W) bool or None (all valid).
    eye : (3,) eye position in scene coordinates.
    planes : (6, 4) inward plane equations; a sample is inside the frustum when
        ``a·X + b·Y + c·Z + d >= 0`` for all six.
    lam : projection factor (pixels per unit of error at unit distance).

    Returns
    -------
    ScreenError
        Statistics of ρ over valid covered samples inside the frustum, and the
        number of valid samples inside the frustum that the mesh does not cover.

    Examples
    --------
    >>> import numpy as np
    >>> i, j = np.mgrid[0:3, 0:3].astype(float)
    >>> v = np.array([[0, 0], [0, 2], [2, 0], [2, 2]]); f = np.array([[0, 1, 2], [1, 3, 2]])
    >>> planes = np.zeros((6, 4)); planes[:, 3] = 1.0  # everything inside
    >>> Z = np.zeros((3, 3))
    >>> e = screen_space_error(v, f, np.ones(4), j, i, Z, None, np.array([1.0, 1.0, 10.0]),
    ...                        planes, 100.0)
    >>> round(e.max, 6), e.n_samples
    (10.0, 9)
    """
    X, Y, Z, eye, inside = _in_frustum(X, Y, Z, valid, planes, eye)
    err, covered = _worst_abs_error(vertices_ij, faces, vertex_z, Z)
    sel = inside & covered
    rho = _projected(lam, err[sel], X[sel], Y[sel], Z[sel], eye)
    mx, p99, mean = _stats(rho)
    return ScreenError(mx, p99, mean, int(rho.size), int(np.count_nonzero(inside & ~covered)))


def _in_frustum(X, Y, Z, valid, planes, eye):
    """float64 X, Y, Z and eye, and the valid samples inside every frustum plane."""
    Z = np.asarray(Z, dtype=np.float64)
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    valid = np.ones(Z.shape, bool) if valid is None else np.asarray(valid, dtype=bool)
    planes = np.asarray(planes, dtype=np.float64).reshape(-1, 4)
    eye = np.asarray(eye, dtype=np.float64).reshape(3)
    if not (X.shape == Y.shape == Z.shape == valid.shape):
        raise ValueError("X, Y, Z and valid must have the same shape")
    inside = valid.copy()
    with np.errstate(invalid="ignore"):
        for a, b, c, d in planes:  # six planes, each vectorised over the grid
            inside &= (a * X + b * Y + c * Z + d) >= 0.0
    return X, Y, Z, eye, inside


def _projected(lam, dz, X, Y, Z, eye):
    """λ·dz / d (seed 002 eq. 2's ρ) at samples X, Y, Z; inf where d = 0 < dz."""
    dist = np.sqrt((X - eye[0]) ** 2 + (Y - eye[1]) ** 2 + (Z - eye[2]) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dist > 0, float(lam) * dz / dist, np.where(dz > 0, np.inf, 0.0))


def picture_coordinates(X, Y, Z, look_from, look_at, up, fov_y_deg: float,
                        size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where scene points fall in a pinhole picture: column and row in pixels (from the
    top left corner) and depth along the view.

    The camera is VTK's (``tests/rendering`` checks it against VTK's own projection):
    it looks from ``look_from`` at ``look_at``, ``up`` tilts it, ``fov_y_deg`` spans
    the picture's ``size`` (width, height) height, square pixels. A point at depth z,
    x right and y up of the view axis, is (W/2 + f·x/z, H/2 − f·y/z) with
    f = (H/2)/tan(fov_y/2) pixels.

    Examples
    --------
    >>> import numpy as np
    >>> c, r, z = picture_coordinates(np.array([0.0, 1.0]), np.array([10.0, 10.0]),
    ...                               np.zeros(2), (0, 0, 0), (0, 1, 0), (0, 0, 1), 90.0,
    ...                               (200, 100))
    >>> c.tolist(), r.tolist(), z.tolist()
    ([100.0, 105.0], [50.0, 50.0], [10.0, 10.0])
    """
    e = np.asarray(look_from, np.float64)
    f = np.asarray(look_at, np.float64) - e
    f /= np.linalg.norm(f)
    right = np.cross(f, np.asarray(up, np.float64))
    right /= np.linalg.norm(right)
    top = np.cross(right, f)
    px = (size[1] / 2.0) / np.tan(np.radians(fov_y_deg) / 2.0)
    dx, dy, dz = X - e[0], Y - e[1], Z - e[2]
    depth = dx * f[0] + dy * f[1] + dz * f[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        col = size[0] / 2.0 + px * (dx * right[0] + dy * right[1] + dz * right[2]) / depth
        row = size[1] / 2.0 - px * (dx * top[0] + dy * top[1] + dz * top[2]) / depth
    return col, row, depth


def picture_displacement(
    vertices_ij: np.ndarray,
    faces: np.ndarray,
    vertex_z: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    Z: np.ndarray,
    valid: np.ndarray | None,
    view,
    per_sample: bool = False,
) -> ScreenError | tuple[ScreenError, np.ndarray]:
    """How far the drawn surface moves each sample in the picture, in pixels (with
    ``per_sample``, also each counted sample's displacement).

    Every valid sample (X, Y, Z) the mesh covers is projected twice through ``view``'s
    camera (:func:`picture_coordinates`; ``view`` has ``look_from``, ``look_at``,
    ``up``, ``fov_y_deg``, ``size`` and the frustum ``planes``): at its true height and
    at the mesh's height there (the lowest and the highest where triangles disagree),
    and the distance between the two pictures is its displacement. A sample counts when
    its true point or its drawn point (either height) lies inside the frustum: every
    sample the picture shows, at its place or at a wrong one (a sample just outside
    the frustum drawn just inside counts, as a culled vertex's could be;
    :func:`screen_space_error` counts only the first kind). ``n_uncovered``: valid
    samples whose true point is inside and that no triangle covers. This is what a
    planar picture shows, independent of any bound's formula (LP's ρ divides by the
    distance to the eye, the picture by the depth).

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> i, j = np.mgrid[0:3, 0:3].astype(float)
    >>> v = np.array([[0, 0], [0, 2], [2, 0], [2, 2]]); f = np.array([[0, 1, 2], [1, 3, 2]])
    >>> planes = np.zeros((6, 4)); planes[:, 3] = 1.0  # everything inside
    >>> cam = SimpleNamespace(look_from=(1, 1, 10), look_at=(1, 1, 0), up=(0, 1, 0),
    ...                       fov_y_deg=90.0, size=(200, 200), planes=planes)
    >>> e = picture_displacement(v, f, np.ones(4), j, i, np.zeros((3, 3)), None, cam)
    >>> round(e.max, 6), e.n_samples  # a corner, √2 off axis, at depth 10 drawn at 9
    (1.571348, 9)
    >>> round(float(np.sqrt(2) * 100 * (1 / 9 - 1 / 10)), 6)
    1.571348
    """
    planes = np.asarray(view.planes, np.float64)
    X, Y, Z, _, inside = _in_frustum(X, Y, Z, valid, planes, view.look_from)
    ok = np.isfinite(Z)
    lo, hi = mesh_height_range_on_grid(vertices_ij, faces, vertex_z, Z.shape)
    drawn = ok & np.isfinite(lo) if valid is None else ok & np.isfinite(lo) & valid
    shown = inside.copy()
    for zm in (lo, hi):  # drawn inside the frustum from outside it
        shown |= _in_frustum(X, Y, zm, drawn, planes, view.look_from)[4]
    sel = drawn & shown
    x, y = X[sel], Y[sel]
    cam = (view.look_from, view.look_at, view.up, view.fov_y_deg, view.size)
    c0, r0, _ = picture_coordinates(x, y, Z[sel], *cam)
    disp = np.zeros(len(x))
    for zm in (lo[sel], hi[sel]):
        c1, r1, _ = picture_coordinates(x, y, zm, *cam)
        disp = np.maximum(disp, np.hypot(c1 - c0, r1 - r0))
    mx, p99, mean = _stats(disp)
    out = ScreenError(mx, p99, mean, int(disp.size),
                      int(np.count_nonzero(inside & ~np.isfinite(lo))))
    return (out, disp) if per_sample else out


def screen_space_change(
    before: tuple[np.ndarray, np.ndarray, np.ndarray],
    after: tuple[np.ndarray, np.ndarray, np.ndarray],
    X: np.ndarray,
    Y: np.ndarray,
    Z: np.ndarray,
    valid: np.ndarray | None,
    eye: np.ndarray,
    planes: np.ndarray,
    lam: float,
    planes_before: np.ndarray | None = None,
) -> ScreenError:
    """How far the drawn surface jumps between two frames, in pixels (the popping metric).

    Both meshes (``(vertices_ij, faces, vertex_z)`` each) are rasterised onto the grid
    samples; at every valid sample inside the frustum ``planes`` of the second frame
    (and inside ``planes_before``, the first frame's, when given: a sample that comes
    into view was not drawn before, so it cannot pop) that both cover, the change is
    lam·|z_after − z_before| / ‖(X, Y, Z) − eye‖, with ``eye`` and ``lam`` those of
    the second frame. Where triangles overlap with
    different heights (skirts, cracks) the middle of their range is taken, so a
    crack that stays put is not a jump. ``n_uncovered`` counts valid in-frustum samples
    covered by one frame only (drawn or hidden anew: not measured).

    Examples
    --------
    >>> import numpy as np
    >>> i, j = np.mgrid[0:3, 0:3].astype(float)
    >>> v = np.array([[0, 0], [0, 2], [2, 0], [2, 2]]); f = np.array([[0, 1, 2], [1, 3, 2]])
    >>> planes = np.zeros((6, 4)); planes[:, 3] = 1.0
    >>> c = screen_space_change((v, f, np.zeros(4)), (v, f, np.ones(4)), j, i, np.zeros((3, 3)),
    ...                         None, np.array([1.0, 1.0, 10.0]), planes, 100.0)
    >>> round(c.max, 6), c.n_samples
    (10.0, 9)
    """
    X, Y, Z, eye, inside = _in_frustum(X, Y, Z, valid, planes, eye)
    if planes_before is not None:
        inside &= _in_frustum(X, Y, Z, valid, planes_before, eye)[4]
    z = []
    for ij, faces, vz in (before, after):
        lo, hi = mesh_height_range_on_grid(ij, faces, vz, Z.shape)
        z.append(0.5 * (lo + hi))
    both = inside & np.isfinite(z[0]) & np.isfinite(z[1])
    one = inside & (np.isfinite(z[0]) != np.isfinite(z[1]))
    pop = _projected(lam, np.abs(z[1][both] - z[0][both]), X[both], Y[both], Z[both], eye)
    mx, p99, mean = _stats(pop)
    return ScreenError(mx, p99, mean, int(pop.size), int(np.count_nonzero(one)))


def vertical_error_polydata(
    mesh: pv.PolyData, terrain_xyz: np.ndarray, valid: np.ndarray | None = None
) -> VerticalError:
    """Vertical error of a triangulated ``pyvista.PolyData`` against a terrain.

    The mesh's ``point_data["grid_ij"]`` gives each point's (row, col) and its
    points' z the heights. ``terrain_xyz`` is (H, W, 3) scene positions or an
    (H, W) array of heights; NaN heights count as invalid.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> ij = np.array([[0, 0], [0, 2], [2, 0], [2, 2]], float)
    >>> pts = np.c_[ij[:, 1], ij[:, 0], np.zeros(4)]
    >>> m = pv.PolyData(pts, np.array([3, 0, 1, 2, 3, 1, 3, 2])); m.point_data["grid_ij"] = ij
    >>> vertical_error_polydata(m, np.zeros((3, 3))).max
    0.0
    """
    mesh = mesh.triangulate()
    faces = np.asarray(mesh.faces).reshape(-1, 4)[:, 1:]
    ij = np.asarray(mesh.point_data["grid_ij"], dtype=np.float64)
    vz = np.asarray(mesh.points, dtype=np.float64)[:, 2]
    t = np.asarray(terrain_xyz, dtype=np.float64)
    Z = t[..., 2] if t.ndim == 3 else t
    ok = np.isfinite(Z)
    valid = ok if valid is None else (np.asarray(valid, dtype=bool) & ok)
    return vertical_error(ij, faces, vz, np.where(ok, Z, 0.0), valid)

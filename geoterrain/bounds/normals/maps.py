"""Normal maps computed from full-resolution geometry.

Seed 000 (sections 2.9 and 3.9): lighting uses a per-pixel normal map built from the
full-resolution geometry, so it does not change with the level of detail. The thesis uses
a Sobel filter on a regular heightmap; here the tangents come from the 3-D scene
positions, so curvilinear (geographic) grids and vertical exaggeration are handled.

- :func:`normal_map`: unit normals (N, N, 3) float32, central differences (or Horn/Sobel
  weights) of the positions along rows and columns, normal = cross product pointing +Z
  (parallel compiled kernel, float64 arithmetic).
- :func:`level_normal_maps`: the maps of every pyramid level, level L the
  :func:`normal_map` of level L's own samples (every 2**L-th row and column): what a
  store holds, and what its reader derives from a tile's decoded heights and its stored
  border ring at every level (docs/store.md).

Their octahedral codes: :mod:`geoterrain.bounds.normals.codes`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoterrain.core.threads import parallel_kernel, serial_twin

__all__ = ["normal_map", "level_normal_maps"]


def normal_map(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    valid: np.ndarray | None = None,
    kernel: str = "central",
    *,
    serial: bool = False,
) -> np.ndarray:
    """Unit normals (N, N, 3) float32 from full-resolution scene positions.

    Kernel ``"central"``: tangents are central differences of the 3-D positions along
    the rows (``P[i, j+1] - P[i, j-1]``) and along the columns (``P[i+1, j] - P[i-1, j]``);
    one-sided differences at borders and next to invalid samples. Kernel ``"horn"``
    (the Sobel / Horn 3x3 operator of seed 000): each tangent is the 1-2-1 weighted mean
    of the central tangents of the three neighbouring lines. The normal is the normalised
    cross product of the two tangents, oriented so that its Z component is >= 0. With
    only one tangent, the other is taken horizontal and perpendicular to it; an isolated
    sample (no valid neighbour) or a degenerate one gets (0, 0, 1). Never NaN. Invalid
    samples get (0, 0, 1).

    Computed by a parallel compiled kernel, one pass over the positions, all arithmetic
    in float64 (only the result is rounded to float32, so the normal is within 1 float32
    ulp per component, about 6e-8, of the exact normal of the float64 tangents; the
    plane tests hold to 1e-6). :func:`geoterrain.testing.reference.normal_map_reference` is the
    vectorised numpy oracle (same formulas) the tests compare against.

    Parameters
    ----------
    x, y, z : (N, N) float
        Scene positions (x, y may be curvilinear; z includes vertical exaggeration).
    valid : (N, N) bool, optional
        Valid samples (default: all finite positions).
    kernel : {"central", "horn"}

    Returns
    -------
    (N, N, 3) float32

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(4.0), np.arange(4.0))
    >>> n = normal_map(j, -i, 0.5 * j, np.ones((4, 4), bool))
    >>> (np.round(n[1, 1].astype(float), 4) + 0.0).tolist()
    [-0.4472, 0.0, 0.8944]
    """
    if kernel not in ("central", "horn"):
        raise ValueError(f"unknown kernel {kernel!r}")
    # no copy of x and y: they may be broadcast views (Frame.grid_xy); z and the mask
    # contiguous and writeable, as a tile's (derived_codes), so that the kernels compile
    # for one layout (a pyramid level's z is a strided view: copied)
    x, y = (np.asarray(a, dtype=np.float64) for a in (x, y))
    z = np.require(z, np.float64, ("C", "W"))
    if not (x.shape == y.shape == z.shape) or x.ndim != 2:
        raise ValueError("x, y and z must be 2-D arrays of the same shape")
    v = (
        np.ones(x.shape, np.bool_)
        if valid is None
        else np.require(np.broadcast_to(np.asarray(valid, np.bool_), x.shape), None,
                        ("C", "W"))
    )
    out = np.empty((*x.shape, 3), np.float32)
    if x.size:
        if serial:  # the same code without threads (a tile; a fork() child)
            vv = SERIAL_KERNELS["_valid_finite_nb"](x, y, z, v)
            SERIAL_KERNELS["_normals_nb"](x, y, z, vv, kernel == "horn", out)
        else:
            vv = _valid_finite_nb(x, y, z, v)
            _normals_nb(x, y, z, vv, kernel == "horn", out)
    return out


def level_normal_maps(x: np.ndarray, y: np.ndarray, z: np.ndarray,
                      valid: np.ndarray | None, levels: int) -> list[np.ndarray]:
    """Normal maps of pyramid levels 0 … ``levels`` − 1, each (N_L, N_L, 3) float32:
    level L is :func:`normal_map` of level L's own samples (rows and columns
    0, 2**L, 2·2**L, …), central differences at that level's spacing (seed 000's
    normal-map lighting, one map per level of the texture quadtree, §2.5).

    A coarse texel's normal is then the slope across 2·2**L samples through it: the mean
    of the fine slopes along its row and column, so no finer sample is needed, and a
    reader rebuilds it from a tile's decoded heights (the stored border ring supplies the
    neighbours outside the tile).

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(9.0), np.arange(9.0))
    >>> maps = level_normal_maps(j, -i, 0.5 * j, None, 3)
    >>> [m.shape[0] for m in maps]
    [9, 5, 3]
    >>> bool(np.allclose(maps[2], maps[0][::4, ::4]))  # a plane's normal at every level
    True
    """
    if levels < 1:
        raise ValueError("levels must be >= 1")
    out = []
    for L in range(levels):
        s = 1 << L
        out.append(normal_map(x[::s, ::s], y[::s, ::s], z[::s, ::s],
                              None if valid is None else np.asarray(valid)[::s, ::s]))
    return out


@parallel_kernel(cache=True, nogil=True)
def _valid_finite_nb(x, y, z, valid):  # pragma: no cover - compiled
    rows, cols = x.shape
    out = np.empty((rows, cols), np.bool_)
    for i in prange(rows):
        for j in range(cols):
            out[i, j] = (
                valid[i, j]
                and np.isfinite(x[i, j])
                and np.isfinite(y[i, j])
                and np.isfinite(z[i, j])
            )
    return out


@njit(cache=True, nogil=True)
def _tangent_nb(x, y, z, v, i, j, axis):  # pragma: no cover - compiled
    """Central / one-sided tangent at (i, j) along ``axis`` (0: rows i, 1: columns j)."""
    rows, cols = v.shape
    if not v[i, j]:
        return 0.0, 0.0, 0.0, False
    if axis == 0:
        hb = i > 0 and v[i - 1, j]
        hf = i + 1 < rows and v[i + 1, j]
        ib, jb, i_f, jf = i - 1, j, i + 1, j
    else:
        hb = j > 0 and v[i, j - 1]
        hf = j + 1 < cols and v[i, j + 1]
        ib, jb, i_f, jf = i, j - 1, i, j + 1
    if hf and hb:
        return (
            0.5 * ((x[i_f, jf] - x[i, j]) + (x[i, j] - x[ib, jb])),
            0.5 * ((y[i_f, jf] - y[i, j]) + (y[i, j] - y[ib, jb])),
            0.5 * ((z[i_f, jf] - z[i, j]) + (z[i, j] - z[ib, jb])),
            True,
        )
    if hf:
        return x[i_f, jf] - x[i, j], y[i_f, jf] - y[i, j], z[i_f, jf] - z[i, j], True
    if hb:
        return x[i, j] - x[ib, jb], y[i, j] - y[ib, jb], z[i, j] - z[ib, jb], True
    return 0.0, 0.0, 0.0, False


@njit(cache=True, nogil=True)
def _horn_nb(x, y, z, v, i, j, axis):  # pragma: no cover - compiled
    """1-2-1 mean of the ``axis`` tangents of the lines across ``axis`` (Horn / Sobel)."""
    rows, cols = v.shape
    ax, ay, az, h = _tangent_nb(x, y, z, v, i, j, axis)
    w = 2.0 if h else 0.0
    ax, ay, az = w * ax, w * ay, w * az
    for d in (-1, 1):
        if axis == 1:
            ii, jj = i + d, j
            inside = 0 <= ii < rows
        else:
            ii, jj = i, j + d
            inside = 0 <= jj < cols
        if inside:
            bx, by, bz, hh = _tangent_nb(x, y, z, v, ii, jj, axis)
            if hh:
                ax += bx
                ay += by
                az += bz
                w += 1.0
    if w > 0.0:
        s = 1.0 / max(w, 1.0)
        return ax * s, ay * s, az * s, True
    return 0.0, 0.0, 0.0, False


@parallel_kernel(cache=True, nogil=True)
def _normals_nb(x, y, z, v, horn, out):  # pragma: no cover - compiled
    rows, cols = v.shape
    for ip in prange(rows):
        i = np.int64(ip)  # prange's index may be unsigned: int64 for the helpers' arithmetic
        for j in range(cols):
            out[i, j, 0] = 0.0
            out[i, j, 1] = 0.0
            out[i, j, 2] = 1.0
            if not v[i, j]:
                continue
            if (not horn and 0 < i < rows - 1 and 0 < j < cols - 1 and v[i - 1, j]
                    and v[i + 1, j] and v[i, j - 1] and v[i, j + 1]):
                # the common case, straight-line: both central tangents (the arithmetic
                # of _tangent_nb's two-sided branch, so the same bits)
                jx = 0.5 * ((x[i, j + 1] - x[i, j]) + (x[i, j] - x[i, j - 1]))
                jy = 0.5 * ((y[i, j + 1] - y[i, j]) + (y[i, j] - y[i, j - 1]))
                jz = 0.5 * ((z[i, j + 1] - z[i, j]) + (z[i, j] - z[i, j - 1]))
                ix = 0.5 * ((x[i + 1, j] - x[i, j]) + (x[i, j] - x[i - 1, j]))
                iy = 0.5 * ((y[i + 1, j] - y[i, j]) + (y[i, j] - y[i - 1, j]))
                iz = 0.5 * ((z[i + 1, j] - z[i, j]) + (z[i, j] - z[i - 1, j]))
                _unit_cross(jx, jy, jz, ix, iy, iz, out, i, j)
                continue
            # the axis an int64, not a literal: one compilation of each helper for
            # both axes (LLVM still folds it where it inlines them)
            # z[:, :]: an 'A' view, as _ring_guess_nb's tile views (one _tangent_nb)
            if horn:
                jx, jy, jz, hj = _horn_nb(x, y, z[:, :], v, i, j, np.int64(1))
                ix, iy, iz, hi = _horn_nb(x, y, z[:, :], v, i, j, np.int64(0))
            else:
                jx, jy, jz, hj = _tangent_nb(x, y, z[:, :], v, i, j, np.int64(1))
                ix, iy, iz, hi = _tangent_nb(x, y, z[:, :], v, i, j, np.int64(0))
            if not (hi or hj):
                continue
            if hj and not hi:  # missing tangent: horizontal, perpendicular to the other
                ix, iy, iz = -jy, jx, 0.0
            elif hi and not hj:
                jx, jy, jz = iy, -ix, 0.0
            _unit_cross(jx, jy, jz, ix, iy, iz, out, i, j)


@njit(cache=True, nogil=True)
def _unit_cross(jx, jy, jz, ix, iy, iz, out, i, j):  # pragma: no cover - compiled
    """out[i, j] = the unit cross product of the tangents, z up; left (0, 0, 1) where
    it is degenerate."""
    nx = jy * iz - jz * iy
    ny = jz * ix - jx * iz
    nz = jx * iy - jy * ix
    if nz < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    scale = max(abs(jx), abs(jy), abs(jz), abs(ix), abs(iy), abs(iz), 1e-300)
    if length > 1e-12 * scale * scale:
        out[i, j, 0] = nx / length
        out[i, j, 1] = ny / length
        out[i, j, 2] = nz / length


#: the serial twins by kernel name (one tile's work on the calling thread)
SERIAL_KERNELS: dict = {}


for _k in (_valid_finite_nb, _normals_nb):
    SERIAL_KERNELS[_k.__name__] = serial_twin(_k)
del _k  # no second module name for a kernel (a test's spy names it by its name)
_valid_finite_serial = SERIAL_KERNELS["_valid_finite_nb"]
_normals_serial = SERIAL_KERNELS["_normals_nb"]

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
- :func:`level_normal_codes`: those maps' octahedral codes, a band of rows at a time
  (what the whole-grid preprocess stores with every normal);
  :func:`ring_normal_codes`: the same codes on the tiles' border rings only (what it
  stores with derived normals, the default).
- :func:`normal_pyramid`: the maps of every pyramid level, each level a 3x3 binomial
  weighted mean (renormalised) of the previous one around its kept samples (what stores
  held before; kept for comparison, docs/lab/store-size.md).
- :func:`level_normals`: the map for one pyramid level L directly from the full map (box
  mean over each sample's footprint, renormalised; summed-area tables, memory-hungry).
- :func:`encode_octahedral` / :func:`decode_octahedral`: 2-component octahedral packing
  (8 or 16 bits per component), by rounding (default) or with the "precise" encoder
  (best of the 4 nearest codes, ``precise=True``). Measured max angular error over 10**6
  random directions plus the axes (float32 decoded output): rounding 0.935 deg (8 bits),
  0.0037 deg (16 bits); precise 0.632 deg (8 bits), 0.0025 deg (16 bits).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.core.threads import cores_for, forked, parallel_kernel, serial_twin

__all__ = [
    "normal_map",
    "level_normal_maps",
    "level_normal_codes",
    "ring_normal_codes",
    "RingCodes",
    "level_normals",
    "normal_pyramid",
    "encode_octahedral",
    "decode_octahedral",
    "derived_codes",
    "ring_guess",
]

#: measured bounds (degrees) for :func:`encode_octahedral` (default: rounding), see the
#: module docstring
OCTAHEDRAL_MAX_ERROR_DEG = {8: 0.94, 16: 0.0037}
#: measured bounds (degrees) for ``encode_octahedral(..., precise=True)``
OCTAHEDRAL_MAX_ERROR_DEG_PRECISE = {8: 0.64, 16: 0.0025}


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


# rows of a level a band of :func:`level_normal_codes` maps at a time: its float32 map
# (12.6 MB at 4097 columns) instead of the level's (201 MB at 4097²)
NORMAL_BAND = 256


def level_normal_codes(x: np.ndarray, y: np.ndarray, z: np.ndarray,
                       valid: np.ndarray | None, levels: int, bits: int = 8,
                       band: int = NORMAL_BAND) -> list[np.ndarray]:
    """``[encode_octahedral(m, bits) for m in level_normal_maps(x, y, z, valid, levels)]``,
    the same codes, each level mapped and coded ``band`` rows at a time (with one row of
    halo each side: the central differences read no further), so no level's whole float
    map is ever held.

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(9.0), np.arange(9.0))
    >>> z = np.random.default_rng(1).normal(size=(9, 9))
    >>> a = level_normal_codes(j, -i, z, None, 3, band=2)
    >>> b = [encode_octahedral(m) for m in level_normal_maps(j, -i, z, None, 3)]
    >>> all((p == q).all() for p, q in zip(a, b))
    True
    """
    if levels < 1:
        raise ValueError("levels must be >= 1")
    band = max(int(band), 1)
    out = []
    for L in range(levels):
        s = 1 << L
        xl, yl, zl = x[::s, ::s], y[::s, ::s], z[::s, ::s]
        vl = None if valid is None else np.asarray(valid)[::s, ::s]
        n = zl.shape[0]
        codes = np.empty((*zl.shape, 2), np.uint8 if bits == 8 else np.uint16)
        for i0 in range(0, n, band):
            i1 = min(i0 + band, n)
            a, b = max(i0 - 1, 0), min(i1 + 1, n)  # one row of halo each side
            m = normal_map(xl[a:b], yl[a:b], zl[a:b], None if vl is None else vl[a:b])
            codes[i0:i1] = encode_octahedral(m[i0 - a:i1 - a], bits)
        out.append(codes)
    return out


def _take(a: np.ndarray, idx: np.ndarray, axis: int) -> np.ndarray:
    """``np.take(a, idx, axis)``, broadcast again along ``a``'s zero-stride axes (a
    projected grid's x and y, Frame.grid_xy): no copy of what is repeated."""
    a = np.asarray(a)
    sl = tuple(slice(0, 1) if st == 0 else slice(None) for st in a.strides)
    small = a[sl]
    if small.shape[axis] > 1:
        small = np.take(small, idx, axis=axis)
    shape = list(a.shape)
    shape[axis] = len(idx)
    return np.broadcast_to(small, shape)


def _line_indices(n: int, step: int) -> np.ndarray:
    # the lines 0, step, 2·step, … and the last one, n − 1
    return np.unique(np.append(np.arange(0, n, step), n - 1))


class RingCodes(NamedTuple):
    """A level's normal codes on its tiles' border rings (:func:`ring_normal_codes`):
    ``rows`` (k, C, 2) the codes of rows ``lines_r`` (0, 2**t, 2·2**t, …, the last),
    ``cols`` (R, m, 2) those of columns ``lines_c``; the level is R × C samples."""

    rows: np.ndarray
    cols: np.ndarray
    lines_r: np.ndarray
    lines_c: np.ndarray

    def rings(self, xy: np.ndarray, t: int) -> np.ndarray:
        """The rings (k, 4T − 4, 2) of the tiles ``xy`` (k, 2: x, y) of side T = 2**t + 1,
        in :func:`geoterrain.bounds.normalbytes.ring_index`'s order: the top row, the
        bottom row, then the left and the right column without their corners (the full
        map's ``codes[(y << t) + rr, (x << t) + cc]``)."""
        T = (1 << t) + 1
        a, m = np.arange(T), np.arange(1, T - 1)
        x, y = xy[:, 0, None], xy[:, 1, None]
        ri, ci = np.searchsorted(self.lines_r, y << t), np.searchsorted(self.lines_c, x << t)
        top = self.rows[ri, (x << t) + a]
        bottom = self.rows[ri + 1, (x << t) + a]
        left = self.cols[(y << t) + m, ci]
        right = self.cols[(y << t) + m, ci + 1]
        return np.concatenate([top, bottom, left, right], axis=1)


def ring_normal_codes(x: np.ndarray, y: np.ndarray, z: np.ndarray,
                      valid: np.ndarray | None, levels: int, t: int,
                      bits: int = 8) -> list[RingCodes]:
    """:func:`level_normal_codes` on the tiles' border rings only: every level's codes
    on its rows and its columns 0, 2**t, 2·2**t, … and the last one, where the tiles of
    ``2**t`` cells a side have their rings (:class:`RingCodes`, the same values as the
    full codes there). What a store with derived normals holds: a reader derives the
    rest from the heights.

    A sample's normal reads its four neighbours only (central differences), so each
    line is mapped with the lines beside it: a level's rows in one stack of three-row
    strips, its columns in one of three-column strips (a strip's middle line sees
    exactly its neighbours; the grid's first and last line stay first and last in the
    stack, one-sided as in the whole map), about 6 / 2**t of the samples.

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(9.0), np.arange(9.0))
    >>> z = np.random.default_rng(1).normal(size=(9, 9))
    >>> full = level_normal_codes(j, -i, z, None, 2)[0]
    >>> ring = ring_normal_codes(j, -i, z, None, 2, 2)[0]
    >>> bool((ring.rows == full[::4]).all() and (ring.cols == full[:, ::4]).all())
    True
    """
    if levels < 1:
        raise ValueError("levels must be >= 1")
    out = []
    for L in range(levels):
        s = 1 << L
        xl, yl, zl = x[::s, ::s], y[::s, ::s], z[::s, ::s]
        vl = None if valid is None else np.asarray(valid)[::s, ::s]
        got = []
        for axis in (0, 1):
            n = zl.shape[axis]
            lines = _line_indices(n, 1 << t)
            take, mid, at = [], [], 0
            for k in lines.tolist():
                a, b = max(k - 1, 0), min(k + 2, n)
                take.append(np.arange(a, b))
                mid.append(at + k - a)
                at += b - a
            idx = np.concatenate(take)
            m = normal_map(_take(xl, idx, axis), _take(yl, idx, axis),
                           np.take(zl, idx, axis=axis),
                           None if vl is None else np.take(vl, idx, axis=axis))
            m = m[np.asarray(mid)] if axis == 0 else m[:, np.asarray(mid)]
            got.append((encode_octahedral(m, bits), lines))
        out.append(RingCodes(got[0][0], got[1][0], got[0][1], got[1][1]))
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


def _box_sum(a: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Sums of ``a`` (N, N, ...) over boxes rows lo[r]..hi[r], cols lo[c]..hi[c] (closed)."""
    cs = np.zeros((a.shape[0] + 1, a.shape[1] + 1, *a.shape[2:]), np.float64)
    np.cumsum(np.cumsum(a, axis=0, dtype=np.float64), axis=1, out=cs[1:, 1:])
    h1 = hi + 1
    return cs[h1][:, h1] - cs[lo][:, h1] - cs[h1][:, lo] + cs[lo][:, lo]


def level_normals(n_full: np.ndarray, level: int, valid: np.ndarray | None = None) -> np.ndarray:
    """Normal map (N_L, N_L, 3) float32 of pyramid level L from the full-resolution map.

    Level-L sample (a, b) sits at full-resolution (a * 2**L, b * 2**L); its footprint is
    the closed box of half-width 2**(L-1) around it (2**L + 1 samples a side for L >= 1,
    clipped to the grid; neighbouring footprints share their border lines). The result
    is the normalised mean of the (valid) full-resolution normals in that box, computed
    with summed-area tables; (0, 0, 1) where the box holds no valid sample.

    Examples
    --------
    >>> n = np.zeros((5, 5, 3), np.float32); n[..., 2] = 1
    >>> level_normals(n, 2).shape
    (2, 2, 3)
    """
    n_full = np.asarray(n_full, dtype=np.float64)
    size = n_full.shape[0]
    s = 1 << level
    if level == 0:
        idx = np.arange(size)
        lo = hi = idx
    else:
        centre = np.arange(0, size, s)
        lo = np.clip(centre - s // 2, 0, size - 1)
        hi = np.clip(centre + s // 2, 0, size - 1)
    w = np.ones(n_full.shape[:2]) if valid is None else np.asarray(valid, np.float64)
    tot = _box_sum(n_full * w[..., None], lo, hi)
    length = np.linalg.norm(tot, axis=-1, keepdims=True)
    ok = length > 1e-12
    out = np.where(ok, tot / np.where(ok, length, 1.0), np.array([0.0, 0.0, 1.0]))
    return out.astype(np.float32)


def normal_pyramid(n_full: np.ndarray, valid: np.ndarray | None, levels: int) -> list[np.ndarray]:
    """Normal maps of pyramid levels 0 .. ``levels - 1``, each (N_L, N_L, 3) float32.

    The fast replacement of :func:`level_normals` for the whole pyramid: level L + 1 is
    computed from level L alone (one pass per level on shrinking arrays), not from the
    full-resolution map. The filter, exactly:

    - level 0: ``n_0 = n_full`` (as float32, not renormalised), weight
      ``w_0 = valid`` (all ones when ``valid`` is None);
    - level L + 1, sample (a, b) (= level-L sample (2a, 2b)):
      ``s = sum over di, dj in {-1, 0, 1} of k[di] * k[dj] * w_L[2a+di, 2b+dj] *
      n_L[2a+di, 2b+dj]`` with ``k = (1, 2, 1)`` (the binomial 3x3 kernel), neighbours
      outside the level-L grid omitted (no renormalisation of the weights at borders:
      the normalisation below makes it irrelevant). ``n_{L+1} = s / |s|``, or (0, 0, 1)
      when ``|s| <= 1e-12`` (no valid sample, or opposite normals cancelling);
      ``w_{L+1}(a, b) = 1`` if any of the 9 weights ``w_L`` is non-zero, else 0.

    Sums are accumulated in float64 from the float32 inputs. The effective footprint of a
    level-L sample is the closed box of half-width ``2**L - 1`` full-resolution samples
    (tent-like weights), a little wider than the ``2**(L-1)`` box of
    :func:`level_normals`, which smooths the coarse maps slightly more (less aliasing).

    Parameters
    ----------
    n_full : (N, N, 3) float
        Full-resolution unit normals (e.g. :func:`normal_map`).
    valid : (N, N) bool or None
        Valid samples; invalid ones carry no weight at any level.
    levels : int
        Number of levels (>= 1); level L has ``(N - 1) // 2**L + 1`` samples a side.

    Returns
    -------
    list of (N_L, N_L, 3) float32

    Examples
    --------
    >>> n = np.zeros((5, 5, 3), np.float32); n[..., 2] = 1
    >>> [a.shape for a in normal_pyramid(n, None, 3)]
    [(5, 5, 3), (3, 3, 3), (2, 2, 3)]
    """
    if levels < 1:
        raise ValueError("levels must be >= 1")
    cur = np.ascontiguousarray(n_full, dtype=np.float32)
    if cur.ndim != 3 or cur.shape[2] != 3:
        raise ValueError("n_full must be (N, M, 3)")
    if valid is None:
        w = np.ones(cur.shape[:2], np.float32)
    else:
        w = np.ascontiguousarray(np.broadcast_to(valid, cur.shape[:2]), dtype=np.float32)
    out = [cur]
    for _ in range(1, levels):
        rows, cols = (cur.shape[0] + 1) // 2, (cur.shape[1] + 1) // 2
        nxt = np.empty((rows, cols, 3), np.float32)
        wn = np.empty((rows, cols), np.float32)
        _reduce_nb(cur, w, nxt, wn)
        out.append(nxt)
        cur, w = nxt, wn
    return out


@parallel_kernel(cache=True, nogil=True)
def _reduce_part_nb(n, w, i0, rows, out, wout, a0):  # pragma: no cover - compiled
    # rows a0 … of the next level from ``n``, ``w``: this level's rows i0 … of ``rows``
    cols = n.shape[1]
    k = (1.0, 2.0, 1.0)
    for ao in prange(out.shape[0]):
        a = a0 + ao
        for b in range(out.shape[1]):
            sx = 0.0
            sy = 0.0
            sz = 0.0
            anyw = False
            for di in range(3):
                i = 2 * a + di - 1
                if i < 0 or i >= rows:
                    continue
                for dj in range(3):
                    j = 2 * b + dj - 1
                    if j < 0 or j >= cols:
                        continue
                    wt = w[i - i0, j]
                    if wt != 0.0:
                        anyw = True
                        f = k[di] * k[dj] * wt
                        sx += f * n[i - i0, j, 0]
                        sy += f * n[i - i0, j, 1]
                        sz += f * n[i - i0, j, 2]
            length = np.sqrt(sx * sx + sy * sy + sz * sz)
            if length > 1e-12:
                out[ao, b, 0] = sx / length
                out[ao, b, 1] = sy / length
                out[ao, b, 2] = sz / length
            else:
                out[ao, b, 0] = 0.0
                out[ao, b, 1] = 0.0
                out[ao, b, 2] = 1.0
            wout[ao, b] = 1.0 if anyw else 0.0


def _reduce_nb(n, w, out, wout):
    _reduce_part_nb(n, w, 0, n.shape[0], out, wout, 0)


def encode_octahedral(n: np.ndarray, bits: int = 8, precise: bool = False, *,
                      serial: bool = False) -> np.ndarray:
    """Pack unit vectors (..., 3) into octahedral codes (..., 2) uint8 or uint16.

    Default: the projected point rounded to the nearest code. ``precise=True``: of the 4
    codes around the projected point, keeps the one that decodes closest to ``n``. Max
    angular errors: see :data:`OCTAHEDRAL_MAX_ERROR_DEG` (rounding) and
    :data:`OCTAHEDRAL_MAX_ERROR_DEG_PRECISE`. Zero vectors encode (0, 0, 1).
    ``serial``: on the calling thread only (the same code compiled without threads: one
    tile, or a fork() child, where GNU OpenMP aborts a parallel launch).

    Examples
    --------
    >>> e = encode_octahedral(np.array([0.0, 0.0, 1.0]), 16)
    >>> (np.round(decode_octahedral(e, 16).astype(float), 4) + 0.0).tolist()
    [0.0, 0.0, 1.0]
    """
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    n = np.asarray(n)
    if n.shape[-1:] != (3,):
        raise ValueError("n must have shape (..., 3)")
    if n.dtype not in (np.float32, np.float64):
        n = n.astype(np.float64)
    flat = np.ascontiguousarray(n.reshape(-1, 3))
    out = np.empty((flat.shape[0], 2), np.uint8 if bits == 8 else np.uint16)
    (SERIAL_KERNELS["_encode_oct_nb"] if serial else _encode_oct_nb)(flat, (1 << bits) - 1,
                                                              bool(precise), out)
    return out.reshape(*n.shape[:-1], 2)


@njit(cache=True, nogil=True)
def _oct_point(cu, cv, m):  # pragma: no cover - compiled
    """The unnormalised point of code (cu, cv) over ``m``: u, v = 2·code/m − 1, z =
    1 − |u| − |v|, and the lower half folded over (float64)."""
    u = cu / m * 2.0 - 1.0
    v = cv / m * 2.0 - 1.0
    zz = 1.0 - abs(u) - abs(v)
    if zz < 0.0:
        x = (1.0 - abs(v)) * (1.0 if u >= 0.0 else -1.0)
        y = (1.0 - abs(u)) * (1.0 if v >= 0.0 else -1.0)
    else:
        x, y = u, v
    return x, y, zz


@njit(cache=True, nogil=True)
def _oct_dot_nb(cu, cv, m, ux, uy, uz):  # pragma: no cover - compiled
    """Cosine between the decoded code (cu, cv) and the unit vector u."""
    x, y, zz = _oct_point(cu, cv, m)
    return (x * ux + y * uy + zz * uz) / np.sqrt(x * x + y * y + zz * zz)


@njit(cache=True, nogil=True, inline="always")
def _oct_plane(x, y, z, fm):  # pragma: no cover - compiled
    """A direction's point on the octahedron's unfolded plane, scaled to codes: (fu, fv),
    the unit-L1 (x, y, z) (fm = 2^bits − 1)."""
    l1 = abs(x) + abs(y) + abs(z)
    if l1 > 0.0:
        x, y, z = x / l1, y / l1, z / l1
    else:
        x, y, z = 0.0, 0.0, 1.0
    if z < 0.0:
        fx = (1.0 - abs(y)) * (1.0 if x >= 0.0 else -1.0)
        fy = (1.0 - abs(x)) * (1.0 if y >= 0.0 else -1.0)
    else:
        fx, fy = x, y
    fu = (min(max(fx, -1.0), 1.0) * 0.5 + 0.5) * fm
    fv = (min(max(fy, -1.0), 1.0) * 0.5 + 0.5) * fm
    return fu, fv, x, y, z


@parallel_kernel(cache=True, nogil=True)
def _encode_oct_nb(n, m, precise, out):  # pragma: no cover - compiled
    fm = float(m)
    for k in prange(n.shape[0]):
        fu, fv, x, y, z = _oct_plane(float(n[k, 0]), float(n[k, 1]), float(n[k, 2]), fm)
        if not precise:
            out[k, 0] = min(max(np.floor(fu + 0.5), 0.0), fm)
            out[k, 1] = min(max(np.floor(fv + 0.5), 0.0), fm)
            continue
        ln = np.sqrt(x * x + y * y + z * z)
        ux, uy, uz = x / ln, y / ln, z / ln
        bu = 0.0
        bv = 0.0
        best = -np.inf
        for du in range(2):
            for dv in range(2):
                cu = min(max(np.floor(fu) + du, 0.0), fm)
                cv = min(max(np.floor(fv) + dv, 0.0), fm)
                d = _oct_dot_nb(cu, cv, fm, ux, uy, uz)
                if d > best:
                    best, bu, bv = d, cu, cv
        out[k, 0] = bu
        out[k, 1] = bv


def decode_octahedral(e: np.ndarray, bits: int = 8) -> np.ndarray:
    """Unpack octahedral codes (..., 2) into unit vectors (..., 3) float32.

    Examples
    --------
    >>> d = decode_octahedral(encode_octahedral(np.array([0.6, 0.0, -0.8]), 8), 8)
    >>> bool(np.dot(d, [0.6, 0.0, -0.8]) > np.cos(np.radians(0.5)))
    True
    """
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    e = np.asarray(e)
    out = np.empty(e.shape[:-1] + (3,), np.float32)
    _decode_oct_nb(np.ascontiguousarray(e.reshape(-1, 2)), float((1 << bits) - 1),
                   out.reshape(-1, 3))
    return out


@njit(cache=True, nogil=True)
def _decode_oct_nb(e, m, out):  # pragma: no cover - compiled
    """Unit normals of codes ``e`` (n, 2) over ``m`` (:func:`_oct_point`, normalised), one
    compiled pass without temporaries (a tile's texture decodes its normals; the array
    version spent 0.24 ms a 65² tile on temporaries)."""
    for k in range(e.shape[0]):
        x, y, zz = _oct_point(e[k, 0], e[k, 1], m)
        n = np.sqrt(x * x + y * y + zz * zz)
        out[k, 0] = x / n
        out[k, 1] = y / n
        out[k, 2] = zz / n


#: the serial twins by kernel name (one tile's work on the calling thread)
SERIAL_KERNELS: dict = {}


for _k in (_valid_finite_nb, _normals_nb, _encode_oct_nb):
    SERIAL_KERNELS[_k.__name__] = serial_twin(_k)
_valid_finite_serial = SERIAL_KERNELS["_valid_finite_nb"]
_normals_serial = SERIAL_KERNELS["_normals_nb"]
_encode_oct_serial = SERIAL_KERNELS["_encode_oct_nb"]


def derived_codes(h: np.ndarray, zf: float, valid: np.ndarray, x: np.ndarray, y: np.ndarray,
                  rings: np.ndarray, ring: tuple[np.ndarray, np.ndarray],
                  bits: int = 8, residual: bool = False) -> np.ndarray:
    """The normal codes (n, T, T, 2) of tiles whose normal maps are derived on read: each
    tile's :func:`normal_map` (central differences) of scene x, y (n, T, T; broadcast views
    are fine) and z = ``h`` × ``zf`` (heights in source units, as ``Frame.z``) where
    ``valid``, encoded by :func:`encode_octahedral` with ``bits``, and its border ring
    (``ring`` = rows, columns: :func:`~geoterrain.bounds.normalbytes.ring_index`) set to
    ``rings[k]``, the codes stored for it. ``residual`` (schema 17's
    ``normals_ring_residual``): ``rings[k]`` holds each ring code's difference mod 2^bits
    from the tile's own derived code there (:func:`ring_guess`), added back. The tiles
    run on every core, each with the serial kernels (one tile, or a fork() child: on this
    thread).

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(4.0), np.arange(4.0))
    >>> v = np.ones((1, 4, 4), bool)
    >>> z = (0.5 * j)[None]
    >>> want = encode_octahedral(normal_map(j, -i, z[0], v[0]), 8)
    >>> got = derived_codes(z, 1.0, v, j[None], -i[None], want[:1, :1], (np.array([0]),
    ...                     np.array([0])))
    >>> bool(np.array_equal(got[0], want))
    True
    """
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    n, T0, T1 = h.shape
    out = np.empty((n, T0, T1, 2), np.uint8 if bits == 8 else np.uint16)
    if n == 0:
        return out
    kernel = _DERIVED_SERIAL if n == 1 or forked() else _derived_codes_nb
    rr, cc = ring
    kernel(np.ascontiguousarray(h, np.float64), float(zf), np.ascontiguousarray(valid, np.bool_),
           x, y, np.ascontiguousarray(rings), np.asarray(rr, np.int64),
           np.asarray(cc, np.int64), (1 << bits) - 1, bool(residual), out)
    return out


@parallel_kernel(cache=True, nogil=True)
def _derived_codes_nb(h, zf, valid, X, Y, rings, rr, cc, m, residual, out):  # pragma: no cover
    n, T0, T1 = h.shape
    for k in prange(n):  # tiles on every core: each writes its own
        z = np.empty((T0, T1), np.float64)
        for i in range(T0):
            for j in range(T1):
                z[i, j] = h[k, i, j] * zf  # Frame.z
        vv = _valid_finite_serial(X[k], Y[k], z, valid[k])
        nrm = np.empty((T0, T1, 3), np.float32)
        # np.bool_: a bool, not a literal False, as the whole map's calls pass (one
        # compilation of each serial kernel for both)
        _normals_serial(X[k], Y[k], z, vv, np.bool_(False), nrm)
        codes = out[k].reshape((T0 * T1, 2))
        _encode_oct_serial(nrm.reshape((-1, 3)), m, np.bool_(False), codes)
        for q in range(len(rr)):  # the stored border ring
            p = rr[q] * T1 + cc[q]
            if residual:  # the stored difference from the derived code, mod 2^bits
                codes[p, 0] = (codes[p, 0] + rings[k, q, 0]) & m
                codes[p, 1] = (codes[p, 1] + rings[k, q, 1]) & m
            else:
                codes[p, 0] = rings[k, q, 0]
                codes[p, 1] = rings[k, q, 1]


_DERIVED_SERIAL = serial_twin(_derived_codes_nb)


def ring_guess(z: np.ndarray, valid: np.ndarray, x: np.ndarray, y: np.ndarray,
               ring: tuple[np.ndarray, np.ndarray], bits: int = 8,
               origins: np.ndarray | None = None) -> np.ndarray:
    """The codes (k, R, 2) that :func:`derived_codes` derives at each tile's border ring
    (``ring`` = rows, columns, R samples) before it sets the stored ones: the
    :func:`normal_map` of the tile's own (T, T) scene x, y, z (NaN or not ``valid``:
    ignored), whose tangents at its border are one-sided, computed at the ring only, with
    the same compiled arithmetic (the same bits). A store's ring blob holds the
    difference from them (schema 17, ``normals_ring_residual``). ``z``, ``valid``: (k, T,
    T), or with ``origins`` (k, 2: row, column) one 2-D lattice that holds tile k at
    ``origins[k]`` (no copies); ``x``, ``y``: (k, T, T) (broadcast views are fine).

    Examples
    --------
    >>> j, i = np.meshgrid(np.arange(5.0), np.arange(5.0))
    >>> z = np.random.default_rng(4).normal(size=(1, 5, 5)); v = np.ones((1, 5, 5), bool)
    >>> from geoterrain.bounds.normalbytes import ring_index
    >>> rr, cc = ring_index(5)
    >>> full = encode_octahedral(normal_map(j, -i, z[0], v[0]), 8)
    >>> bool((ring_guess(z, v, j[None], -i[None], (rr, cc))[0] == full[rr, cc]).all())
    True
    """
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    rr, cc = ring
    T = x.shape[-1]
    if origins is None:
        n = z.shape[0]
        z = np.ascontiguousarray(z, np.float64).reshape(n * T, T)
        valid = np.ascontiguousarray(valid, np.bool_).reshape(n * T, T)
        origins = np.stack([np.arange(n) * T, np.zeros(n, np.int64)], axis=1)
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    out = np.empty((len(o), len(rr), 2), np.uint8 if bits == 8 else np.uint16)
    if len(o):
        with cores_for(len(o) * T * T):  # tiles on every core (a few: on this thread)
            _ring_guess_nb(np.asarray(z, np.float64), np.asarray(valid, np.bool_), x, y,
                           np.ascontiguousarray(o[:, 0]), np.ascontiguousarray(o[:, 1]),
                           np.asarray(rr, np.int64), np.asarray(cc, np.int64),
                           float((1 << bits) - 1), out)
    return out


@parallel_kernel(cache=True, nogil=True)
def _ring_guess_nb(z, valid, X, Y, r0, c0, rr, cc, fm, out):  # pragma: no cover - compiled
    # _normals_nb's branch off the straight-line case (a border sample never takes it),
    # then _encode_oct_nb's rounding, at the ring's samples of each tile only; the mask
    # (_valid_finite_nb's) only where a ring's tangents read it: within one of the border.
    # Tiles on every core, each with scratch of its own (each tile's codes alone)
    n = r0.shape[0]
    T0, T1 = X.shape[1], X.shape[2]
    for k in prange(n):
        buf = np.empty((1, 1, 3), np.float32)
        vv = np.zeros((T0, T1), np.bool_)
        zk = z[r0[k]:r0[k] + T0, c0[k]:c0[k] + T1]
        vk = valid[r0[k]:r0[k] + T0, c0[k]:c0[k] + T1]
        xk, yk = X[k], Y[k]
        for i in range(T0):
            edge_i = i < 2 or i >= T0 - 2
            for j in range(T1):
                if edge_i or j < 2 or j >= T1 - 2:
                    vv[i, j] = (vk[i, j] and np.isfinite(xk[i, j]) and np.isfinite(yk[i, j])
                                and np.isfinite(zk[i, j]))
        for q in range(rr.shape[0]):
            i, j = rr[q], cc[q]
            buf[0, 0, 0] = 0.0
            buf[0, 0, 1] = 0.0
            buf[0, 0, 2] = 1.0
            if vv[i, j]:
                jx, jy, jz, hj = _tangent_nb(xk, yk, zk, vv, i, j, np.int64(1))
                ix, iy, iz, hi = _tangent_nb(xk, yk, zk, vv, i, j, np.int64(0))
                if hi or hj:
                    if hj and not hi:
                        ix, iy, iz = -jy, jx, 0.0
                    elif hi and not hj:
                        jx, jy, jz = iy, -ix, 0.0
                    _unit_cross(jx, jy, jz, ix, iy, iz, buf, np.int64(0), np.int64(0))
            fu, fv, _, _, _ = _oct_plane(float(buf[0, 0, 0]), float(buf[0, 0, 1]),
                                         float(buf[0, 0, 2]), fm)
            out[k, q, 0] = min(max(np.floor(fu + 0.5), 0.0), fm)
            out[k, q, 1] = min(max(np.floor(fv + 0.5), 0.0), fm)

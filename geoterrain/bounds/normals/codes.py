"""The normal codes a store holds and a reader derives: a level's maps coded a band at a
time, on its tiles' border rings, and derived on read from a tile's decoded heights.

- :func:`level_normal_codes`: the octahedral codes
  (:mod:`~geoterrain.bounds.normals.octahedral`) of every level's normal map
  (:mod:`~geoterrain.bounds.normals.maps`), a band of rows at a time (what the
  whole-grid preprocess stores with every normal);
  :func:`ring_normal_codes`: the same codes on the tiles' border rings only (what it
  stores with derived normals, the default).
- :func:`derived_codes`: the codes of tiles whose maps are derived on read, all in one
  compiled call; :func:`ring_guess`: what it derives at their border rings (the stored
  ring is the difference from it).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from geoterrain.bounds.normals.maps import (
    _normals_serial,
    _tangent_nb,
    _unit_cross,
    _valid_finite_serial,
    level_normal_maps,  # noqa: F401 (its doctests' name)
    normal_map,
)
from geoterrain.bounds.normals.octahedral import _encode_oct_serial, _oct_plane, encode_octahedral
from geoterrain.core.threads import cores_for, forked, parallel_kernel, serial_twin

__all__ = ["level_normal_codes", "ring_normal_codes", "RingCodes", "derived_codes",
           "ring_guess"]

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

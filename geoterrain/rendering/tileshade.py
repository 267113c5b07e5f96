"""One texture tile's default shading in one compiled pass: hypsometric tint × hillshade.

:func:`~geoterrain.rendering.tileshader.tile_rgb` shades a tile as
``colours.colorize`` (the ``auto`` palette's land and water ramps, ``np.interp`` per
channel) × ``shading.tile_hillshade`` (the tile's octahedral normal codes), clipped
and rounded to uint8. Done as numpy
passes, that cost about 0.3 ms of a 65² tile's 0.55 ms. Here it is one pass with the
same float64 ramp arithmetic (numpy's interpolation formula, slope·(x − x_j) + y_j)
and the same float32 product and rounding.

Examples
--------
>>> import numpy as np
>>> from geoterrain.rendering.colours import LAND, WATER
>>> h = np.array([[0.0, 500.0], [1000.0, -5.0]])
>>> codes = np.full((2, 2, 2), 128, np.uint8)  # normals straight up
>>> rgb = shade_tile(h, codes, False, 8, np.array([0, 0, 1], np.float32), 0.35, 1.25,
...                  (-100.0, 1000.0), 0.0, LAND, WATER)
>>> rgb.shape, rgb.dtype.name
((2, 2, 3), 'uint8')
>>> r, g, b = rgb[1, 1].tolist()  # -5 m is below the water level 0: blue
>>> b > r
True
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.core.threads import forked, parallel_kernel, serial_twin
from geoterrain.rendering.shading import oct_shade


class Ramp(NamedTuple):
    """A colour ramp as the compiled shading reads it (:func:`_stops`): its stops ``x``
    (n,), their colours ``c`` (n, 3) and each segment's slopes ``slope`` (n − 1, 3)."""

    x: np.ndarray
    c: np.ndarray
    slope: np.ndarray


class Tint(NamedTuple):
    """The ``auto`` palette's tint as the compiled shading reads it
    (:func:`_palette_args`): land from ``base`` over ``span``; water at or below
    ``wet_level`` when ``has_water``, its depth ramp (when ``depth_ramp``) from
    ``depth_lo`` over ``depth_span``; the land and water ramps (:class:`Ramp`'s arrays,
    flat: a parallel loop takes no tuple of tuples of arrays)."""

    base: float
    span: float
    wet_level: float
    has_water: bool
    depth_lo: float
    depth_span: float
    depth_ramp: bool
    land_x: np.ndarray
    land_c: np.ndarray
    land_slope: np.ndarray
    water_x: np.ndarray
    water_c: np.ndarray
    water_slope: np.ndarray


_RAMPS: dict[tuple, Ramp] = {}


def _stops(ramp) -> Ramp:
    """A ramp's stops, colours (n, 3) and each segment's slopes (n − 1, 3), np.interp's
    (fp[j + 1] − fp[j]) / (xp[j + 1] − xp[j]); cached (the palette's ramps are a few)."""
    key = tuple((float(x), tuple(float(c) for c in col)) for x, col in ramp)
    got = _RAMPS.get(key)
    if got is None:
        xp = np.array([x for x, _ in key], np.float64)
        fp = np.ascontiguousarray(np.array([c for _, c in key], np.float64))
        slope = np.empty((max(len(xp) - 1, 0), 3), np.float64)
        for j in range(len(xp) - 1):  # the same division as numpy's, per segment
            for k in range(3):
                slope[j, k] = (fp[j + 1, k] - fp[j, k]) / (xp[j + 1] - xp[j])
        got = _RAMPS[key] = Ramp(xp, fp, slope)
    return got


@njit(cache=True, nogil=True, inline="always")
def _segment(x, xp):  # pragma: no cover - compiled
    """The ramp segment of ``x`` in [xp[0], xp[-1]]: j with xp[j] <= x < xp[j + 1], or
    n − 1 from the last stop on (np.interp's search, done once for the three channels)."""
    n = len(xp)
    if x >= xp[n - 1]:
        return n - 1
    j = 0
    while j + 1 < n and xp[j + 1] <= x:
        j += 1
    return j


@njit(cache=True, nogil=True, inline="always")
def _ramp(x, j, xp, fp, slope, k):  # pragma: no cover - compiled
    """np.interp(x, xp, fp[:, k]) in segment j (:func:`_segment`), numpy's formula
    slope·(x − x_j) + y_j with the segment's slope computed once (:func:`_stops`)."""
    if j == len(xp) - 1 or xp[j] == x:
        return fp[j, k]
    return slope[j, k] * (x - xp[j]) + fp[j, k]


@njit(cache=True, nogil=True)
def _fill_lut(m, lx, ly, lz, amb, ceil, lut):  # pragma: no cover - compiled
    for a in range(lut.shape[0]):
        for b in range(lut.shape[1]):
            lut[a, b] = oct_shade(float(a), float(b), m, lx, ly, lz, amb, ceil)


_LUTS: dict[tuple, np.ndarray] = {}


def shade_lut(light: np.ndarray, ambient: float, ceiling: float) -> np.ndarray:
    """The hillshade (256, 256) float32 of every 8-bit octahedral code (u, v), under the
    unit ``light`` (:func:`~geoterrain.rendering.shading.oct_shade`, so exactly its values): a
    tile's shading looks its codes up rather than decoding each (0.07 ms of a 65²
    tile). Built once per light (0.5 ms), kept (a few lights a process: 256 kB each).

    Examples
    --------
    >>> lut = shade_lut(np.array([0, 0, 1], np.float32), 0.35, 1.25)
    >>> lut.shape, round(float(lut[128, 128]), 4)  # about straight up, the sun overhead
    ((256, 256), 1.0)
    """
    lt = np.asarray(light, np.float32)
    key = (*lt.tolist(), float(np.float32(ambient)), float(np.float32(ceiling)))
    lut = _LUTS.get(key)
    if lut is None:
        lut = np.empty((256, 256), np.float32)
        _fill_lut(255.0, lt[0], lt[1], lt[2], np.float32(ambient), np.float32(ceiling), lut)
        lut.setflags(write=False)
        _LUTS[key] = lut
    return lut


@njit(cache=True, nogil=True, inline="always")
def _texel(z, s, tint, out, i, j):  # pragma: no cover - compiled
    """One texel: the tint of height ``z`` (metres; NaN: the colour of 0, as nan_to_num)
    × the shade ``s``, clipped and rounded into ``out[i, j]``. The one colour rule of the
    default style, for stored tiles and magnified ones alike."""
    base, span, wet_level, has_water, depth_lo, depth_span, depth_ramp = tint[:7]
    land_x, land_c, land_s, water_x, water_c, water_s = tint[7:]
    one = np.float32(1.0)
    zero = np.float32(0.0)
    if z != z:
        z = 0.0  # nodata: the colour of 0 (nan_to_num)
    wet = has_water and z <= wet_level
    if wet:
        f = 1.0
        if depth_ramp:
            f = min(max((z - depth_lo) / depth_span, 0.0), 1.0)
        xp, fp, sl = water_x, water_c, water_s
    else:
        f = min(max((z - base) / span, 0.0), 1.0)
        xp, fp, sl = land_x, land_c, land_s
    seg = _segment(f, xp)
    for k in range(3):
        w = min(max(np.float32(_ramp(f, seg, xp, fp, sl, k)) * s, zero), one)
        out[i, j, k] = np.uint8(w * np.float32(255) + np.float32(0.5))


@njit(cache=True, nogil=True)
def _shade_tile(h, cf, codes, planar, lut, tint, out):  # pragma: no cover - compiled
    """:func:`shade_tile`'s pass: heights ``h`` (× ``cf``: metres), 8-bit normal
    ``codes`` (flat; ``planar``: as stored), the hillshade ``lut`` (:func:`shade_lut`)
    and the palette's ``tint`` (:class:`Tint`), into ``out`` (T, T, 3)."""
    T0, T1 = h.shape
    if planar:  # two planes of 2-D differences mod 256 (normalbytes.normals_to_bytes)
        uv = np.empty(T0 * T1 * 2, np.uint8)  # to interleaved pairs
        for c in range(2):
            for i in range(T0):
                acc = 0
                for j in range(T1):
                    acc = (acc + codes[c * T0 * T1 + i * T1 + j]) & 255
                    k = 2 * (i * T1 + j) + c
                    uv[k] = acc if i == 0 else (uv[k - 2 * T1] + acc) & 255
        codes = uv
    for i in range(T0):
        for j in range(T1):
            s = lut[codes[2 * (i * T1 + j)], codes[2 * (i * T1 + j) + 1]]
            _texel(h[i, j] * cf, s, tint, out, i, j)


@njit(cache=True, nogil=True)
def _tint_tile(h, cf, shade, tint, out):  # pragma: no cover - compiled
    """A tile's texels from heights ``h`` (× ``cf``: metres) and a ready ``shade``
    (float32), as :func:`_shade_tile` colours them (:func:`_texel`)."""
    T0, T1 = h.shape
    for i in range(T0):
        for j in range(T1):
            _texel(h[i, j] * cf, shade[i, j], tint, out, i, j)


@parallel_kernel(cache=True, nogil=True)
def _tint_tiles(h, cf, shade, tint, out):  # pragma: no cover - compiled
    """:func:`_tint_tile` of each tile of ``h`` on every core."""
    for k in prange(h.shape[0]):
        _tint_tile(h[k], cf, shade[k], tint, out[k])


@njit(cache=True, nogil=True, inline="always")
def _bilerp(a, finite, i0, j0, fy, fx):  # pragma: no cover - compiled
    """``a`` (T, T) bilinear at (i0 + fy, j0 + fx): separable, rows then columns, where
    ``finite`` (the whole source tile is); else the weighted mean of the finite corners,
    NaN where none is (:func:`magnify_tiles`)."""
    v00, v01 = a[i0, j0], a[i0, j0 + 1]
    v10, v11 = a[i0 + 1, j0], a[i0 + 1, j0 + 1]
    if finite:
        t0 = (1.0 - fy) * v00 + fy * v10
        t1 = (1.0 - fy) * v01 + fy * v11
        return (1.0 - fx) * t0 + fx * t1
    num = den = 0.0
    for v, w in ((v00, (1.0 - fy) * (1.0 - fx)), (v01, (1.0 - fy) * fx),
                 (v10, fy * (1.0 - fx)), (v11, fy * fx)):
        if math.isfinite(v):
            num += w * v
            den += w
    return num / den if den > 1e-12 else np.nan


@njit(cache=True, nogil=True)
def _magnify(src, which, oy, ox, k, out):  # pragma: no cover - compiled
    """Each magnified tile's texels, bilinear in its source tile (NaN-aware where the
    source tile holds a non-finite value): :func:`magnify_tiles`."""
    T = src.shape[1]
    S = out.shape[1]
    finite = np.empty(src.shape[0], np.bool_)
    for m in range(src.shape[0]):
        finite[m] = np.isfinite(src[m]).all()
    for n in range(out.shape[0]):
        a = src[which[n]]
        scale = 1.0 / (1 << k[n])
        for r in range(S):
            cy = oy[n] + r * scale
            i0 = min(int(math.floor(cy)), T - 2)
            fy = cy - i0
            for c in range(S):
                cx = ox[n] + c * scale
                j0 = min(int(math.floor(cx)), T - 2)
                fx = cx - j0
                out[n, r, c] = _bilerp(a, finite[which[n]], i0, j0, fy, fx)


@parallel_kernel(cache=True, nogil=True)
def _magnify_tint(h, s, hfin, sfin, which, oy, ox, k, cf, tint, out):  # pragma: no cover
    """:func:`magnify_tint_tiles`'s pass: per texel, :func:`_magnify`'s height and shade
    (the shade rounded to float32, as ``tint_tiles`` takes it), coloured by
    :func:`_texel`; tiles on every core."""
    T = h.shape[1]
    S = out.shape[1]
    for n in prange(out.shape[0]):
        m = which[n]
        scale = 1.0 / (1 << k[n])
        for r in range(S):
            cy = oy[n] + r * scale
            i0 = min(int(math.floor(cy)), T - 2)
            fy = cy - i0
            for c in range(S):
                cx = ox[n] + c * scale
                j0 = min(int(math.floor(cx)), T - 2)
                fx = cx - j0
                z = _bilerp(h[m], hfin[m], i0, j0, fy, fx)
                sh = np.float32(_bilerp(s[m], sfin[m], i0, j0, fy, fx))
                _texel(z * cf, sh, tint, out[n], r, c)


def magnify_tiles(src: np.ndarray, which: np.ndarray, level: np.ndarray, x: np.ndarray,
                  y: np.ndarray, step: int) -> np.ndarray:
    """Magnified tiles' texels (n, step + 1, step + 1) float64 in one compiled pass: tile
    (``level[n]`` < 0, ``x[n]``, ``y[n]``) interpolated bilinearly in ``src[which[n]]``,
    its level-0 tile's array (T, T) (a texel the weighted mean of its finite corners
    where the source tile holds a non-finite value, NaN where none is). The one
    magnification: :func:`geoterrain.rendering.tileshader.magnified` runs it over one
    tile's channels for the other styles.

    Examples
    --------
    >>> a = np.array([[[0.0, 4.0], [8.0, 12.0]]])  # one 2 × 2 level-0 tile (step 1)
    >>> magnify_tiles(a, np.array([0]), np.array([-1]), np.array([0]), np.array([0]),
    ...               2)[0, 1].tolist()
    [4.0, 6.0, 8.0]
    """
    src, which, k, oy, ox, n = _magnified_args(src, which, level, x, y, step)
    out = np.empty((n, int(step) + 1, int(step) + 1))
    if n:
        _magnify(src, which, oy, ox, k, out)
    return out


def _magnified_args(src: np.ndarray, which: np.ndarray, level: np.ndarray, x: np.ndarray,
                    y: np.ndarray, step: int) -> tuple:
    """:func:`magnify_tiles`'s checked arguments: src, which, k, oy, ox (the offsets as
    float64) and n."""
    src = np.ascontiguousarray(src, np.float64)
    which = np.ascontiguousarray(which, np.int64)
    level = np.asarray(level, np.int64)
    n = len(which)
    if src.ndim != 3 or src.shape[1] < 2 or src.shape[2] < 2 or not (
            len(level) == len(x) == len(y) == n):
        raise ValueError("src must be (m, T, T), T >= 2, with one level, x, y per tile")
    if n and (which.min() < 0 or which.max() >= len(src) or level.max() >= 0):
        raise ValueError("which must index src, and every level be below 0")
    k = -level
    mask = np.left_shift(1, k) - 1
    width = np.right_shift(int(step), k)  # a tile's width in level-0 samples
    oy = (np.asarray(y, np.int64) & mask) * width
    ox = (np.asarray(x, np.int64) & mask) * width
    if n and ((oy + width).max() > src.shape[1] - 1 or (ox + width).max() > src.shape[2] - 1):
        raise ValueError("a magnified tile reaches past its source tile")
    return src, which, k, oy.astype(np.float64), ox.astype(np.float64), n


def magnify_tint_tiles(h: np.ndarray, shade: np.ndarray, which: np.ndarray, level: np.ndarray,
                       x: np.ndarray, y: np.ndarray, step: int, cf: float,
                       clim: tuple[float, float], water_level: float | None, land, water,
                       tolerance: float = 0.0, coast: float | None = None) -> np.ndarray:
    """The default style's magnified tiles in one compiled pass on every core:
    ``tint_tiles(magnify_tiles(h, …), cf, magnify_tiles(shade, …).astype(float32), …)``,
    the same bytes, without the two interpolated fields in between (each texel's height
    and shade interpolated and coloured at once). ``h`` and ``shade`` (m, T, T): the
    level-0 tiles' heights (× ``cf``: metres) and hillshade; the other arguments
    :func:`magnify_tiles`'s and :func:`tint_tiles`'s. RGB uint8 (n, step + 1, step + 1, 3).

    Examples
    --------
    >>> from geoterrain.rendering.colours import LAND, WATER
    >>> h = np.array([[[0.0, 400.0], [800.0, 1200.0]]])
    >>> s = np.ones((1, 2, 2))
    >>> a = (np.array([0]), np.array([-1]), np.array([0]), np.array([0]), 2)
    >>> rgb = magnify_tint_tiles(h, s, *a, 1.0, (0.0, 1200.0), None, LAND, WATER)
    >>> want = tint_tiles(magnify_tiles(h, *a), 1.0,
    ...                   magnify_tiles(s, *a).astype(np.float32), (0.0, 1200.0), None,
    ...                   LAND, WATER)
    >>> rgb.shape, bool(np.array_equal(rgb, want))
    ((1, 3, 3, 3), True)
    """
    h, which, k, oy, ox, n = _magnified_args(h, which, level, x, y, step)
    shade = np.ascontiguousarray(shade, np.float64)
    if shade.shape != h.shape:
        raise ValueError("the heights and the shade must be the same (m, T, T)")
    out = np.empty((n, int(step) + 1, int(step) + 1, 3), np.uint8)
    if n == 0:
        return out
    kernel = _SERIAL_MAGNIFY_TINT if n == 1 or forked() else _magnify_tint
    kernel(h, shade, np.isfinite(h).all(axis=(1, 2)), np.isfinite(shade).all(axis=(1, 2)),
           which, oy, ox, k, float(cf),
           _palette_args(clim, water_level, land, water, tolerance, coast), out)
    return out


def tint_tiles(h: np.ndarray, cf: float, shade: np.ndarray, clim: tuple[float, float],
               water_level: float | None, land, water, tolerance: float = 0.0,
               coast: float | None = None) -> np.ndarray:
    """The default style's texels of n tiles from heights ``h`` (n, T, T) (× ``cf``:
    metres; NaN: the colour of 0) and their shade (n, T, T) float32: the same colour rule
    as :func:`shade_tiles` (:func:`_texel`), for tiles whose shade is not one stored normal
    code per texel (a magnified tile's, interpolated at its texels). RGB uint8 (n, T, T, 3).

    Examples
    --------
    >>> from geoterrain.rendering.colours import LAND, WATER
    >>> h = np.array([[[-5.0, 0.5], [100.0, 900.0]]])
    >>> rgb = tint_tiles(h, 1.0, np.ones((1, 2, 2), np.float32), (-100.0, 1000.0), 0.0,
    ...                  LAND, WATER)
    >>> bool(rgb[0, 0, 0, 2] > rgb[0, 0, 0, 0]), bool(rgb[0, 0, 1, 1] > rgb[0, 0, 1, 2])
    (True, True)
    """
    n = h.shape[0]
    out = np.empty((*h.shape, 3), np.uint8)
    if n == 0:
        return out
    kernel = _SERIAL_TINT if n == 1 or forked() else _tint_tiles
    kernel(np.ascontiguousarray(h, np.float64), float(cf),
           np.ascontiguousarray(shade, np.float32),
           _palette_args(clim, water_level, land, water, tolerance, coast), out)
    return out


def shade_tile(h: np.ndarray, codes: np.ndarray, planar: bool, bits: int, light: np.ndarray,
               ambient: float, ceiling: float, clim: tuple[float, float],
               water_level: float | None, land, water, tolerance: float = 0.0) -> np.ndarray:
    """RGB uint8 (T, T, 3): the ``auto`` palette's tint of heights ``h`` (metres, NaN as 0)
    × the hillshade of ``codes`` (8-bit; ``planar``: as stored, else (T, T, 2) pairs).

    ``clim`` is the palette's (lo, hi), ``water_level`` its level or None, ``land`` and
    ``water`` the ramps, ``tolerance`` the heights' codec bound (metres)
    (:data:`geoterrain.rendering.colours.LAND`, ``WATER``). The same arithmetic as
    ``colorize`` × ``shading.hillshade``; see the module example.
    """
    if bits != 8:
        raise ValueError("the fused shading reads 8-bit normal codes")
    T0, T1 = h.shape
    out = np.empty((T0, T1, 3), np.uint8)
    _shade_tile(np.ascontiguousarray(h, np.float64), 1.0,
                np.ascontiguousarray(np.asarray(codes, np.uint8).reshape(-1)),
                bool(planar), shade_lut(light, ambient, ceiling),
                _palette_args(clim, water_level, land, water, tolerance), out)
    return out


def _palette_args(clim, water_level, land, water, tolerance: float = 0.0,
                  coast: float | None = None) -> Tint:
    """The compiled shading's palette :class:`Tint`: base, span, the level at or below
    which it is water, whether there is water, the depth ramp's low end, span and
    whether it ramps, and the land and water ramps (:func:`_stops`); ``tolerance`` and
    ``coast`` as :func:`geoterrain.rendering.colours.colorize`'s."""
    lo, hi = (float(v) for v in clim)
    if hi <= lo:
        lo, hi = lo - 0.5, lo + 0.5
    wl = water_level
    base = max(lo, wl) if wl is not None else lo
    span = max(hi - base, 1e-9)
    wet_level = float(wl) + (tolerance if coast is None else max(tolerance, coast)) \
        if wl is not None else 0.0
    top = float(wl) - tolerance if wl is not None else 0.0  # the depth ramp's surface
    depth_lo = min(lo, top)
    depth_ramp = wl is not None and top > depth_lo
    depth_span = max(top - depth_lo, 1e-9)
    return Tint(float(base), float(span), wet_level, wl is not None, float(depth_lo),
                float(depth_span), bool(depth_ramp), *_stops(land), *_stops(water))


@parallel_kernel(cache=True, nogil=True)
def _shade_tiles(h, cf, codes, lut, tint, out):  # pragma: no cover - compiled
    """:func:`shade_tiles`'s pass: :func:`_shade_tile` of each tile of ``h`` with its
    normal codes ``codes[k]`` (pairs)."""
    n, T0, T1 = h.shape
    for k in prange(n):  # tiles on every core: each writes its own
        _shade_tile(h[k], cf, codes[k].reshape(-1), False, lut, tint, out[k])


def shade_tiles(h: np.ndarray, cf: float, codes: np.ndarray, light: np.ndarray,
                ambient: float, ceiling: float, clim: tuple[float, float],
                water_level: float | None, land, water, tolerance: float = 0.0,
                coast: float | None = None) -> np.ndarray:
    """:func:`shade_tile` of n tiles at once, on every core: RGB uint8 (n, T, T, 3).

    ``h`` (n, T, T) heights in source units (× ``cf`` for metres), ``codes`` (n, T, T, 2)
    their 8-bit normal codes (``TerrainLike.normal_codes``). Each tile's pixels are
    :func:`shade_tile`'s.

    Examples
    --------
    >>> from geoterrain.rendering.colours import LAND, WATER
    >>> from geoterrain.bounds.normals import encode_octahedral, normal_map
    >>> j, i = np.meshgrid(np.arange(4.0), np.arange(4.0))
    >>> h, v = np.stack([3.0 * j * i, 2.0 * j]), np.ones((4, 4), bool)
    >>> codes = np.stack([encode_octahedral(normal_map(j, -i, z, v), 8) for z in h])
    >>> args = (np.array([0, 0, 1], np.float32), 0.35, 1.25, (0.0, 10.0), None, LAND, WATER)
    >>> rgb = shade_tiles(h, 1.0, codes, *args)
    >>> all(np.array_equal(rgb[k], shade_tile(h[k], codes[k], False, 8, *args))
    ...     for k in range(2))
    True
    """
    n, T0, T1 = h.shape
    out = np.empty((n, T0, T1, 3), np.uint8)
    if n == 0:
        return out
    if codes.dtype != np.uint8:
        raise ValueError("the fused shading reads 8-bit normal codes")
    # one tile, or a fork child (no thread pool there): on this thread
    kernel = _SERIAL_TILES if n == 1 or forked() else _shade_tiles
    kernel(np.ascontiguousarray(h, np.float64), float(cf), np.ascontiguousarray(codes),
           shade_lut(light, ambient, ceiling),
           _palette_args(clim, water_level, land, water, tolerance, coast), out)
    return out


_SERIAL_TILES = serial_twin(_shade_tiles)
_SERIAL_TINT = serial_twin(_tint_tiles)
_SERIAL_MAGNIFY_TINT = serial_twin(_magnify_tint)

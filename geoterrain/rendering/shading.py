"""Light on the terrain textures: the sun's direction, a multidirectional hillshade,
cast shadows and ambient occlusion (a sky-view factor).

The hillshade is Lambert's cosine between the stored full-resolution normals and the
sun (seed 000's normal-map lighting), ``AMBIENT + (1 − AMBIENT) · max(n·l, 0) / l_z``,
so flat ground is 1 whatever the sun's height. A multidirectional hillshade averages
four suns 45° apart centred on the given azimuth, so slopes facing any way keep relief.

**Cast shadows** (rayshader's ``ray_shade``, on whole arrays): a sample is in shadow
when the terrain toward the sun rises above the ray from it to the sun. The horizon
is propagated by one sweep per sun direction (compiled): along the sun's dominant
axis, each sample's upstream point q lies one line nearer the sun, and the highest
ray-height seen from q is carried on::

    H(p) = max(z(q), H(q)) − |pq| · tan(elevation),   shadow(p) = H(p) > z(p)

with z(q), H(q) interpolated linearly along the previous line. It is checked against
an independent per-sample ray march (:func:`geoterrain.testing.reference.shadow_reference`).

**Ambient occlusion** is the sky-view factor SVF = 1 − mean_d sin(max(0, θ_d)) over
``DIRECTIONS`` azimuths, θ_d the horizon angle within ``RADIUS`` samples: 1 on a plane
and on peaks, lower in valleys, always in [0, 1].

Textures are shaded per stored tile, so a tile's shadows need the terrain around it:
:func:`tile_light` sweeps a window of the tile's level that reaches as far toward the
sun as the highest terrain can cast a shadow (at most one tile further: a taller
shadow is cut there, and said in the docstring of :func:`shadow_reach`).

Examples
--------
>>> z = np.zeros((9, 9)); z[4, 4] = 2.5
>>> m = shadow_mask(z, np.ones_like(z, bool), 1.0, 90.0, 45.0)  # sun in the east
>>> m[4, :4].tolist(), m[4, 5:].tolist()  # the spike's shadow falls to its west
([False, False, True, True], [False, False, False, False])
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.bounds.normals.octahedral import _oct_point

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

AMBIENT = 0.35  # the shade of a slope facing away from the sun
SHADE_CEILING = 1.25  # the brightest a slope facing the sun gets (flat ground: 1)
SUN_AZIMUTH = 315.0  # degrees clockwise from north: light from the north-west (cartography)
SUN_ELEVATION = 45.0
DIRECTIONS = 8  # sky-view factor: horizon azimuths
RADIUS = 16  # sky-view factor: samples searched per direction
AO_FLOOR = 0.45  # the shade where the sky is all hidden (SVF 0); SVF 1 leaves it unchanged
MULTI_OFFSETS = (-67.5, -22.5, 22.5, 67.5)  # azimuths of the multidirectional suns

__all__ = ["Light", "hillshade", "hillshade_codes", "light_vector", "parse_sun", "shadow_mask",
           "shadow_fraction", "sky_view", "tile_hillshade"]


@dataclass(frozen=True)
class Light:
    """How the textures are lit: sun ``azimuth`` (degrees clockwise from north) and
    ``elevation`` (degrees above the horizon), a ``multidirectional`` hillshade, cast
    ``shadows`` and ``ambient_occlusion``. The default is the classic cartographic
    north-west sun at 45° without shadows: the pictures of earlier releases.

    Examples
    --------
    >>> Light().is_default, Light(shadows=True).is_default
    (True, False)
    """

    azimuth: float = SUN_AZIMUTH
    elevation: float = SUN_ELEVATION
    multidirectional: bool = False
    shadows: bool = False
    ambient_occlusion: bool = False

    def __post_init__(self):
        from geoterrain.exceptions import UsageError

        if not (0.0 < self.elevation <= 90.0):
            raise UsageError(f"the sun's elevation must be in (0, 90] degrees, got "
                             f"{self.elevation:g}", cli="--sun AZ,EL: EL must be in (0, 90]")
        object.__setattr__(self, "azimuth", float(self.azimuth) % 360.0)

    @property
    def is_default(self) -> bool:
        return self == Light()


def parse_sun(text: str) -> tuple[float, float]:
    """``"AZ,EL"`` → (azimuth, elevation) in degrees; a :class:`UsageError` otherwise.

    Examples
    --------
    >>> parse_sun("135,30")
    (135.0, 30.0)
    """
    from geoterrain.exceptions import UsageError

    try:
        az, el = (float(v) for v in str(text).split(","))
    except ValueError:
        raise UsageError(f"the sun must be AZ,EL in degrees (e.g. 135,30), got {text!r}",
                         cli=f"--sun: expected AZ,EL in degrees such as 135,30, got "
                             f"{text!r}") from None
    if not (math.isfinite(az) and math.isfinite(el)):
        raise UsageError(f"the sun must be finite degrees, got {text!r}")
    return az, el


def light_vector(azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector toward the sun in the scene frame (x east, y north, z up).

    Examples
    --------
    >>> np.round(light_vector(90, 0), 6).tolist()
    [1.0, 0.0, 0.0]
    """
    az, el = math.radians(azimuth), math.radians(elevation)
    return np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el),
                     math.sin(el)], np.float32)


#: the default light's unit vector (sun from the north-west at 45°)
DEFAULT_SUN = light_vector(SUN_AZIMUTH, SUN_ELEVATION)


def hillshade(normals: np.ndarray, light: Light = Light(),
              shadow: np.ndarray | None = None) -> np.ndarray:
    """Shade in [AMBIENT, SHADE_CEILING] per unit normal (…, 3): 1 on flat ground,
    AMBIENT in shadow: ``min(AMBIENT + (1 − AMBIENT) · max(n·l, 0) / l_z, SHADE_CEILING)``
    for the sun l (the mean over the suns of a multidirectional light).

    The one hillshade: pictures, the viewer, ``export-raster --what shade`` and the
    exports' textures all shade with it (:func:`hillshade_codes` is its compiled form on
    stored normal codes, for the default light).

    Examples
    --------
    >>> n = np.array([[0, 0, 1.0], [0.6, 0, 0.8]], np.float32)
    >>> np.round(hillshade(n, Light(90, 45)), 3).tolist()  # a slope facing the sun
    [1.0, 1.25]
    """
    azs = [light.azimuth + d for d in MULTI_OFFSETS] if light.multidirectional \
        else [light.azimuth]
    lam = np.zeros(normals.shape[:-1], np.float32)
    for az in azs:
        lv = light_vector(az, light.elevation)
        lam += np.clip(normals @ lv, 0.0, None) / lv[2]  # flat ground: 1
    lam /= len(azs)
    if shadow is not None:  # True / 1: all in shadow; a fraction dims the sun in part
        lam = lam * (1.0 - np.asarray(shadow, np.float32))
    return np.minimum(AMBIENT + (1.0 - AMBIENT) * lam, SHADE_CEILING).astype(np.float32)


def hillshade_codes(codes: np.ndarray, bits: int, light: np.ndarray, ambient: float,
                    ceiling: float) -> np.ndarray:
    """Hillshade (H, W) float32 straight from octahedral codes (H, W, 2), in one compiled
    pass: ``min(ambient + (1 − ambient)·clip(n·l, 0, 1) / l_z, ceiling)`` with ``n`` the
    decoded unit normal (:func:`~geoterrain.bounds.normals.decode_octahedral`, float32)
    and ``l`` the unit ``light``: :func:`hillshade` of the decoded normals, within a
    float32 ulp (the dot product's order of summation).

    A tile's texture needs only this shade: decoding its normals to float32 first
    (and keeping them) cost 0.14 ms a 65² tile and 50 kB of cache.

    Examples
    --------
    >>> from geoterrain.bounds.normals import encode_octahedral
    >>> e = encode_octahedral(np.array([[0.0, 0.0, 1.0]]), 8)
    >>> s = hillshade_codes(e, 8, np.array([0.0, 0.0, 1.0], np.float32), 0.35, 1.25)
    >>> round(float(s[0]), 3)  # the sun overhead lights flat ground fully
    1.0
    """
    if bits not in (8, 16):
        raise ValueError("bits must be 8 or 16")
    e = np.asarray(codes)
    out = np.empty(e.shape[:-1], np.float32)
    lt = np.asarray(light, np.float32)
    _shade_oct_nb(np.ascontiguousarray(e.reshape(-1, 2)), float((1 << bits) - 1), lt[0],
                  lt[1], lt[2], np.float32(ambient), np.float32(ceiling), out.reshape(-1))
    return out


@njit(cache=True, nogil=True)
def _shade_oct_nb(e, m, lx, ly, lz, amb, ceil, out):  # pragma: no cover - compiled
    for k in range(e.shape[0]):
        out[k] = oct_shade(e[k, 0], e[k, 1], m, lx, ly, lz, amb, ceil)


@njit(cache=True, nogil=True, inline="always")
def oct_shade(cu, cv, m, lx, ly, lz, amb, ceil):  # pragma: no cover - compiled
    """The hillshade (float32) of one code (cu, cv) over ``m``, unit light (lx, ly, lz):
    min(amb + (1 − amb)·clip(n·l, 0, 1) / l_z, ceil), n decoded as float32
    (:func:`~geoterrain.bounds.normals.decode_octahedral`). Shared by :func:`hillshade_codes`
    and the fused tile shading (:mod:`geoterrain.rendering.tileshade`)."""
    one = np.float32(1.0)
    x, y, zz = _oct_point(cu, cv, m)
    n = np.sqrt(x * x + y * y + zz * zz)
    d = np.float32(x / n) * lx + np.float32(y / n) * ly + np.float32(zz / n) * lz
    lam = min(max(d, np.float32(0.0)), one) / lz
    return min(amb + (one - amb) * lam, ceil)


def tile_hillshade(terrain: TerrainLike, level: int, x: int, y: int) -> np.ndarray:
    """:func:`hillshade` (default light) of a stored tile's normal map (T, T) float32,
    computed from its normal codes in one compiled pass (:func:`hillshade_codes`) unless
    the terrain's normals are not the stored ones (vertical exaggeration).

    Examples
    --------
    >>> s = tile_hillshade(t, t.grid.top_level, 0, 0)
    >>> s.shape, bool(((s >= AMBIENT - 1e-6) & (s <= SHADE_CEILING)).all())
    ((33, 33), True)
    """
    if not terrain.stored_normals:  # e.g. vertically exaggerated
        return hillshade(terrain.tile_normals(level, x, y))
    return hillshade_codes(terrain.tile_normal_codes(level, x, y), terrain.meta["normal_bits"],
                           DEFAULT_SUN, AMBIENT, SHADE_CEILING)


@njit(cache=True, inline="always")
def _lerp(lo, hi, w):
    # linear between two neighbours; an absent one (−inf: outside or no data) makes
    # the point absent unless it sits exactly on the other (fewer shadows, never more)
    if w == 0.0:
        return lo
    if lo == -np.inf or hi == -np.inf:
        return -np.inf
    return (1.0 - w) * lo + w * hi


@njit(cache=True)
def _sweep(z, d, f, step_rise, transpose):
    """The horizon sweep of the module docstring. Sweep lines are columns (``transpose``
    False) or rows (True); the sun lies toward line index +``d`` (±1), and a ray moves
    ``f`` samples along the line per line crossed. Returns H, the highest ray height."""
    R, C = z.shape
    H = np.full((R, C), -np.inf)
    n_lines, n_along = (R, C) if transpose else (C, R)
    first = n_lines - 1 if d > 0 else 0
    for k in range(1, n_lines):
        line = first - d * k
        up = line + d  # the line nearer the sun
        for a in range(n_along):
            pos = a + f
            lo = int(math.floor(pos))
            w = pos - lo
            if lo < 0 or lo >= n_along or (w > 0.0 and lo + 1 >= n_along):
                continue
            hi = min(lo + 1, n_along - 1)
            if transpose:
                zq = _lerp(z[up, lo], z[up, hi], w)
                hq = _lerp(H[up, lo], H[up, hi], w)
            else:
                zq = _lerp(z[lo, up], z[hi, up], w)
                hq = _lerp(H[lo, up], H[hi, up], w)
            best = max(zq, hq)
            if best > -np.inf:
                if transpose:
                    H[line, a] = best - step_rise
                else:
                    H[a, line] = best - step_rise
    return H


@njit(cache=True)
def _upsample(z, k):
    """Bilinear k× refinement of a grid; a point is known (finite) only where every
    corner it weighs is (−inf: outside the data)."""
    R, C = z.shape
    if k == 1 or R < 2 or C < 2:
        return z.copy()
    out = np.empty(((R - 1) * k + 1, (C - 1) * k + 1))
    for i in range(out.shape[0]):
        i0 = min(i // k, R - 2)
        wi = i / k - i0
        for j in range(out.shape[1]):
            j0 = min(j // k, C - 2)
            wj = j / k - j0
            v = 0.0
            ok = True
            for a, b, w in ((i0, j0, (1 - wi) * (1 - wj)), (i0, j0 + 1, (1 - wi) * wj),
                            (i0 + 1, j0, wi * (1 - wj)), (i0 + 1, j0 + 1, wi * wj)):
                if w > 0.0:
                    if z[a, b] == -np.inf:
                        ok = False
                    else:
                        v += w * z[a, b]
            out[i, j] = v if ok else -np.inf
    return out


def _shadow_fine(z, valid, spacing, azimuth, elevation, supersample):
    """The shadow of every point of the ``supersample``× bilinear refinement, and k."""
    k = max(int(supersample), 1)
    valid = np.asarray(valid, bool)
    z = _upsample(np.where(valid, np.asarray(z, np.float64), -np.inf), k)
    spacing = spacing / k
    az, el = math.radians(azimuth), math.radians(elevation)
    e, n = math.sin(az), math.cos(az)  # toward the sun: east, north
    tan_el = math.tan(el)
    if abs(e) >= abs(n):  # columns are the sweep lines: one column per step
        fi = -n / abs(e)  # rows move north (−i) as the ray goes toward the sun
        step = spacing * math.hypot(1.0, fi)
        H = _sweep(z, 1 if e > 0 else -1, fi, step * tan_el, False)
    else:  # rows are the sweep lines
        fj = e / abs(n)
        step = spacing * math.hypot(1.0, fj)
        H = _sweep(z, -1 if n > 0 else 1, fj, step * tan_el, True)  # north lies toward −i
    tol = 1e-9 * max(1.0, float(np.max(np.abs(np.where(np.isfinite(z), z, 0.0)))))
    return (H > z + tol) & np.isfinite(z), k


def shadow_mask(z: np.ndarray, valid: np.ndarray, spacing: float, azimuth: float,
                elevation: float, supersample: int = 3) -> np.ndarray:
    """Cast shadows: True where the terrain toward the sun hides it (module docstring).

    ``z`` heights in the same units as ``spacing`` (the sample spacing), rows growing
    southwards and columns eastwards; invalid samples cast no shadow and get False.
    The sweep runs on a bilinear ``supersample``× refinement of the grid, so the
    terrain between samples occludes as a bilinear surface does (the ray march of the
    oracle): at 3× the masks agree on ≥ 99.5 % of the samples of real DEM crops, at 1×
    on ≥ 98.4 % (`benchmarks/bench_shading.py`; docs/lab/light.md).
    """
    valid = np.asarray(valid, bool)
    if elevation >= 90.0:
        return np.zeros(valid.shape, bool)
    S, k = _shadow_fine(z, valid, spacing, azimuth, elevation, supersample)
    return valid & S[::k, ::k]


@njit(cache=True)
def _box_mean(S, k, R, C):
    out = np.zeros((R, C), np.float32)
    h = k // 2
    for i in range(R):
        for j in range(C):
            n = 0
            c = 0
            for a in range(max(i * k - h, 0), min(i * k + h, S.shape[0] - 1) + 1):
                for b in range(max(j * k - h, 0), min(j * k + h, S.shape[1] - 1) + 1):
                    n += 1
                    c += S[a, b]
            out[i, j] = c / n
    return out


def shadow_fraction(z: np.ndarray, valid: np.ndarray, spacing: float, azimuth: float,
                    elevation: float, supersample: int = 3) -> np.ndarray:
    """The part of each sample's cell (its k × k supersampled points) in shadow, in
    [0, 1]: soft shadow edges, so the textures of neighbouring pyramid levels agree."""
    valid = np.asarray(valid, bool)
    if elevation >= 90.0:
        return np.zeros(valid.shape, np.float32)
    S, k = _shadow_fine(z, valid, spacing, azimuth, elevation, supersample)
    return np.where(valid, _box_mean(S.astype(np.uint8), k, *valid.shape), 0.0
                    ).astype(np.float32)


@njit(cache=True)
def _svf(z, spacing, di, dj, r0, r1, c0, c1):
    """SVF of the samples [r0, r1) × [c0, c1) of ``z``: ``di``, ``dj`` (D, K) are the
    integer offsets of the K steps of each of the D directions."""
    D, K = di.shape
    out = np.ones((r1 - r0, c1 - c0), np.float32)
    R, C = z.shape
    for i in range(r0, r1):
        for j in range(c0, c1):
            zp = z[i, j]
            if zp == -np.inf:
                continue
            acc = 0.0
            for d in range(D):
                best = 0.0
                for k in range(K):
                    ii, jj = i + di[d, k], j + dj[d, k]
                    if ii < 0 or ii >= R or jj < 0 or jj >= C:
                        break
                    zq = z[ii, jj]
                    if zq == -np.inf:
                        continue
                    sl = (zq - zp) / (spacing * math.hypot(di[d, k], dj[d, k]))
                    if sl > best:
                        best = sl
                acc += best / math.sqrt(1.0 + best * best)  # sin(atan(slope))
            out[i - r0, j - c0] = 1.0 - acc / D
    return out


def _offsets(directions: int, radius: int) -> tuple[np.ndarray, np.ndarray]:
    a = 2.0 * np.pi * np.arange(directions) / directions
    k = np.arange(1, radius + 1)
    di = np.rint(-np.cos(a)[:, None] * k).astype(np.int64)  # north is −row
    dj = np.rint(np.sin(a)[:, None] * k).astype(np.int64)
    return di, dj


def sky_view(z: np.ndarray, valid: np.ndarray, spacing: float, directions: int = DIRECTIONS,
             radius: int = RADIUS) -> np.ndarray:
    """Sky-view factor in [0, 1] per sample (1: the whole sky is open; a plane is 1).

    Examples
    --------
    >>> float(sky_view(np.zeros((5, 5)), np.ones((5, 5), bool), 1.0).min())
    1.0
    """
    return sky_view_core(z, valid, spacing, 0, directions, radius)


def sky_view_core(z: np.ndarray, valid: np.ndarray, spacing: float, m: int,
                  directions: int = DIRECTIONS, radius: int = RADIUS) -> np.ndarray:
    """:func:`sky_view` of the samples at least ``m`` from the edge of ``z`` only (the
    rest of ``z`` is the terrain they see)."""
    z = np.where(valid, np.asarray(z, np.float64), -np.inf)
    di, dj = _offsets(int(directions), int(radius))
    R, C = z.shape
    return _svf(z, float(spacing), di, dj, m, R - m, m, C - m)


def shadow_reach(zmax: float, zmin: float, spacing: float, elevation: float) -> int:
    """Samples toward the sun that can shade a tile: (zmax − zmin) / (tan(el) · spacing).

    :func:`tile_light` caps it at one tile: a shadow cast from further away (a sun lower
    than about atan(relief / tile width)) is cut at the window's edge.

    Examples
    --------
    >>> shadow_reach(100.0, 0.0, 10.0, 45.0)
    10
    """
    if elevation >= 90.0:
        return 0
    reach = max(zmax - zmin, 0.0) / (math.tan(math.radians(elevation)) * spacing)
    return int(math.ceil(reach - 1e-9))


def _level_window(terrain: TerrainLike, level: int, x: int, y: int, m: int):
    """Heights (scene z) and validity of tile (level, x, y) grown by ``m`` ≤ T − 1
    samples of the same level on every side (from the neighbouring stored tiles; the
    grid's edge and unstored tiles are invalid), and the tile's offset in it."""
    g = terrain.grid
    T = g.tile_samples
    n = T - 1
    across, down = g.tiles(level)
    W = n + 1 + 2 * m
    z = np.full((W, W), np.nan)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            tx, ty = x + dx, y + dy
            if not (0 <= tx < across and 0 <= ty < down) or (level, tx, ty) not in \
                    terrain.tile_info:
                continue
            if (dx or dy) and m == 0:
                continue
            h = terrain.tile(level, tx, ty).heights
            # the neighbour's samples in window coordinates, clipped to the window
            r0, c0 = m + dy * n, m + dx * n
            rs, cs = max(0, -r0), max(0, -c0)
            re, ce = min(T, W - r0), min(T, W - c0)
            if rs < re and cs < ce:
                z[r0 + rs:r0 + re, c0 + cs:c0 + ce] = h[rs:re, cs:ce]
    valid = np.isfinite(z)
    return terrain.frame.z(np.where(valid, z, 0.0)), valid


def _highest(terrain: TerrainLike) -> float | None:
    """The highest stored height (scene z): the largest of the root tiles' boxes (each
    holds every height below it), None when none has one."""
    g = terrain.grid
    across, down = g.roots
    tops = [terrain.tile_info.get((g.top_level, x, y), {}).get("zmax")
            for y in range(down) for x in range(across)]
    tops = [z for z in tops if z is not None]
    return max(tops) if tops else None


def tile_shade(terrain: TerrainLike, level: int, x: int, y: int, light: Light, spacing: float
               ) -> np.ndarray:
    """The (T, T) float32 shade of one stored tile under ``light``: the hillshade of its
    normal map, with cast shadows and the sky-view factor when asked. ``spacing`` is
    the finest sample spacing in scene units (a level-L sample is 2^L of it).

    Shadows and the sky-view factor look at the tile's neighbours of the same level, up
    to :func:`shadow_reach` (capped at one tile) and ``RADIUS`` samples away.
    """
    normals = terrain.tile_normals(level, x, y)
    shadow = svf = None
    if light.shadows or light.ambient_occlusion:
        T = terrain.grid.tile_samples
        step = spacing * (1 << level)
        m = 0
        if light.shadows:
            zmax = _highest(terrain)
            info = terrain.tile_info[(level, x, y)]
            if zmax is not None and info["zmin"] is not None:
                m = shadow_reach(zmax, info["zmin"], step, light.elevation)
        if light.ambient_occlusion:
            m = max(m, RADIUS)
        m = min(m, T - 1)
        z, valid = _level_window(terrain, level, x, y, m)
        core = (slice(m, m + T), slice(m, m + T))
        if light.shadows:
            shadow = shadow_fraction(z, valid, step, light.azimuth, light.elevation)[core]
        if light.ambient_occlusion:
            svf = sky_view_core(z, valid, step, m)
    shade = hillshade(normals, light, shadow)
    if svf is not None:
        shade = shade * (AO_FLOOR + (1.0 - AO_FLOOR) * svf)
    return shade.astype(np.float32)

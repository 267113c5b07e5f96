"""Terrain textures: elevation colours × a hillshade from the stored normal maps.

The hillshade comes from the stored *full-resolution* normal maps
(``Terrain.tile_normals``, seed 000 normal-map lighting), so a coarse LOD mesh
textured with it shows the relief of the full DEM.

Examples
--------
>>> img = texture_image(t, "normals")
>>> img.dtype.name, img.shape[2]
('uint8', 3)
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from geoterrain.rendering.colours import Palette, as_palette, colorize

SHADINGS = ("normals", "elevation", "plain")
SUN_AZIMUTH = 315.0  # degrees clockwise from north: light from the north-west (cartography)
SUN_ALTITUDE = 45.0
AMBIENT = 0.35
MAX_TEXTURE = 8193  # samples per side; a larger DEM's texture comes from a coarser level

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


SHADE_CEILING = 1.25  # the brightest a slope facing the sun gets (flat ground: 1)


def _sun() -> np.ndarray:
    az, alt = math.radians(SUN_AZIMUTH), math.radians(SUN_ALTITUDE)
    return np.array([math.sin(az) * math.cos(alt), math.cos(az) * math.cos(alt),
                     math.sin(alt)], np.float32)


def _hillshade(normals: np.ndarray) -> np.ndarray:
    light = _sun()
    lam = np.clip(normals @ light, 0.0, 1.0) / light[2]  # flat ground: 1
    return np.minimum(AMBIENT + (1.0 - AMBIENT) * lam, SHADE_CEILING)


def tile_hillshade(terrain, level: int, x: int, y: int) -> np.ndarray:
    """:func:`_hillshade` of a stored tile's normal map (T, T) float32, computed from the
    stored codes in one compiled pass (:func:`~geoterrain.bounds.normals.hillshade_codes`)
    unless the terrain's normals are not the stored ones (vertical exaggeration).

    Examples
    --------
    >>> s = tile_hillshade(t, t.grid.top_level, 0, 0)
    >>> s.shape, bool(((s >= AMBIENT - 1e-6) & (s <= SHADE_CEILING)).all())
    ((33, 33), True)
    """
    from geoterrain.bounds.normals import hillshade_codes  # compiled: not at import (--help)

    if not getattr(terrain, "stored_normals", False):  # e.g. vertically exaggerated
        return _hillshade(terrain.tile_normals(level, x, y))
    return hillshade_codes(terrain.tile_normal_codes(level, x, y), terrain.meta["normal_bits"],
                           _sun(), AMBIENT, SHADE_CEILING)


def texture_level(terrain, max_size: int = MAX_TEXTURE) -> int:
    """The finest pyramid level whose grid fits a ``max_size`` texture."""
    g = terrain.grid
    for L in g.levels:
        if g.level_size(L) <= max_size:
            return L
    return g.top_level


def height_tolerance(terrain) -> float:
    """The codec's bound ε on the terrain's heights, in metres (0 when lossless): the
    colours' ``tolerance`` around the water level
    (:func:`geoterrain.rendering.colours.colorize`)."""
    q = getattr(terrain, "quantizer", None)
    return float(q.codec_error) * terrain.frame.z_to_m if q is not None else 0.0


def elevation_range(terrain) -> tuple[float, float]:
    """(min, max) elevation in metres (no vertical exaggeration) of the valid data."""
    lo, hi = terrain.scene_box()
    zs = terrain.frame.z_scale or 1.0
    a, b = float(lo[2] / zs), float(hi[2] / zs)
    return (a, b) if b > a else (a - 0.5, a + 0.5)


def build_texture_image(terrain, shading: str, cmap: str | Palette = "auto",
                        level: int | None = None) -> np.ndarray:
    """RGB uint8 image (S, S, 3) of the level-L grid: elevation colour × hillshade.

    Hillshade from the stored normal maps of level L (computed from the
    full-resolution geometry), colours from the level's heights. Row 0 is grid row 0.

    Examples
    --------
    >>> img = build_texture_image(t, "normals")  # doctest: +SKIP
    """
    g = terrain.grid
    L = texture_level(terrain) if level is None else level
    S, T, step = g.level_size(L), g.tile_samples, 1 << g.t
    shade = np.ones((S, S), np.float32)
    h = np.zeros((S, S), np.float64)
    for (lv, x, y) in terrain.tile_keys(L):
        sl = (slice(y * step, y * step + T), slice(x * step, x * step + T))
        if shading == "normals":
            shade[sl] = _hillshade(terrain.tile_normals(lv, x, y))
        h[sl] = np.nan_to_num(terrain.tile(lv, x, y).heights, nan=0.0)
    z0, z1 = elevation_range(terrain)
    zm = terrain.frame.z_to_m
    rgb = colorize(h * zm, as_palette(cmap), (z0, z1), height_tolerance(terrain))
    rgb *= shade[..., None]
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


def texture_image(terrain, shading: str, cmap: str | Palette = "auto",
                  level: int | None = None) -> np.ndarray:
    """:func:`build_texture_image`, cached per terrain, shading, colour map and level."""
    L = texture_level(terrain) if level is None else level
    cache = _CACHE.setdefault(terrain, {})
    key = (shading, as_palette(cmap), L)
    if key not in cache:
        cache[key] = build_texture_image(terrain, shading, cmap, L)
    return cache[key]

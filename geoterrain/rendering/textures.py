"""Terrain textures: elevation colours × a hillshade from the stored normal maps.

The hillshade (:func:`geoterrain.rendering.shading.hillshade`) comes from the stored
*full-resolution* normal maps (``Terrain.tile_normals``, seed 000 normal-map lighting),
so a coarse LOD mesh textured with it shows the relief of the full DEM.

Examples
--------
>>> img = texture_image(t, "normals")
>>> img.dtype.name, img.shape[2]
('uint8', 3)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.colours import Palette, as_palette, colorize
from geoterrain.rendering.shading import hillshade

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

SHADINGS = ("normals", "elevation", "plain")
MAX_TEXTURE = 8193  # samples per side; a larger DEM's texture comes from a coarser level


def texture_level(terrain: TerrainLike, max_size: int = MAX_TEXTURE) -> int:
    """The finest pyramid level whose grid fits a ``max_size`` texture."""
    g = terrain.grid
    for L in g.levels:
        if max(g.level_shape(L)) <= max_size:
            return L
    return g.top_level


def height_tolerance(terrain: TerrainLike) -> float:
    """The codec's bound ε on the terrain's heights, in metres (0 when lossless): the
    colours' ``tolerance`` around the water level
    (:func:`geoterrain.rendering.colours.colorize`)."""
    q = getattr(terrain, "quantizer", None)
    return float(q.codec_error) * terrain.frame.z_to_m if q is not None else 0.0


SEA_SHARE = 0.002  # the auto palette's sea: at least this share of the data at 0 m


def terrain_palette(terrain: TerrainLike, cmap: str | Palette | None) -> Palette:
    """The palette ``cmap`` for ``terrain``: the ``auto`` palette draws a sea at 0 m where
    the data goes below 0 m (bathymetry), or where whole stored tiles of at least
    ``SEA_SHARE`` of the data lie at 0 m (a sea of zeros, as SRTM's), from the tile table
    alone (nothing is decoded); a DEM that merely touches 0 m at a sample or two (a
    synthetic one scaled to start at 0) gets no water. An explicit ``water_level`` is kept
    as given.

    Examples
    --------
    >>> terrain_palette(t, "auto").cmap
    'auto'
    """
    import dataclasses

    pal = as_palette(cmap)
    if pal.cmap != "auto" or pal.water_level is not None or not pal.sea:
        return pal
    if elevation_range(terrain)[0] > 0.0:
        return pal
    if elevation_range(terrain)[0] < -coast_tolerance(terrain):
        return pal  # bathymetry
    share = terrain.derived(__name__ + ".sea", lambda: _sea_share(terrain))
    return pal if share >= SEA_SHARE else dataclasses.replace(pal, sea=False)


def _sea_share(terrain: TerrainLike) -> float:
    """The share of the valid samples in level-0 tiles that lie wholly at or below 0 m
    (within the coast tolerance), from the tile table's boxes and counts."""
    top = coast_tolerance(terrain) * terrain.frame.z_scale  # scene units
    wet = total = 0
    for (L, _, _), info in terrain.tile_info.items():
        if L == 0:
            n = int(info.get("nvalid", 0))
            total += n
            wet += n if info["zmax"] <= top else 0
    return wet / total if total else 0.0


def coast_tolerance(terrain: TerrainLike) -> float:
    """How far above the water level an *interpolated* height still counts as water, in
    metres: half the heights' step where they are integers of a step (lossless integer or
    decimal DEMs: an SRTM sea of zeros meets 1 m land midway, where its nearest samples
    would draw it), else the codec's bound ε (:func:`height_tolerance`).

    Examples
    --------
    >>> coast_tolerance(t) >= height_tolerance(t)
    True
    """
    q = getattr(terrain, "quantizer", None)
    eps = height_tolerance(terrain)
    if q is not None and q.mode in ("int", "decimal"):
        return max(eps, 0.5 * float(q.step) * terrain.frame.z_to_m)
    return eps


def elevation_range(terrain: TerrainLike) -> tuple[float, float]:
    """(min, max) elevation in metres (no vertical exaggeration) of the valid data."""
    lo, hi = terrain.scene_box()
    zs = terrain.frame.z_scale or 1.0
    a, b = float(lo[2] / zs), float(hi[2] / zs)
    return (a, b) if b > a else (a - 0.5, a + 0.5)


def build_texture_image(terrain: TerrainLike, shading: str, cmap: str | Palette = "auto",
                        level: int | None = None) -> np.ndarray:
    """RGB uint8 image (rows, cols, 3) of the level-L grid (``grid.level_shape(L)``: the
    S × S square, or a root grid's rectangle): elevation colour × hillshade.

    Hillshade from the stored normal maps of level L (computed from the
    full-resolution geometry), colours from the level's heights. Row 0 is grid row 0.

    Examples
    --------
    >>> img = build_texture_image(t, "normals")  # doctest: +SKIP
    """
    g = terrain.grid
    L = texture_level(terrain) if level is None else level
    shape, T, step = g.level_shape(L), g.tile_samples, 1 << g.t
    shade = np.ones(shape, np.float32)
    h = np.zeros(shape, np.float64)
    for (lv, x, y) in terrain.tile_keys(L):
        sl = (slice(y * step, y * step + T), slice(x * step, x * step + T))
        if shading == "normals":
            shade[sl] = hillshade(terrain.tile_normals(lv, x, y))
        h[sl] = np.nan_to_num(terrain.tile(lv, x, y).heights, nan=0.0)
    z0, z1 = elevation_range(terrain)
    zm = terrain.frame.z_to_m
    rgb = colorize(h * zm, terrain_palette(terrain, cmap), (z0, z1), height_tolerance(terrain))
    rgb *= shade[..., None]
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


def texture_image(terrain: TerrainLike, shading: str, cmap: str | Palette = "auto",
                  level: int | None = None) -> np.ndarray:
    """:func:`build_texture_image`, cached per terrain, shading, colour map and level."""
    L = texture_level(terrain) if level is None else level
    cache = terrain.derived(__name__, dict)
    key = (shading, terrain_palette(terrain, cmap), L)
    if key not in cache:
        cache[key] = build_texture_image(terrain, shading, cmap, L)
    return cache[key]


def sample_spacing(terrain: TerrainLike) -> float:
    """The finest sample spacing (scene units) near the grid centre and corners: a
    level-L texel is 2^L of it.

    Examples
    --------
    >>> sample_spacing(t) > 0
    True
    """
    g = terrain.grid
    pts = []
    for c in ((g.rows // 2, g.cols // 2), (0, 0), (max(g.rows - 2, 0), max(g.cols - 2, 0))):
        ii = np.array([c[0], c[0], c[0] + 1])
        jj = np.array([c[1], c[1] + 1, c[1]])
        X, Y = terrain.frame.xy(ii, jj)
        pts.append(min(math.hypot(X[1] - X[0], Y[1] - Y[0]), math.hypot(X[2] - X[0],
                                                                          Y[2] - Y[0])))
    return max(min(pts), 1e-12)

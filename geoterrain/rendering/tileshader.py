"""How a picture's style shades the stored tiles its texture atlas draws.

A :class:`TileShader` is one style (shading, palette, light, drape) over one terrain. It
hands the atlas (:func:`geoterrain.rendering.tiletextures.build_view_texture`) each tile's
RGB uint8 (T, T, 3), cached in the terrain's byte-bounded tile cache under the style's
number, and shades the tiles not cached yet, up to a frame's budget: in the default style
(the ``auto`` palette's tint × the default sun's hillshade of the stored 8-bit normal
codes) all of them in one compiled call on every core
(:func:`geoterrain.rendering.tileshade.shade_tiles`); otherwise one by one, as
:func:`geoterrain.rendering.colours.colorize` × (the drape) × the hillshade
(:func:`geoterrain.rendering.shading.tile_hillshade`) or the lit shade
(:func:`geoterrain.rendering.shading.tile_shade`).

Examples
--------
>>> shader = TileShader(t)
>>> rgbs = shader([(t.grid.top_level, 0, 0)])
>>> rgbs[0].shape, shader.built
((33, 33, 3), 1)
>>> shader.cached(t.grid.top_level, 0, 0) is rgbs[0]
True
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.colours import LAND, WATER, Palette, as_palette, colorize, water_level
from geoterrain.rendering.drape import Drape, drape_tile
from geoterrain.rendering.shading import (
    AMBIENT,
    DEFAULT_SUN,
    SHADE_CEILING,
    Light,
    tile_hillshade,
    tile_shade,
)
from geoterrain.rendering.textures import elevation_range, height_tolerance, sample_spacing
from geoterrain.rendering.tileshade import shade_tiles

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["TileShader", "tile_rgb"]

# every shading style met so far, numbered: a tile's cache key holds the number, so a
# lookup hashes a few ints, not the palette, light and drape (a handful of styles a
# process; each is a small frozen value). Numbered under a lock: the viewer shades on a
# worker thread, and two new styles must never get one number.
_STYLES: dict[tuple, int] = {}
_STYLES_LOCK = threading.Lock()


class TileShader:
    """One style's shading of ``terrain``'s stored tiles, cached in the terrain.

    Calling it with tile keys returns each tile's RGB uint8 (T, T, 3): the cached ones as
    they are and, up to ``max_builds`` (None: all), the others shaded now; past the
    budget, None. ``built`` counts the tiles it shaded.
    """

    def __init__(self, terrain: TerrainLike, shading: str = "normals",
                 cmap: str | Palette = "auto", light: Light | None = None,
                 drape: Drape | None = None):
        self.terrain, self.shading, self.palette = terrain, shading, as_palette(cmap)
        self.light, self.drape = light, drape
        self.built = 0
        # a vertically exaggerated view shares its base terrain's cache but not its
        # shading (its normals are steeper)
        lk = None if light is None or light.is_default else light
        style = (shading, self.palette, lk, drape, float(terrain.vertical_exaggeration))
        with _STYLES_LOCK:
            self.style = _STYLES.setdefault(style, len(_STYLES))
        # the default style: one compiled pass over many tiles (geoterrain.rendering.tileshade)
        self.compiled = (shading == "normals" and lk is None and drape is None
                         and self.palette.cmap == "auto" and terrain.stored_normals
                         and terrain.meta["normal_bits"] == 8)

    def key(self, level: int, x: int, y: int) -> tuple:
        """The tile's key in the terrain's cache."""
        return ("rgb", self.style, level, x, y)

    def cached(self, level: int, x: int, y: int) -> np.ndarray | None:
        """The tile's cached shading (marked as just used), or None."""
        return self.terrain.lookup(self.key(level, x, y))

    def peek(self, level: int, x: int, y: int) -> np.ndarray | None:
        """The tile's cached shading, or None; the cache's order is left as it is."""
        return self.terrain.peek(self.key(level, x, y))

    def __call__(self, keys: Sequence[TileKey], max_builds: int | None = None
                 ) -> list[np.ndarray | None]:
        if self.compiled:
            # the new tiles in one compiled call, then the cached ones in order
            todo = [k for k in dict.fromkeys(keys) if self.peek(*k) is None][:max_builds]
            ready = {}
            for k, rgb in zip(todo, self._batch(todo), strict=True):
                ready[k] = self.terrain.memo(self.key(*k), lambda rgb=rgb: rgb)
            self.built += len(todo)
            return [ready[k] if k in ready else self.cached(*k) for k in keys]
        out, start = [], self.built
        for k in keys:
            rgb = self.cached(*k)
            if rgb is None and (max_builds is None or self.built - start < max_builds):
                rgb = self.tile(*k)
            out.append(rgb)
        return out

    def tile(self, level: int, x: int, y: int) -> np.ndarray:
        """One tile's shading, cached (shaded now whatever the budget)."""

        def make():
            self.built += 1
            if self.compiled:
                return self._batch([(level, x, y)])[0]
            return self._one(level, x, y)

        return self.terrain.memo(self.key(level, x, y), make)

    def _one(self, level: int, x: int, y: int) -> np.ndarray:
        t, pal, light, drape = self.terrain, self.palette, self.light, self.drape
        z0, z1 = elevation_range(t)
        h = np.nan_to_num(t.tile(level, x, y).heights, nan=0.0)
        rgb = colorize(h * t.frame.z_to_m, pal, (z0, z1), height_tolerance(t))
        if drape is not None:  # the image over the colours; its nodata shows them
            img, on = drape_tile(t, drape, level, x, y)
            a = float(drape.opacity)
            rgb[on] = a * img[on] + (1.0 - a) * rgb[on]
        if self.shading == "normals" and (light is None or light.is_default):
            rgb *= tile_hillshade(t, level, x, y)[..., None]
        elif self.shading == "normals":  # sun, shadows, ambient occlusion
            rgb *= tile_shade(t, level, x, y, light, sample_spacing(t))[..., None]
        return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)

    def _batch(self, keys: list) -> list[np.ndarray]:
        """The default style's shading of each tile of ``keys`` in one compiled call over
        all of them on every core (:func:`geoterrain.rendering.tileshade.shade_tiles`; a
        single tile's on this thread), from their heights and the normal codes the
        terrain hands over."""
        t, pal = self.terrain, self.palette
        T, n = t.grid.tile_samples, len(keys)
        h = np.empty((n, T, T))
        for k, key in enumerate(keys):
            h[k] = t.tile(*key).heights
        codes = t.normal_codes(keys)
        z0, z1 = elevation_range(t)
        rgb = shade_tiles(h, t.frame.z_to_m, codes, DEFAULT_SUN, AMBIENT, SHADE_CEILING,
                          pal.clim if pal.clim is not None else (z0, z1),
                          water_level(pal, (z0, z1)), LAND, WATER, height_tolerance(t))
        return [a.copy() for a in rgb]  # each cached on its own (not views of one array)


def tile_rgb(terrain: TerrainLike, level: int, x: int, y: int, shading: str,
             cmap: str | Palette = "auto", light: Light | None = None,
             drape: Drape | None = None) -> np.ndarray:
    """RGB uint8 (T, T, 3) shading of stored tile (level, x, y) in a style, cached in the
    terrain (:class:`TileShader`).

    Examples
    --------
    >>> tile_rgb(t, t.grid.top_level, 0, 0, "normals").shape
    (33, 33, 3)
    """
    return TileShader(terrain, shading, cmap, light, drape).tile(level, x, y)

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

A magnified tile (level < 0, :mod:`geoterrain.rendering.tiletextures`) is shaded by the
same rule from its level-0 tile's heights, shade (and drape) interpolated bilinearly at
its texels (:func:`magnified`, one tile's channels; in the default style a frame's
magnified tiles in one call; both the compiled pass
:func:`geoterrain.rendering.tileshade.magnify_tiles`): the height is
interpolated first and classified after, so a coast or a colour step follows the
interpolated surface, not the nearest sample.

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

from geoterrain.rendering.colours import LAND, WATER, Palette, colorize, water_level
from geoterrain.rendering.drape import Drape, drape_tile
from geoterrain.rendering.shading import (
    AMBIENT,
    DEFAULT_SUN,
    SHADE_CEILING,
    Light,
    tile_hillshade,
    tile_shade,
)
from geoterrain.rendering.textures import (
    coast_tolerance,
    elevation_range,
    height_tolerance,
    sample_spacing,
    terrain_palette,
)
from geoterrain.rendering.tileshade import (
    magnify_tiles,
    magnify_tint_tiles,
    shade_lut,
    shade_tiles,
)

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["TileShader", "magnified", "tile_rgb"]


def magnified(a: np.ndarray, level: int, x: int, y: int, step: int) -> np.ndarray:
    """Magnified tile (``level`` < 0, x, y)'s texels (step + 1)² interpolated bilinearly in
    ``a``, its level-0 tile's array (T, T, ...) (NaN-aware: a texel takes the weighted mean
    of its finite corners; NaN where none is).

    The tile covers 1/2^-level of its level-0 tile's side, from sample (y mod 2^-level,
    x mod 2^-level) × its width, with 2^-level texels per sample. Each channel of ``a`` is
    one tile of :func:`geoterrain.rendering.tileshade.magnify_tiles`, the compiled pass the
    default style magnifies a frame's tiles with: one interpolation for every style. (An
    earlier numpy one, separable weights through ``einsum``, rounded its sums in another
    order, up to 5e-13 apart; the shaded tiles were the same bytes in every style tried:
    ``tests/rendering/test_tileshade.py``.)

    Examples
    --------
    >>> a = np.array([[0.0, 4.0], [8.0, 12.0]])  # a 2 × 2 level-0 tile (step 1)
    >>> magnified(np.kron(a, np.ones((1, 1))), -1, 0, 0, 2).tolist()[1]
    [4.0, 6.0, 8.0]
    >>> magnified(np.stack([a, -a], -1), -1, 0, 0, 2)[1, 1].tolist()  # channels
    [6.0, -6.0]
    """
    k = -int(level)
    if k <= 0:
        raise ValueError("a magnified tile's level is below 0")
    v = np.asarray(a, np.float64)
    src = np.moveaxis(v.reshape(v.shape[0], v.shape[1], -1), -1, 0)  # a tile per channel
    n = src.shape[0]
    out = magnify_tiles(src, np.arange(n), np.full(n, -k), np.full(n, int(x)),
                        np.full(n, int(y)), step)
    return np.moveaxis(out, 0, -1).reshape((step + 1, step + 1) + v.shape[2:])


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
        self.terrain, self.shading = terrain, shading
        self.palette = terrain_palette(terrain, cmap)
        self.light, self.drape = light, drape
        self.built = 0
        # a vertically exaggerated view shares its base terrain's cache but not its
        # shading (its normals are steeper)
        lk = None if light is None or light.is_default else light
        style = (shading, self.palette, lk, drape, float(terrain.vertical_exaggeration))
        with _STYLES_LOCK:
            self.style = _STYLES.setdefault(style, len(_STYLES))
        # the default style: one compiled pass over many tiles (geoterrain.rendering.tileshade)
        self.tinted = (shading == "normals" and lk is None and drape is None
                       and self.palette.cmap == "auto")
        self.compiled = (self.tinted and terrain.stored_normals
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
        if self.compiled or (self.tinted and all(k[0] < 0 for k in keys)):
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
            if self.compiled or (self.tinted and level < 0):
                return self._batch([(level, x, y)])[0]
            return self._one(level, x, y)

        return self.terrain.memo(self.key(level, x, y), make)

    def _one(self, level: int, x: int, y: int) -> np.ndarray:
        if level < 0:  # magnified: the level-0 tile's fields at the texels
            k = -level
            p = (0, x >> k, y >> k)
            fields = self.terrain.memo(("fields", self.style, *p), lambda: self._fields(*p))
            step = 1 << self.terrain.grid.t
            fields = tuple(None if f is None else magnified(f, level, x, y, step)
                           for f in fields)
            return self._colour(*fields)
        return self._colour(*self._fields(level, x, y))

    def _fields(self, level: int, x: int, y: int) -> tuple:
        """A stored tile's heights (metres, NaN at nodata), drape colours and coverage (or
        None) and shade (or None): what :meth:`_colour` colours."""
        t, light, drape = self.terrain, self.light, self.drape
        h = t.tile(level, x, y).heights * t.frame.z_to_m
        img = on = shade = None
        if drape is not None:
            img, on = drape_tile(t, drape, level, x, y)
            on = on.astype(np.float32)
        if self.shading == "normals" and (light is None or light.is_default):
            shade = tile_hillshade(t, level, x, y)
        elif self.shading == "normals":  # sun, shadows, ambient occlusion
            shade = tile_shade(t, level, x, y, light, sample_spacing(t))
        return h, img, on, shade

    def _colour(self, h, img, on, shade) -> np.ndarray:
        """RGB uint8 of a tile's (or its texels') fields: the palette's colours of the
        heights, the drape over them, × the shade."""
        t, pal, drape = self.terrain, self.palette, self.drape
        z0, z1 = elevation_range(t)
        rgb = colorize(np.nan_to_num(h, nan=0.0), pal, (z0, z1), height_tolerance(t),
                       coast_tolerance(t))
        if drape is not None:  # the image over the colours; its nodata shows them
            cover = np.nan_to_num(on, nan=0.0) > 0.5
            a = float(drape.opacity)
            rgb[cover] = a * np.nan_to_num(img[cover]) + (1.0 - a) * rgb[cover]
        if shade is not None:
            rgb *= np.nan_to_num(shade, nan=1.0)[..., None]
        return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)

    def _batch(self, keys: list) -> list[np.ndarray]:
        """The default style's shading of each tile of ``keys`` in one compiled call over
        all of them on every core (:func:`geoterrain.rendering.tileshade.shade_tiles`; a
        single tile's on this thread), from their heights and the normal codes the
        terrain hands over; magnified tiles (level < 0) from their level-0 tile's heights
        and hillshade interpolated at their texels, coloured by the same rule
        (:func:`geoterrain.rendering.tileshade.tint_tiles`)."""
        t, pal = self.terrain, self.palette
        T = t.grid.tile_samples
        z0, z1 = elevation_range(t)
        clim = pal.clim if pal.clim is not None else (z0, z1)
        args = (clim, water_level(pal, (z0, z1)), LAND, WATER, height_tolerance(t),
                coast_tolerance(t))
        real = [k for k in keys if k[0] >= 0]
        out = {}
        if real and not self.compiled:  # the tinted style over normals not stored
            out.update({key: self._one(*key) for key in real})
        elif real:
            h = np.empty((len(real), T, T))
            for k, key in enumerate(real):
                h[k] = t.tile(*key).heights
            codes = t.normal_codes(real)
            rgb = shade_tiles(h, t.frame.z_to_m, codes, DEFAULT_SUN, AMBIENT, SHADE_CEILING,
                              *args)
            out.update({key: rgb[k].copy() for k, key in enumerate(real)})
            for k, key in enumerate(real):
                if key[0] == 0:  # kept for its magnified tiles (_default_fields): a nearer
                    # view magnifies the level-0 tiles a farther one shaded (the low flight
                    # of benchmarks/bench_render.py: 400 of its 442 magnified tiles' parents)
                    t.memo(self._codes_key(key), lambda c=codes[k].copy(): c)
        virtual = [k for k in keys if k[0] < 0]
        if virtual:
            # each level-0 tile's heights and shade once, then every magnified tile's
            # texels in one compiled pass (magnify_tiles: magnified's interpolation)
            parents = {}
            for L, x, y in virtual:
                parents.setdefault((0, x >> -L, y >> -L), len(parents))
            ph = np.empty((len(parents), T, T))
            ps = np.empty((len(parents), T, T))
            for p, m in parents.items():
                ph[m], ps[m] = t.memo(("fields", self.style, *p),
                                      lambda p=p: self._default_fields(p))
            which = np.array([parents[(0, x >> -L, y >> -L)] for L, x, y in virtual])
            L, x, y = (np.array(a, np.int64) for a in zip(*virtual, strict=True))
            # magnify_tiles of the heights and the shade, then tint_tiles: one pass
            rgb = magnify_tint_tiles(ph, ps, which, L, x, y, 1 << t.grid.t, 1.0, *args)
            out.update({key: rgb[k].copy() for k, key in enumerate(virtual)})
        return [out[k] for k in keys]  # each cached on its own (not views of one array)

    def _codes_key(self, key) -> tuple:
        """The cache key of a level-0 tile's normal codes, kept from its shading."""
        return ("codes", self.style, *key)

    def _default_fields(self, key) -> tuple[np.ndarray, np.ndarray]:
        """A stored tile's heights (metres) and default hillshade for its magnified tiles:
        from its normal codes, the values the compiled shading looks up (or the hillshade
        of its normals where they are not the stored ones, as under exaggeration)."""
        t = self.terrain
        h = t.tile(*key).heights * t.frame.z_to_m
        if not self.compiled:
            return h, tile_hillshade(t, *key)
        codes = t.peek(self._codes_key(key))  # as shaded at level 0 (_batch), if kept
        if codes is None:
            codes = t.normal_codes([key])[0]
        lut = shade_lut(DEFAULT_SUN, AMBIENT, SHADE_CEILING)
        return h, lut[codes[..., 0], codes[..., 1]]


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

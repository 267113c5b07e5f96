"""Elevation colours: a hypsometric land map, water below a level, any matplotlib map.

A :class:`Palette` says how heights (metres, no exaggeration) become colours:

- ``cmap="auto"`` (default): hypsometric land tints (green → tan → brown → white,
  no black anywhere); where the data reaches 0 m or below, everything at or
  below sea level is water in blues (a topo-bathymetric map split at sea level).
- any matplotlib colormap name: that map over ``clim``; with ``water_level``
  the heights at or below it are still water.
- ``water_level=H``: heights at or below H are water.
- ``clim=(lo, hi)``: the heights the map spans (default: the data's range).

A store coded within ε (``--codec-error``) cannot tell heights within ε of the water
level apart, so its ``tolerance`` ε paints them all as the water's surface: a flat sea
whose decoded heights wander within ±ε stays one colour, and the depth ramp starts ε
below the level.

Examples
--------
>>> p = Palette("auto", water_level=0.0)
>>> rgb = colorize(np.array([-50.0, 0.0, 10.0, 3000.0]), p, (-100.0, 3000.0))
>>> bool(rgb[1, 2] > rgb[1, 0]), bool(rgb[2, 1] > rgb[2, 2])  # sea blue, lowland green
(True, True)
>>> bool(rgb.sum(-1).min() > 0.5)  # no black
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoterrain.exceptions import UsageError

# hypsometric tints (heights as a fraction of the land range): lowland green to snow
LAND = [(0.00, (0.34, 0.58, 0.36)), (0.15, (0.55, 0.70, 0.42)), (0.35, (0.83, 0.80, 0.55)),
        (0.60, (0.72, 0.56, 0.38)), (0.82, (0.60, 0.50, 0.44)), (1.00, (0.96, 0.96, 0.96))]
# water from the deepest (0) to the surface (1)
WATER = [(0.00, (0.08, 0.22, 0.48)), (0.70, (0.25, 0.50, 0.78)), (1.00, (0.50, 0.72, 0.90))]


@dataclass(frozen=True)
class Palette:
    """How heights become colours (see the module docs)."""

    cmap: str = "auto"
    clim: tuple[float, float] | None = None
    water_level: float | None = None
    sea: bool = True  # the auto palette's sea at 0 m where the data reaches it

    def __post_init__(self) -> None:
        check_cmap(self.cmap)
        if self.clim is not None:
            lo, hi = (float(v) for v in self.clim)
            if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
                raise UsageError(f"clim must be two finite numbers MIN < MAX, got {self.clim}")
            object.__setattr__(self, "clim", (lo, hi))
        if self.water_level is not None and not np.isfinite(self.water_level):
            raise UsageError(f"water_level must be finite, got {self.water_level}")


def as_palette(cmap: str | Palette | None) -> Palette:
    """A :class:`Palette` from a colormap name (or the palette itself)."""
    if isinstance(cmap, Palette):
        return cmap
    return Palette("auto" if cmap is None else cmap)


def check_cmap(name: str) -> None:
    """Raise UsageError (listing a few names) unless ``name`` is "auto" or a matplotlib map
    (the maps of :mod:`geoterrain.rendering.cmaptable` without importing matplotlib)."""
    from geoterrain.rendering.cmaptable import TABLE

    if name == "auto" or name in TABLE:
        return
    import matplotlib

    if name not in matplotlib.colormaps:
        raise UsageError(f"unknown colormap {name!r}; use auto or a matplotlib name such as "
                         "terrain, viridis, cividis, gist_earth, Greys_r")


def _ramp(stops, x: np.ndarray) -> np.ndarray:
    xs = np.array([s for s, _ in stops])
    cs = np.array([c for _, c in stops])
    return np.stack([np.interp(x, xs, cs[:, k]) for k in range(3)], -1)


def water_level(palette: Palette, data_range: tuple[float, float]) -> float | None:
    """The level at or below which heights are water (None: no water): the palette's
    ``water_level``, else the ``auto`` palette's sea at 0 m where the data reaches it (and
    the palette's ``sea`` is on: :func:`geoterrain.rendering.textures.terrain_palette`
    turns it off for data that only touches 0 m at a few samples).

    Examples
    --------
    >>> water_level(Palette("auto"), (0.0, 900.0)), water_level(Palette("auto", sea=False),
    ...                                                         (0.0, 900.0))
    (0.0, None)
    """
    if palette.water_level is not None:
        return float(palette.water_level)
    if palette.cmap == "auto" and palette.sea and data_range[0] <= 0.0:
        return 0.0
    return None


def colorize(h: np.ndarray, palette: Palette, data_range: tuple[float, float],
             tolerance: float = 0.0, coast: float | None = None) -> np.ndarray:
    """RGB float32 in [0, 1] (shape h.shape + (3,)) for heights ``h`` in metres.

    ``data_range`` is the data's (min, max); ``palette.clim`` overrides it for the map;
    ``tolerance``: the heights' codec bound ε in metres (the module's last paragraph);
    ``coast``: heights up to this far above the water level are water too (heights
    interpolated between integer samples: half the heights' step, so the coast runs
    midway between a sample at the level and one a step above; at least ``tolerance``).

    Examples
    --------
    >>> p = Palette("auto")
    >>> rgb = colorize(np.array([-1.5, 0.0, 1.5]), p, (-1.5, 900.0), tolerance=2.0)
    >>> bool((rgb == rgb[1]).all())  # all within ε of the sea level: its surface
    True
    """
    h = np.asarray(h, np.float64)
    lo, hi = palette.clim if palette.clim is not None else data_range
    if hi <= lo:
        lo, hi = lo - 0.5, lo + 0.5
    wl = water_level(palette, data_range)
    if palette.cmap == "auto":
        base = max(lo, wl) if wl is not None else lo
        rgb = _ramp(LAND, np.clip((h - base) / max(hi - base, 1e-9), 0, 1))
    else:
        from geoterrain.rendering.cmaptable import colours

        x = np.clip((h - lo) / (hi - lo), 0, 1)
        rgb = colours(palette.cmap, x)  # the maps held as tables: no matplotlib
        if rgb is None:
            import matplotlib

            rgb = matplotlib.colormaps[palette.cmap](x)[..., :3]
    if wl is not None:
        wet = h <= wl + (tolerance if coast is None else max(tolerance, coast))
        if wet.any():
            top = wl - tolerance  # the depth ramp's surface
            depth_lo = min(lo, top)
            span = max(top - depth_lo, 1e-9)
            frac = np.clip((h[wet] - depth_lo) / span, 0, 1) if top > depth_lo else 1.0
            rgb[wet] = _ramp(WATER, np.broadcast_to(frac, h[wet].shape))
    return rgb.astype(np.float32)


def colorbar_colours(palette: Palette, data_range: tuple[float, float], n: int = 256,
                     tolerance: float = 0.0) -> tuple[np.ndarray, tuple[float, float]]:
    """((n, 3) float32 RGB, (lo, hi)): the colours of :func:`colorize` (with the same
    ``tolerance``) at ``n`` heights evenly spaced over the range the colour bar spans.

    The range is never wider than the data's (or ``clim``): where water has no depth in
    the data (its lowest heights are the water level, as a sea of SRTM zeros), the bar is
    the land's and the water is a swatch beside it (:func:`water_swatch`).

    Examples
    --------
    >>> rgb, (lo, hi) = colorbar_colours(Palette("auto"), (0.0, 1500.0))
    >>> rgb.shape, (lo, hi)  # no sea range below 0 m that the data does not have
    ((256, 3), (0.0, 1500.0))
    """
    lo, hi = palette.clim if palette.clim is not None else data_range
    if hi <= lo:
        lo, hi = lo - 0.5, lo + 0.5
    wl = water_level(palette, data_range)
    z = np.linspace(lo, hi, n)
    if water_swatch(palette, data_range, tolerance) is not None:
        # the bar's lowest colour is the land's just above the water, not the water's
        z[0] = np.nextafter(max(lo, wl + tolerance), np.inf)
    return colorize(z, palette, data_range, tolerance), (lo, hi)


def colorbar_map(palette: Palette, data_range: tuple[float, float], n: int = 256,
                 tolerance: float = 0.0):
    """(matplotlib ListedColormap, (lo, hi)) of :func:`colorbar_colours` (imports
    matplotlib: the viewer's and the globe's colour bars).

    Examples
    --------
    >>> cm, (lo, hi) = colorbar_map(Palette("auto"), (0.0, 1500.0))
    >>> cm.N, (lo, hi)
    (256, (0.0, 1500.0))
    """
    import matplotlib.colors

    rgb, lim = colorbar_colours(palette, data_range, n, tolerance)
    return matplotlib.colors.ListedColormap(rgb), lim


def water_swatch(palette: Palette, data_range: tuple[float, float],
                 tolerance: float = 0.0) -> tuple[float, float, float] | None:
    """The water's colour, for a swatch beside the colour bar, where the data has water
    but no depth below it (its lowest heights are the water level); None otherwise (no
    water, or water with a depth range, which the bar itself shows).

    Examples
    --------
    >>> water_swatch(Palette("auto"), (0.0, 900.0)) is not None  # a sea of zeros
    True
    >>> water_swatch(Palette("auto"), (-50.0, 900.0)) is None  # depths: on the bar
    True
    """
    lo = palette.clim[0] if palette.clim is not None else data_range[0]
    wl = water_level(palette, data_range)
    if wl is None or wl - tolerance > lo:
        return None
    rgb = colorize(np.array([wl]), palette, data_range, tolerance)[0]
    return tuple(float(c) for c in rgb)

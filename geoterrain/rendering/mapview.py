"""A map view: orthographic, north up, framed, with a graticule or the CRS's grid.

:func:`map_view` frames the whole terrain straight from above in a parallel projection
(:attr:`geoterrain.core.view.View.parallel`): one scale at every point of the picture, so
the scale bar holds everywhere and says so (no "at view centre"). Around the data's
rectangle :func:`geoterrain.rendering.mapgrid.draw_map_grid` draws a neat line and its
ticks, labelled in the DEM's own coordinates:

- a projected DEM (UTM, a state plane): grid lines of its eastings and northings (nice
  round values in its unit, e.g. every 5 000 m), straight in the picture, the scene frame
  being the CRS's own axes;
- a geographic DEM: a graticule of meridians and parallels (every 1′, 2′, 5′, … 30′, 1°,
  … as fits), labelled in degrees and minutes, drawn through pyproj from the local
  azimuthal equidistant frame the scene uses, so they bend as they should.

The colour bar, scale bar and north arrow keep their column at the right.

Examples
--------
>>> v = map_view(t, (480, 270))
>>> v.parallel, [round(c, 6) + 0.0 for c in v.up]  # north up
(True, [0.0, 1.0, 0.0])
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from geoterrain.core.view import View
from geoterrain.rendering.cameras import terrain_bounds
from geoterrain.rendering.overlays import Layout, layout_for, text_size

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

MAP_FOV = 0.5  # degrees: the narrow perspective the LOD selection sees the map through


def map_layout(terrain: TerrainLike, size: tuple[int, int], **kw) -> tuple[Layout, tuple]:
    """The overlay column of a map picture (its scale bar exact everywhere) and the
    rectangle (x0, y0, x1, y1) left for the map inside the tick labels' margins."""
    lay = layout_for(terrain, size, exact_scale=True, **kw)
    fs = lay.fs
    label_w = text_size("139°59′E", 0.85 * fs)[0]
    x0, y0, x1, y1 = lay.free
    return lay, (x0 + label_w + 0.8 * fs, y0 + 0.3 * fs, x1 - 0.3 * fs, y1 - 1.6 * fs)


def map_view(terrain: TerrainLike, size: tuple[int, int] = (1280, 720), **kw) -> View:
    """The orthographic, north-up view of the whole terrain fitted into the map rectangle of
    :func:`map_layout` (``kw``: its overlays: title, colorbar, scale_bar, north_arrow,
    shading, cmap).

    Examples
    --------
    >>> v = map_view(t, (640, 360), title="Map")
    >>> v.parallel and v.fov_y_deg == MAP_FOV
    True
    """
    _, (x0, y0, x1, y1) = map_layout(terrain, size, **kw)
    lo, hi = terrain_bounds(terrain)
    W, H = size
    span_x, span_y = max(hi[0] - lo[0], 1e-9), max(hi[1] - lo[1], 1e-9)
    scale = min((x1 - x0) / span_x, (y1 - y0) / span_y)  # pixels per metre
    cx, cy = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
    # the data's centre goes to the map rectangle's centre: the target is the scene point
    # under the picture's centre
    tx = cx + (W / 2 - 0.5 * (x0 + x1)) / scale
    ty = cy - (H / 2 - 0.5 * (y0 + y1)) / scale
    half = (H / 2) / scale  # metres from the centre to the top edge
    d = half / math.tan(math.radians(MAP_FOV) / 2)
    tz = 0.5 * (lo[2] + hi[2])
    return View((tx, ty, tz + d), (tx, ty, tz), (0.0, 1.0, 0.0), MAP_FOV, tuple(size),
                parallel=True)

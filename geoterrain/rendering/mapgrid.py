"""A map's grid: the neat line around the data's rectangle, and its eastings and northings
(a projected DEM) or meridians and parallels (a geographic one, through pyproj, in degrees
and minutes), drawn over a map picture (:mod:`geoterrain.rendering.mapview`) by the
overlays (:func:`geoterrain.rendering.overlays.compose`).

Examples
--------
>>> from geoterrain.rendering.mapview import map_view
>>> lines = grid_lines(t, map_view(t, (480, 270)))
>>> len(lines) >= 4 and {ln.side for ln in lines} == {"bottom", "left"}
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.rendering.cameras import project, terrain_bounds
from geoterrain.rendering.canvas2d import Layer, Text, grey

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

MINUTES = (1, 2, 5, 10, 15, 20, 30, 60, 120, 300, 600, 900, 1800)  # graticule steps (′)


@dataclass
class GridLine:
    """One grid line of a map: its picture polyline ``px`` (N, 2) (x right, y down), its
    ``label``, the frame ``side`` it is labelled on ("bottom" or "left") and where it
    meets that side (``at``: x for the bottom, y for the left)."""

    px: np.ndarray
    label: str
    side: str
    at: float


def map_rect(terrain: TerrainLike, view: View) -> tuple[float, float, float, float]:
    """The data's rectangle (its scene box) in the picture: (x0, y0, x1, y1)."""
    lo, hi = terrain_bounds(terrain)
    z = float(view.look_at[2])
    px, _ = project(view, np.array([[lo[0], lo[1], z], [hi[0], hi[1], z]]))
    return (float(min(px[:, 0])), float(min(px[:, 1])), float(max(px[:, 0])),
            float(max(px[:, 1])))


def _nice_step(span: float, lines: int = 5) -> float:
    """A 1-2-2.5-5 × 10^k step giving about ``lines`` lines over ``span``."""
    raw = span / lines
    e = 10.0 ** math.floor(math.log10(raw))
    return min((m * e for m in (1, 2, 2.5, 5, 10)), key=lambda s: abs(span / s - lines))


def _dms(v: float, pos: str, neg: str, minutes: bool) -> str:
    h = pos if v >= 0 else neg
    a = abs(v)
    deg = int(math.floor(a + 1e-9))
    mins = int(round((a - deg) * 60))
    if mins == 60:
        deg, mins = deg + 1, 0
    return f"{deg}°{mins:02d}′{h}" if minutes else f"{deg}°{h}"


def grid_lines(terrain: TerrainLike, view: View) -> list[GridLine]:
    """The map's grid: eastings and northings of a projected DEM, or meridians and parallels
    of a geographic one, as picture polylines with their labels (see the module docs)."""
    f = terrain.frame
    lo, hi = terrain_bounds(terrain)
    z = float(view.look_at[2])
    x0, y0, x1, y1 = map_rect(terrain, view)
    # the data's extent in CRS coordinates
    n = 41
    ex = np.concatenate([np.linspace(lo[0], hi[0], n), np.full(n, hi[0]),
                         np.linspace(hi[0], lo[0], n), np.full(n, lo[0])])
    ey = np.concatenate([np.full(n, lo[1]), np.linspace(lo[1], hi[1], n), np.full(n, hi[1]),
                         np.linspace(hi[1], lo[1], n)])
    cx, cy = f.scene_to_crs(ex, ey)
    out: list[GridLine] = []
    geographic = f.kind == "geographic"
    for axis in (0, 1):
        a_lo, a_hi = (float(np.min(cx)), float(np.max(cx))) if axis == 0 else \
            (float(np.min(cy)), float(np.max(cy)))
        b_lo, b_hi = (float(np.min(cy)), float(np.max(cy))) if axis == 0 else \
            (float(np.min(cx)), float(np.max(cx)))
        if geographic:
            step_min = min(MINUTES, key=lambda m: abs((a_hi - a_lo) * 60 / m - 4))
            step = step_min / 60.0
        else:
            step = _nice_step(a_hi - a_lo, 4)
        first = math.ceil(a_lo / step - 1e-9)
        for k in range(first, int(math.floor(a_hi / step + 1e-9)) + 1):
            v = k * step
            b = np.linspace(b_lo, b_hi, 33)
            xs, ys = (np.full_like(b, v), b) if axis == 0 else (b, np.full_like(b, v))
            sx, sy = f.crs_to_scene(xs, ys)
            px, _ = project(view, np.column_stack([sx, sy, np.full(len(b), z)]))
            if geographic:
                label = _dms(v, "E", "W", step_min < 60) if axis == 0 else \
                    _dms(v, "N", "S", step_min < 60)
            else:
                label = f"{v:,.0f}" if step >= 1 else f"{v:,.{-math.floor(math.log10(step))}f}"
            if axis == 0:  # meets the bottom edge at y1
                at = float(np.interp(y1, px[::-1, 1], px[::-1, 0])) \
                    if px[0, 1] > px[-1, 1] else float(np.interp(y1, px[:, 1], px[:, 0]))
                if x0 - 0.5 <= at <= x1 + 0.5:
                    out.append(GridLine(px, label, "bottom", at))
            else:  # meets the left edge at x0
                order = np.argsort(px[:, 0])
                at = float(np.interp(x0, px[order, 0], px[order, 1]))
                if y0 - 0.5 <= at <= y1 + 0.5:
                    out.append(GridLine(px, label, "left", at))
    return out


def draw_map_grid(text: Text, terrain: TerrainLike, view: View, fs: float) -> list[Layer]:
    """The map's neat line, grid lines (clipped to it, translucent), ticks and labels:
    the layers to composite over the picture, in order, and the labels put on ``text``
    under the name "grid"."""
    pt = 100.0 / 72.0  # pixels per point, as the overlays' strokes
    rect = map_rect(terrain, view)
    x0, y0, x1, y1 = rect
    lines = Layer(rect, alpha=0.35, clip=True)
    marks = Layer((x0 - fs, y0, x1, y1 + fs))
    marks.frame(rect, grey(0.15), 0.9 * pt)
    tick = 0.45 * fs
    for ln in grid_lines(terrain, view):
        lines.polyline(ln.px, grey(0.1), 0.6 * pt)
        if ln.side == "bottom":
            marks.segment((ln.at, y1), (ln.at, y1 + tick), grey(0.15), 0.8 * pt, True)
            text.put("grid", ln.at, y1 + tick + 0.1 * fs, ln.label, 0.8 * fs, va="top")
        else:
            marks.segment((x0 - tick, ln.at), (x0, ln.at), grey(0.15), 0.8 * pt, True)
            text.put("grid", x0 - tick - 0.15 * fs, ln.at, ln.label, 0.8 * fs, ha="right")
    return [lines, marks]

"""Overlays drawn over a rendered picture: title, colour bar, scale bar, north arrow.

Every overlay sits on an opaque box sized to its measured text. The boxes live
in a column on the right (north arrow at the top, colour bar, scale bar at the
bottom) and a title strip at the top; :func:`plan` says where they go and which
rectangle they leave free, and the default framing
(:func:`geoterrain.rendering.scene.overview`) fits the terrain into that free
rectangle, so the overlays never cover it. They are drawn with
:mod:`geoterrain.rendering.canvas2d` (Pillow, loaded anyway to write the PNG): a render
does not import matplotlib, which cost a cold render about 0.4 s.

Examples
--------
>>> import numpy as np
>>> from geoterrain.rendering.cameras import default_view
>>> img = compose(np.zeros((240, 320, 3), np.uint8), default_view(t, (320, 240)), t)
>>> img.shape, img.dtype.name
((240, 320, 3), 'uint8')
>>> lay = plan((640, 480), title="Fuji", limits=(0.0, 3776.0))
>>> sorted(lay.boxes)
['colorbar', 'north_arrow', 'scale_bar', 'title']
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.rendering.cameras import project
from geoterrain.rendering.canvas2d import Layer, Text, grey
from geoterrain.rendering.canvas2d import text_size as _text_size
from geoterrain.rendering.colours import Palette, colorbar_colours, water_swatch
from geoterrain.rendering.textures import elevation_range, height_tolerance, terrain_palette

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

DPI = 100.0
Box = tuple[float, float, float, float]  # x0, y0, x1, y1 in pixels, y down


def _nice(x: float) -> float:
    e = 10 ** math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * e <= x:
            return m * e
    return e


def _fmt_len(m: float) -> str:
    return f"{m / 1000:g} km" if m >= 1000 else f"{m:g} m"


def _fmt_ve(ve: float) -> str:
    return f"VE ×{ve:g}"


MAX_COLUMN = 0.10  # the overlay column's share of the picture's width, at most
MIN_FONT = 7.5  # pixels: the smallest text an overlay is drawn with


@dataclass
class Layout:
    """Where each overlay box goes (pixels, y down) and the rectangle left free.

    ``compact``: the colour bar names its unit above the bar ("m") instead of a rotated
    "elevation (m)" beside it, to keep the column within ``MAX_COLUMN`` of the width;
    ``swatch``: the water's colour, shown as a swatch under the bar (water without depth
    in the data); ``scale_note``: the scale bar's second line ("at view centre", or
    nothing where the scale is the same everywhere, as in a map view).
    """

    size: tuple[int, int]
    fs: float  # font size in pixels
    boxes: dict[str, Box] = field(default_factory=dict)
    free: Box = (0.0, 0.0, 0.0, 0.0)
    ticks: list[tuple[float, str]] = field(default_factory=list)
    limits: tuple[float, float] | None = None
    compact: bool = False
    swatch: tuple[float, float, float] | None = None
    scale_note: str = "at view centre"


def text_size(s: str, fs: float, bold: bool = False) -> tuple[float, float]:
    """(width, height) in pixels of ``s`` at ``fs`` pixels, in the font the overlays are
    drawn with (:func:`geoterrain.rendering.canvas2d.text_size`).

    Examples
    --------
    >>> w, h = text_size("10 km", 12.0)
    >>> w > h > 0
    True
    """
    return _text_size(s, fs, bold)


def _ticks(lo: float, hi: float) -> list[tuple[float, str]]:
    """Nice ticks in [lo, hi]: multiples of 1, 2, 2.5 or 5 × 10^k, the step whose count of
    ticks inside the range is nearest 5 (3 to 7), labelled with thousands separators.

    Examples
    --------
    >>> [s for _, s in _ticks(0.0, 1668.0)]
    ['0', '500', '1,000', '1,500']
    >>> [s for _, s in _ticks(1009.2, 1265.7)]
    ['1,050', '1,100', '1,150', '1,200', '1,250']
    """
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [(lo, f"{lo:,.0f}")]
    best = None
    e = math.floor(math.log10(hi - lo)) - 2
    for k in range(e, e + 4):
        for m in (1.0, 2.0, 2.5, 5.0):
            step = m * 10.0 ** k
            first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
            n = last - first + 1
            if 3 <= n <= 7 and (best is None or abs(n - 5) < abs(best[2] - 5)):
                best = (step, first, n)
    if best is None:  # cannot happen for a finite range; the two ends then
        return [(lo, f"{lo:,.0f}"), (hi, f"{hi:,.0f}")]
    step, first, n = best
    vals = [(first + i) * step for i in range(n)]
    digits = 0 if step >= 1 else max(0, -math.floor(math.log10(step) + 1e-9))
    if step < 1 and round(step * 10 ** digits, 9) % 1:  # 0.25: two decimals
        digits += 1
    return [(v, f"{v + 0.0:,.{digits}f}") for v in vals]


def plan(size: tuple[int, int], *, title: str | None = None,
         limits: tuple[float, float] | None = None, scale_bar: bool = True,
         north_arrow: bool = True, ve: float = 1.0, units: str = "m",
         swatch: tuple[float, float, float] | None = None, exact_scale: bool = False,
         right: float = 0.0) -> Layout:
    """The overlay boxes for a picture of ``size`` and the free rectangle between them.

    ``limits`` is the colour bar's (lo, hi) in metres; None draws no colour bar;
    ``swatch`` a water colour shown under it. The text scales with the picture (a 45th
    of its shorter side, at least ``MIN_FONT`` px) and the column is kept within
    ``MAX_COLUMN`` of the width (a compact colour bar where the full one would not fit).
    ``exact_scale``: the scale holds everywhere (a map view): the scale bar has no "at
    view centre". ``right``: pixels kept free between the picture and the column (a map's
    tick labels).

    Examples
    --------
    >>> lay = plan((480, 270), limits=(0.0, 1668.0))
    >>> 480 - min(b[0] for b in lay.boxes.values()) <= 0.1 * 480  # the column's share
    True
    """
    W, H = size
    fs = max(MIN_FONT, min(W, H) / 45.0)
    lay = Layout((W, H), fs, limits=limits, swatch=swatch)
    note = "" if exact_scale else "at view centre"
    for compact in (False, True):
        _place_boxes(lay, title, limits, scale_bar, north_arrow, ve, compact, note, right)
        x0 = min((b[0] for k, b in lay.boxes.items() if k != "title"), default=W)
        if W - x0 <= MAX_COLUMN * W + 1e-9:
            break
    return lay


def _place_boxes(lay: Layout, title, limits, scale_bar, north_arrow, ve, compact: bool,
                 note: str, right: float) -> None:
    W, H = lay.size
    fs = lay.fs
    pad, m = 0.5 * fs, 0.5 * fs
    lay.boxes, lay.compact = {}, compact
    lay.scale_note = "at centre" if compact and note else note
    top = 0.0
    if title:
        tw, th = text_size(title, 1.3 * fs, bold=True)
        bw, bh = tw + 2 * pad, th + 2 * pad
        lay.boxes["title"] = (W / 2 - bw / 2, m, W / 2 + bw / 2, m + bh)
        top = m + bh
    widths, heights = {}, {}
    if north_arrow:
        R = 1.8 * fs
        widths["north_arrow"] = heights["north_arrow"] = 2 * R + 2 * pad
    if scale_bar:
        lines = ["500 km"] + ([lay.scale_note] if lay.scale_note else []) \
            + ([_fmt_ve(ve)] if ve != 1 else [])
        tw = max(text_size(s, fs if k == 0 else 0.8 * fs)[0] for k, s in enumerate(lines))
        widths["scale_bar"] = max(tw, 3 * fs) + 2 * pad
        heights["scale_bar"] = 2 * pad + 1.2 * fs + 0.9 * fs + (len(lines) - 1) * 1.0 * fs
    if limits is not None:
        lay.ticks = _ticks(*limits)
        tickw = max((text_size(s, 0.85 * fs)[0] for _, s in lay.ticks), default=0.0)
        if lay.swatch is not None:
            tickw = max(tickw, text_size("water", 0.85 * fs)[0])
        title_w = 0.0 if compact else 1.2 * fs + 0.3 * fs
        widths["colorbar"] = 2 * pad + title_w + tickw + 0.5 * fs + 0.9 * fs
    if not widths:
        lay.free = (m, top + m, W - m - right, H - m)
        return
    cw = max(widths.values())
    x0, x1 = W - m - cw, W - m
    y = top + m
    if north_arrow:
        lay.boxes["north_arrow"] = (x1 - widths["north_arrow"], y, x1, y + heights["north_arrow"])
        y += heights["north_arrow"] + m
    ybot = H - m
    if scale_bar:
        lay.boxes["scale_bar"] = (x0, ybot - heights["scale_bar"], x1, ybot)
        ybot -= heights["scale_bar"] + m
    if limits is not None and ybot - y > 4 * fs:
        lay.boxes["colorbar"] = (x1 - widths["colorbar"], y, x1, ybot)
    lay.free = (m, top + m, x0 - m - right, H - m)


def layout_for(terrain: TerrainLike, size: tuple[int, int], *, shading: str = "normals",
               cmap: str | Palette = "auto", title: str | None = None, colorbar: bool = True,
               scale_bar: bool = True, north_arrow: bool = True, ve: float = 1.0,
               exact_scale: bool = False, right: float = 0.0) -> Layout:
    """:func:`plan` with the colour bar's range (and water swatch) taken from ``terrain``
    and the palette."""
    ve = getattr(terrain, "vertical_exaggeration", 1.0) if ve == 1.0 else ve
    limits = swatch = None
    if colorbar and shading != "plain":
        pal, rng = terrain_palette(terrain, cmap), elevation_range(terrain)
        tol = height_tolerance(terrain)
        _, limits = colorbar_colours(pal, rng, tolerance=tol)
        swatch = water_swatch(pal, rng, tol)
    return plan(size, title=title, limits=limits, scale_bar=scale_bar,
                north_arrow=north_arrow, ve=ve, swatch=swatch, exact_scale=exact_scale,
                right=right)


def north_direction(view: View) -> np.ndarray | None:
    """Unit screen vector (x right, y down) of north at the view's target, or None."""
    target = np.asarray(view.look_at, np.float64)
    step = max(1e-3, 0.05 * float(np.linalg.norm(target - view.eye)))
    (a, b), z = project(view, np.stack([target, target + np.array([0.0, step, 0.0])]))
    d = b - a
    if not (np.all(z > 0) and np.linalg.norm(d) > 1e-6):
        return None
    return d / np.linalg.norm(d)


def compose(img: np.ndarray, view: View, terrain: TerrainLike, *, shading: str = "normals",
            cmap: str | Palette = "auto", title: str | None = None, colorbar: bool = True,
            scale_bar: bool = True, north_arrow: bool = True, ve: float = 1.0,
            layout: Layout | None = None, extents: dict | None = None) -> np.ndarray:
    """Draw the title, colour bar, scale bar and north arrow over a rendered image.

    Each sits on an opaque box of :func:`layout_for`. The scale bar's box says
    "VE ×N" when the terrain is drawn exaggerated
    (:func:`geoterrain.exaggerate.exaggerated`). A map view (``view.parallel``) also gets
    its neat line, grid and coordinate labels (:mod:`geoterrain.rendering.mapview`), and
    its scale bar holds everywhere. ``extents``, when given, is
    filled with the drawn text's pixel boxes per overlay (for tests).

    Examples
    --------
    >>> out = compose(img, view, t, title="Fuji")  # doctest: +SKIP
    """
    H, W = img.shape[:2]
    ve = getattr(terrain, "vertical_exaggeration", 1.0) if ve == 1.0 else ve
    if layout is None:
        layout = layout_for(terrain, (W, H), shading=shading, cmap=cmap, title=title,
                            colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow,
                            ve=ve, exact_scale=view.parallel)
    if not layout.boxes and not view.parallel:
        return img
    img = np.array(img, np.uint8, copy=True)
    text = Text()
    shapes: list[Layer] = []
    if view.parallel:  # a map: its neat line, grid and labels in the DEM's coordinates
        from geoterrain.rendering.mapgrid import draw_map_grid

        shapes += draw_map_grid(text, terrain, view, layout.fs)
    fs = layout.fs
    pad = 0.5 * fs
    PT = DPI / 72.0  # pixels per point: the strokes' widths as matplotlib drew them

    def box(name):
        lay = Layer(layout.boxes[name])
        lay.rect(layout.boxes[name], fill=(255, 255, 255), edge=grey(0.55), lw=0.8 * PT)
        shapes.append(lay)
        return (lay, *layout.boxes[name])

    if "title" in layout.boxes:
        _, x0, y0, x1, y1 = box("title")
        text.put("title", 0.5 * (x0 + x1), 0.5 * (y0 + y1), title, 1.3 * fs, bold=True)
    if "colorbar" in layout.boxes:
        lay, x0, y0, x1, y1 = box("colorbar")
        rgb, (lo, hi) = colorbar_colours(terrain_palette(terrain, cmap),
                                         elevation_range(terrain),
                                         tolerance=height_tolerance(terrain))
        bx0, by0, bx1, by1 = colorbar_rect(layout)
        if layout.compact:  # the unit above the bar
            text.put("colorbar", 0.5 * (bx0 + bx1), y0 + pad + 0.55 * fs, "m", 0.85 * fs)
        if layout.swatch is not None:  # water without depth: its own swatch, no range
            sw = 0.9 * fs
            sy1 = by1 + sw + 0.6 * fs
            lay.rect((bx0, sy1 - sw, bx1, sy1), fill=_bytes(layout.swatch), edge=grey(0.3),
                     lw=0.6 * PT)
            text.put("colorbar", bx0 - 0.45 * fs, sy1 - 0.5 * sw, "water", 0.85 * fs,
                     ha="right")
        lay.image((bx0, by0, bx1, by1), lambda y: bar_colours(rgb, (by1 - y) / (by1 - by0)))
        lay.frame((bx0, by0, bx1, by1), grey(0.3), 0.6 * PT)
        for v, s in layout.ticks:
            yy = by1 - (v - lo) / (hi - lo) * (by1 - by0)
            lay.segment((bx0 - 0.3 * fs, yy), (bx0, yy), grey(0.2), 0.8 * PT, True)
            text.put("colorbar", bx0 - 0.45 * fs, yy, s, 0.85 * fs, ha="right")
        if not layout.compact:
            text.put("colorbar", x0 + pad + 0.6 * fs, 0.5 * (by0 + by1), "elevation (m)", fs,
                     rotate=True)
    target = np.asarray(view.look_at, np.float64)
    r, _, _ = view.basis()
    if "scale_bar" in layout.boxes:
        lay, x0, y0, x1, y1 = box("scale_bar")
        avail = x1 - x0 - 2 * pad
        rh = np.array([r[0], r[1], 0.0])
        px, length = 0.0, 0.0
        if np.linalg.norm(rh) > 1e-9:
            # a horizontal segment through the target, across the view: metres per pixel
            rh /= np.linalg.norm(rh)
            step = 10 * max(float(np.linalg.norm(target - view.eye)) / view.lam, 1e-9)
            (pa, pb), z = project(view, np.stack([target, target + step * rh]))
            px_per_m = float(np.linalg.norm(pb - pa)) / step if np.all(z > 0) else 0.0
            if px_per_m > 0:
                length = _nice(avail / px_per_m)
                px = length * px_per_m
        cx = 0.5 * (x0 + x1)
        yb = y0 + pad + 1.2 * fs + 0.3 * fs
        if np.isfinite(px) and 2 < px <= avail + 0.5:
            lay.segment((cx - px / 2, yb), (cx + px / 2, yb), (0, 0, 0), 3 * PT)
            for xx in (cx - px / 2, cx + px / 2):
                lay.segment((xx, yb - 0.3 * fs), (xx, yb + 0.3 * fs), (0, 0, 0), 1.2 * PT,
                            True)
            text.put("scale_bar", cx, yb - 0.4 * fs, _fmt_len(length), fs, va="bottom")
            if layout.scale_note:
                text.put("scale_bar", cx, yb + 0.5 * fs, layout.scale_note, 0.8 * fs,
                         va="top")
        if ve != 1:
            text.put("scale_bar", cx, y1 - pad, _fmt_ve(ve), 0.8 * fs, va="bottom")
    if "north_arrow" in layout.boxes:
        lay, x0, y0, x1, y1 = box("north_arrow")
        d = north_direction(view)
        if d is not None:
            c = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
            R = 1.8 * fs
            lay.ring(c, R, grey(0.7), 0.8 * PT)
            # matplotlib's "-|>" arrow: its ends pulled in 2 pt, a head 0.4 × 0.2 of its
            # mutation scale (0.9 fs points), stroked as the shaft
            tail, tip = c - 0.7 * R * d + 2 * PT * d, c + 0.4 * R * d - 2 * PT * d
            hl, hw = 0.4 * 0.9 * fs * PT, 0.2 * 0.9 * fs * PT
            n = np.array([-d[1], d[0]])
            lay.segment(tail, tip - 0.5 * hl * d, (0, 0, 0), 2 * PT)
            lay.polygon(np.stack([tip, tip - hl * d + hw * n, tip - hl * d - hw * n]),
                        (0, 0, 0), 2 * PT)
            text.put("north_arrow", *(c + 0.72 * R * d), "N", 0.8 * fs, bold=True)
    for lay in shapes:  # under the text
        lay.over(img)
    out = text.draw_on(img)
    if extents is not None:
        extents.update(text.extents())
    return out


def colorbar_rect(layout: Layout) -> Box:
    """The colour bar's gradient (x0, y0, x1, y1) in its box of ``layout``: below the
    unit of a compact bar, above the water's swatch.

    Examples
    --------
    >>> lay = plan((640, 480), limits=(0.0, 3776.0))
    >>> x0, y0, x1, y1 = colorbar_rect(lay)
    >>> bx0, by0, bx1, by1 = lay.boxes["colorbar"]
    >>> bx0 < x0 < x1 < bx1 and by0 < y0 < y1 < by1
    True
    """
    x0, y0, x1, y1 = layout.boxes["colorbar"]
    fs = layout.fs
    pad = 0.5 * fs
    bx1 = x1 - pad
    by0, by1 = y0 + pad + 0.5 * fs, y1 - pad - 0.5 * fs
    if layout.compact:
        by0 += 1.1 * fs
    if layout.swatch is not None:
        by1 -= 0.9 * fs + 0.6 * fs
    return bx1 - 0.9 * fs, by0, bx1, by1


def _bytes(rgb) -> tuple[int, int, int]:
    return tuple(int(round(255 * float(c))) for c in rgb[:3])


def bar_colours(rgb: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """The colour bar's colours (uint8) at fractions ``frac`` of its height (0 its foot):
    the table ``rgb`` (n colours, each the centre of an n-th of the bar) interpolated
    linearly, as an image of it is drawn smoothly.

    Examples
    --------
    >>> rgb = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    >>> bar_colours(rgb, np.array([0.0, 0.5, 1.0]))[:, 0].tolist()
    [0, 128, 255]
    """
    k = np.clip(np.asarray(frac, np.float64) * len(rgb) - 0.5, 0, len(rgb) - 1)
    i = np.minimum(k.astype(np.int64), len(rgb) - 2) if len(rgb) > 1 else k.astype(np.int64)
    w = (k - i)[:, None] if len(rgb) > 1 else 0.0
    c = rgb[i] * (1 - w) + (rgb[np.minimum(i + 1, len(rgb) - 1)] * w)
    return np.round(255 * np.clip(c, 0, 1)).astype(np.uint8)


def canvas_over(fig, img: np.ndarray) -> np.ndarray:
    """The drawn matplotlib figure ``fig`` (the picture's size) composited :func:`over`
    ``img``."""
    H, W = img.shape[:2]
    rgba = np.asarray(fig.canvas.buffer_rgba())
    if rgba.shape[:2] != (H, W):  # matplotlib before 3.11 could round a size down a pixel
        fit = np.zeros((H, W, 4), np.uint8)
        h, w = min(H, rgba.shape[0]), min(W, rgba.shape[1])
        fit[:h, :w] = rgba[:h, :w]
        rgba = fit
    return over(img, rgba)


def over(img: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """``rgba`` (straight alpha, uint8) composited over the opaque picture ``img``.

    Porter–Duff "over" with the result rounded to the nearest integer, as Agg blends:
    out = (img·(255 − a) + rgb·a) / 255, on the pixels the overlays touch only.

    Examples
    --------
    >>> img = np.full((1, 2, 3), 200, np.uint8)
    >>> rgba = np.array([[[0, 0, 0, 255], [0, 0, 0, 0]]], np.uint8)
    >>> over(img, rgba)[0, :, 0].tolist()
    [0, 200]
    """
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"over: the picture must be (H, W, 3) uint8, not {img.shape} "
                         f"{img.dtype}")
    if rgba.dtype != np.uint8 or rgba.shape != (*img.shape[:2], 4):
        raise ValueError(f"over: the overlay must be {(*img.shape[:2], 4)} uint8, not "
                         f"{rgba.shape} {rgba.dtype}")
    out = np.array(img, np.uint8, copy=True)
    flat, src = out.reshape(-1, 3), rgba.reshape(-1, 4)
    idx = np.flatnonzero(src[:, 3])
    src = src[idx]
    a = src[:, 3:4].astype(np.uint16)
    mix = flat[idx] * (255 - a) + src[:, :3] * a + np.uint16(128)  # ≤ 65 153
    flat[idx] = (mix + (mix >> 8)) >> 8  # = round(mix / 255), exact below 65 536
    return out


def draw_lines(img: np.ndarray, view: View, lines: list, depth: np.ndarray | None = None, *,
               widths: list | None = None, colour: tuple[int, int, int] = (60, 40, 20),
               alpha: float = 0.85) -> np.ndarray:
    """Draw 3-D polylines (scene coordinates, each (n, 3)) over a rendered picture where
    the terrain does not hide them: contour lines on the view.

    Each segment is projected with the picture's camera; with the picture's ``depth``
    buffer (:func:`geoterrain.rendering.antialias.depth_buffer`, against the view's near
    and far planes) a segment is drawn when both its ends lie no deeper than the drawn
    surface there, with a slack of 1 % of the depth and three pixels' worth (the level of
    detail may place the surface that far from the line's true height). Lines are
    antialiased by Agg and blended "over" the picture; ``widths`` (pixels, per line;
    default 1) makes every fifth contour bolder, as maps draw index contours.

    Examples
    --------
    >>> from geoterrain.rendering.cameras import default_view
    >>> v = default_view(t, (160, 120))
    >>> lo, hi = t.scene_box()
    >>> line = np.array([[lo[0], 0.0, hi[2]], [hi[0], 0.0, hi[2]]])
    >>> out = draw_lines(np.full((120, 160, 3), 255, np.uint8), v, [line])
    >>> int((out < 200).any(-1).sum()) > 20
    True
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    H, W = img.shape[:2]
    if not lines:
        return img
    segs, lw = [], []
    for k, line in enumerate(lines):
        p = np.asarray(line, np.float64)
        if len(p) < 2:
            continue
        xy, z = project(view, p)
        ok = z > (view.near or 1e-9)
        if depth is not None and view.near is not None and view.far is not None:
            n, f = view.near, view.far
            px = np.clip(np.round(xy).astype(np.int64), [0, 0], [W - 1, H - 1])
            d = depth[px[:, 1], px[:, 0]].astype(np.float64)
            zb = n * f / np.maximum(f - d * (f - n), 1e-12)  # the drawn surface's depth
            slack = 0.01 * zb + 3.0 * z / view.lam
            ok &= (z <= zb + slack) & (d < 1.0)
        keep = ok[:-1] & ok[1:]
        if keep.any():
            s = np.stack([xy[:-1][keep], xy[1:][keep]], 1)
            segs.append(s)
            lw += [1.0 if widths is None else float(widths[k])] * len(s)
    if not segs:
        return img
    fig = Figure(figsize=(W / DPI, H / DPI), dpi=DPI, facecolor="none")
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.axis("off")
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    col = tuple(c / 255 for c in colour) + (alpha,)
    ax.add_collection(LineCollection(np.concatenate(segs), linewidths=np.asarray(lw) * 0.72,
                                     colors=[col], antialiaseds=True, capstyle="round"))
    fig.canvas.draw()
    return canvas_over(fig, img)

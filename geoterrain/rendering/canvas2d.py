"""Flat 2-D drawing over a rendered picture without matplotlib: boxes, bars, lines,
triangles and circles anti-aliased by supersampling, and text in matplotlib's own font.

A cold render pays for what it imports: matplotlib's figure and Agg canvas cost about
0.4 s of a fresh process, more than the overlays' whole drawing. Pillow is loaded anyway
to write the PNG, and FreeType (inside Pillow) draws the text, in the DejaVu Sans that
matplotlib ships and draws its own text with (found on disk, matplotlib not imported;
Pillow's built-in font where it is missing).

:class:`Layer` draws shapes at ``SS`` × the picture's resolution on a transparent patch
and reduces them by summing each pixel's ``SS``² subpixels: the coverage of every edge,
composited "over" the picture as premultiplied colour (shapes are opaque, so a
subpixel's colour is its premultiplied colour). Text is drawn after the shapes at the
picture's own resolution, FreeType's grey levels blended over what lies beneath.

Examples
--------
>>> import numpy as np
>>> img = np.zeros((20, 30, 3), np.uint8)
>>> lay = Layer((2.0, 2.0, 12.5, 12.5))
>>> lay.polygon([(2.0, 2.0), (12.5, 2.0), (12.5, 12.0), (2.0, 12.0)], (255, 255, 255))
>>> out = lay.over(img)
>>> out[5, 5].tolist(), bool(0 < out[5, 12, 0] < 255), out[5, 13].tolist()  # an edge's coverage
([255, 255, 255], True, [0, 0, 0])
>>> w, h = text_size("10 km", 12.0)
>>> w > h > 0
True
"""

from __future__ import annotations

import functools
import importlib.util
import math
import os
from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

SS = 4  # subpixels per pixel and axis: coverage in steps of 1/16
RGB = tuple[int, int, int]


def grey(level: float) -> RGB:
    """matplotlib's grey ``"0.55"`` as bytes.

    Examples
    --------
    >>> grey(0.55)
    (140, 140, 140)
    """
    v = int(round(255 * level))
    return (v, v, v)


def _font_file(bold: bool) -> str | None:
    spec = importlib.util.find_spec("matplotlib")  # finds the package, does not import it
    name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
    for loc in (spec.submodule_search_locations or []) if spec else []:
        path = os.path.join(loc, "mpl-data", "fonts", "ttf", name)
        if os.path.exists(path):
            return path
    return None


@functools.lru_cache(maxsize=64)
def font(size: float, bold: bool = False) -> ImageFont.FreeTypeFont:
    """DejaVu Sans (bold) at ``size`` pixels per em, as matplotlib draws text at
    ``size`` × 72 / dpi points."""
    path = _font_file(bold)
    if path is None:
        return ImageFont.load_default(size)
    return ImageFont.truetype(path, size)


def text_size(s: str, fs: float, bold: bool = False) -> tuple[float, float]:
    """(width, height) in pixels of the ink of ``s`` at ``fs`` pixels (as matplotlib
    measures text).

    Examples
    --------
    >>> text_size("m", 10.0)[0] < text_size("mm", 10.0)[0]
    True
    """
    f = font(round(fs, 3), bold)
    left, top, right, bottom = f.getbbox(s, anchor="ls")
    return float(right - left), float(bottom - top)


class Layer:
    """Opaque shapes over the rectangle ``box`` (x0, y0, x1, y1, pixels, y down) of a
    picture, drawn at ``SS`` × and composited with their edges' coverage by :meth:`over`.
    Shapes reaching outside ``box`` by more than two pixels are cut, and outside it at
    all with ``clip``; ``alpha`` makes the whole layer that opaque."""

    def __init__(self, box: Sequence[float], alpha: float = 1.0, clip: bool = False):
        self.alpha, self.clip = float(alpha), tuple(box) if clip else None
        self.x0, self.y0 = math.floor(box[0]) - 2, math.floor(box[1]) - 2
        self.w = math.ceil(box[2]) + 2 - self.x0
        self.h = math.ceil(box[3]) + 2 - self.y0
        self.im = Image.new("RGBA", (self.w * SS, self.h * SS), (0, 0, 0, 0))
        self.draw = ImageDraw.Draw(self.im)

    def _xy(self, x: float, y: float) -> tuple[float, float]:
        return (x - self.x0) * SS, (y - self.y0) * SS

    def _box(self, x0: float, y0: float, x1: float, y1: float) -> tuple[int, int, int, int]:
        """The subpixels whose centres lie inside [x0, x1) × [y0, y1) (Pillow's boxes
        include their last row and column)."""
        (a, b), (c, d) = self._xy(x0, y0), self._xy(x1, y1)
        return round(a), round(b), round(c) - 1, round(d) - 1

    @staticmethod
    def snap(v: float, lw: float) -> float:
        """``v`` moved to where Agg snaps a straight stroke ``lw`` wide: a pixel's centre
        for an odd width in whole pixels, else its edge, so the stroke stays crisp."""
        return math.floor(v + 0.5) + (0.5 if round(lw) % 2 else 0.0)

    def rect(self, box: Sequence[float], fill: RGB | None = None, edge: RGB | None = None,
             lw: float = 0.0) -> None:
        """A rectangle filled with ``fill`` and stroked ``lw`` pixels wide with ``edge``,
        the stroke centred on its outline (as matplotlib strokes a patch), snapped."""
        x0, y0, x1, y1 = box = [self.snap(v, lw) for v in box]
        h = 0.5 * lw if edge is not None and lw > 0 else 0.0
        if fill is None:
            if h:
                self.frame(box, edge, lw)
            return
        if h:
            self.draw.rectangle(self._box(x0 - h, y0 - h, x1 + h, y1 + h), fill=edge)
        self.draw.rectangle(self._box(x0 + h, y0 + h, x1 - h, y1 - h), fill=fill)

    def frame(self, box: Sequence[float], edge: RGB, lw: float) -> None:
        """The outline of ``box`` only, ``lw`` pixels wide, centred on it, snapped."""
        x0, y0, x1, y1 = (self.snap(v, lw) for v in box)
        h = 0.5 * lw
        for b in ((x0 - h, y0 - h, x1 + h, y0 + h), (x0 - h, y1 - h, x1 + h, y1 + h),
                  (x0 - h, y0 + h, x0 + h, y1 - h), (x1 - h, y0 + h, x1 + h, y1 - h)):
            self.draw.rectangle(self._box(*b), fill=edge)

    def image(self, box: Sequence[float], colour_of_row) -> None:
        """Fill ``box`` with rows of colour: ``colour_of_row(y)`` gives (n, 3) uint8 for
        the subpixel rows' centres ``y`` (picture pixels)."""
        a, b, c, d = self._box(*box)
        if c < a or d < b:
            return
        y = (np.arange(b, d + 1) + 0.5) / SS + self.y0
        rows = np.asarray(colour_of_row(y), np.uint8)
        patch = np.empty((len(rows), c - a + 1, 4), np.uint8)
        patch[..., :3] = rows[:, None, :]
        patch[..., 3] = 255
        self.im.paste(Image.fromarray(patch, "RGBA"), (a, b))

    def polygon(self, pts: np.ndarray, fill: RGB, lw: float = 0.0) -> None:
        """The polygon through ``pts`` ((n, 2) pixels), filled, and stroked ``lw`` wide
        in the same colour."""
        xy = [self._xy(*p) for p in np.asarray(pts, np.float64)]
        self.draw.polygon(xy, fill=fill)
        if lw > 0:
            self.draw.line(xy + xy[:1], fill=fill, width=max(1, round(lw * SS)),
                           joint="curve")

    def segment(self, a: Sequence[float], b: Sequence[float], colour: RGB, lw: float,
                projecting: bool = False) -> None:
        """A straight stroke from ``a`` to ``b``, ``lw`` pixels wide, its square ends at
        them or (``projecting``, matplotlib's default for lines) half its width beyond."""
        a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
        d = b - a
        n = np.hypot(*d)
        if n == 0:
            return
        if d[0] == 0 or d[1] == 0:  # level or upright: snapped as Agg snaps it
            a = np.array([self.snap(v, lw) for v in a])
            b = np.array([self.snap(v, lw) for v in b])
            d = b - a
            n = np.hypot(*d)
            if n == 0:
                return
        if projecting:
            a, b = a - d / n * 0.5 * lw, b + d / n * 0.5 * lw
        if d[0] == 0 or d[1] == 0:  # a rectangle: exact coverage
            h = 0.5 * lw
            lo, hi = np.minimum(a, b) - (h if d[0] == 0 else 0, h if d[1] == 0 else 0), \
                np.maximum(a, b) + (h if d[0] == 0 else 0, h if d[1] == 0 else 0)
            self.draw.rectangle(self._box(lo[0], lo[1], hi[0], hi[1]), fill=colour)
            return
        u = np.array([-d[1], d[0]]) / n * 0.5 * lw
        self.polygon(np.stack([a + u, b + u, b - u, a - u]), colour)

    def polyline(self, pts: np.ndarray, colour: RGB, lw: float) -> None:
        """Straight strokes through the points ``pts`` ((n, 2) pixels), ``lw`` wide;
        snapped (:meth:`snap`) where every stroke is level or upright, as Agg does."""
        p = np.asarray(pts, np.float64)
        d = np.diff(p, axis=0)
        if len(d) and ((d[:, 0] == 0) | (d[:, 1] == 0)).all():
            p = np.floor(p + 0.5) + (0.5 if round(lw) % 2 else 0.0)
        xy = (p - (self.x0, self.y0)) * SS
        self.draw.line(xy.ravel().tolist(), fill=colour, width=max(1, round(lw * SS)),
                       joint="curve")

    def ring(self, c: Sequence[float], r: float, colour: RGB, lw: float) -> None:
        """A circle of radius ``r`` about ``c``, stroked ``lw`` pixels wide."""
        (x, y), ro = self._xy(*c), (r + 0.5 * lw) * SS
        self.draw.ellipse((x - ro, y - ro, x + ro, y + ro), outline=colour,
                          width=max(1, round(lw * SS)))

    def over(self, img: np.ndarray) -> np.ndarray:
        """``img`` with the layer composited over it (in place; returned)."""
        H, W = img.shape[:2]
        cx0, cy0 = max(self.x0, 0), max(self.y0, 0)
        cx1, cy1 = min(self.x0 + self.w, W), min(self.y0 + self.h, H)
        if cx1 <= cx0 or cy1 <= cy0:
            return img
        sub = np.asarray(self.im)
        if self.clip is not None:  # the subpixels outside the box cleared
            a, b, c, d = self._box(*self.clip)
            sub = sub.copy()
            sub[:max(b, 0)] = 0
            sub[d + 1:] = 0
            sub[:, :max(a, 0)] = 0
            sub[:, c + 1:] = 0
        sub = sub[(cy0 - self.y0) * SS:(cy1 - self.y0) * SS,
                  (cx0 - self.x0) * SS:(cx1 - self.x0) * SS]
        rows = sub[0::SS].astype(np.uint16)  # strided adds: 5× numpy's sum over axes
        for k in range(1, SS):
            rows += sub[k::SS]
        tot = rows[:, 0::SS].astype(np.uint32)  # premultiplied: a clear subpixel is 0
        for k in range(1, SS):
            tot += rows[:, k::SS]
        if self.alpha != 1.0:
            tot = np.round(tot * self.alpha).astype(np.uint32)
        full = np.uint32(SS * SS * 255)
        dst = img[cy0:cy1, cx0:cx1]
        a = tot[..., 3:4]
        mix = dst.astype(np.uint32) * (full - a) + tot[..., :3] * np.uint32(255)
        dst[...] = ((mix + full // 2) // full).astype(np.uint8)
        return img


class Text:
    """Text to draw over a picture at its own resolution, after its shapes: :meth:`put`
    notes each, :meth:`draw_on` draws them all; ``boxes`` then holds each drawn text's
    ink box (x0, y0, x1, y1) under its name, for tests."""

    def __init__(self):
        self.items: list[tuple] = []
        self.boxes: dict[str, list] = {}

    def put(self, name: str, x: float, y: float, s: str, fs: float, ha: str = "center",
            va: str = "center", bold: bool = False, colour: RGB = (0, 0, 0),
            rotate: bool = False) -> None:
        """``s`` at ``fs`` pixels, placed as matplotlib's ``ha`` (left, center, right)
        and ``va`` (top, center, bottom: the text's ink) say; ``rotate``: read upwards."""
        self.items.append((name, x, y, s, fs, ha, va, bold, colour, rotate))

    def draw_on(self, img: np.ndarray) -> np.ndarray:
        """A copy of ``img`` (H, W, 3) uint8 with the texts drawn."""
        pim = Image.fromarray(np.ascontiguousarray(img, np.uint8), "RGB")
        draw = ImageDraw.Draw(pim)
        for name, x, y, s, fs, ha, va, bold, colour, rotate in self.items:
            f = font(round(fs, 3), bold)
            anchor = "ls"  # placed by its ink, as matplotlib places text
            x_l, t, r, b = f.getbbox(s, anchor=anchor)
            # matplotlib's text box: the ink's, at least as tall and deep as "lp"
            _, t_lp, _, b_lp = f.getbbox("lp", anchor="ls")
            top, bottom = min(t, t_lp), max(b, b_lp)
            dy = {"top": -top, "center": -0.5 * (top + bottom), "bottom": -bottom}[va]
            if not rotate:
                xa = x - {"left": x_l, "center": 0.5 * (x_l + r), "right": r}[ha]
                draw.text((xa, y + dy), s, fill=colour, font=f, anchor=anchor)
                box = draw.textbbox((xa, y + dy), s, font=f, anchor=anchor)
            else:  # drawn level on a mask, turned a quarter left, centred at (x, y)
                mask = Image.new("L", (math.ceil(r - x_l) + 4, math.ceil(b - t) + 4), 0)
                ImageDraw.Draw(mask).text((2 - x_l, 2 - t), s, fill=255, font=f,
                                          anchor=anchor)
                mask = mask.transpose(Image.Transpose.ROTATE_90)
                x0, y0 = round(x - mask.width / 2), round(y - mask.height / 2)
                pim.paste(colour, (x0, y0, x0 + mask.width, y0 + mask.height), mask)
                ink = mask.getbbox() or (0, 0, 0, 0)
                box = (x0 + ink[0], y0 + ink[1], x0 + ink[2], y0 + ink[3])
            self.boxes.setdefault(name, []).append(tuple(float(v) for v in box))
        return np.array(pim)

    def extents(self) -> dict[str, tuple[float, float, float, float]]:
        """Each name's drawn texts' joint box."""
        return {k: (min(b[0] for b in bs), min(b[1] for b in bs), max(b[2] for b in bs),
                    max(b[3] for b in bs)) for k, bs in self.boxes.items()}

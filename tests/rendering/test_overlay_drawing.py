"""The overlays as drawn (without matplotlib): the colour bar shows the palette's colours
at the heights its ticks name, the water swatch its colour, every text is legible ink
inside its box, the title is centred, and a render does not import matplotlib."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.rendering.canvas2d import Layer
from geoterrain.rendering.colours import Palette, colorize, water_swatch
from geoterrain.rendering.overlays import colorbar_rect, compose, layout_for
from geoterrain.rendering.scene import overview
from geoterrain.rendering.textures import elevation_range, height_tolerance, terrain_palette
from tests.rendering.test_pictures import topobathy
from tests.rendering.test_render import synth_store

SIZE = (640, 360)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_layer_covers_exactly_what_it_draws(seed):
    """A layer's opaque fill over whole pixels replaces them; a fill over half of a row
    of pixels blends it half and half (within a level: rounding); every other pixel is
    the picture's, bit for bit, the layer's margin included."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    x0, x1 = sorted(rng.choice(np.arange(-3, 36), 2, replace=False))
    y0, y1 = sorted(rng.choice(np.arange(-3, 28), 2, replace=False))
    c = rng.integers(0, 256, 3)
    lay = Layer((x0, y0 - 1, x1, y1))
    lay.image((x0, y0 - 0.5, x1, y1), lambda y: np.broadcast_to(c, (len(y), 3)))
    out = lay.over(img.copy())
    inside = np.zeros((24, 32), bool)
    inside[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = True
    assert (out[inside] == c).all()
    half = np.zeros((24, 32), bool)
    if 0 <= y0 - 1 < 24:
        half[y0 - 1, max(x0, 0):max(x1, 0)] = True
        want = (img[half].astype(int) + c) / 2
        assert (np.abs(out[half] - want) <= 1.0).all()
    assert np.array_equal(out[~inside & ~half], img[~inside & ~half])


def _overlaid(t, **kw):
    v = overview(t, SIZE, **kw)
    ext: dict = {}
    out = compose(np.zeros((SIZE[1], SIZE[0], 3), np.uint8), v, t, extents=ext, **kw)
    return out, ext, layout_for(t, SIZE, **kw)


@pytest.mark.fast
@pytest.mark.parametrize("case", ["land", "depths", "swatch"])
def test_colour_bar_shows_the_palette(tmp_path_factory, case):
    """Down the bar's middle, 2 px in from its ends, each pixel is the palette's colour
    (:func:`colorize`, computed apart from the bar) of the height its row stands for,
    within 3 levels (the bar is a 256-colour table, interpolated); the swatch is the
    water's colour."""
    if case == "land":
        t, kw = synth_store(tmp_path_factory, "synth"), {}
    else:
        t, _ = topobathy(tmp_path_factory)
        kw = {} if case == "depths" else {"cmap": Palette("auto", sea=False,
                                                            water_level=-300.0)}
    out, _, lay = _overlaid(t, **kw)
    pal, rng = terrain_palette(t, kw.get("cmap", "auto")), elevation_range(t)
    lo, hi = lay.limits
    x0, y0, x1, y1 = colorbar_rect(lay)
    rows = np.arange(int(np.ceil(y0)) + 2, int(y1) - 2)
    col = int(0.5 * (x0 + x1))
    h = hi - (rows + 0.5 - y0) / (y1 - y0) * (hi - lo)  # the bar's top is hi
    want = np.round(255 * colorize(h, pal, rng, height_tolerance(t))).astype(int)
    got = out[rows, col].astype(int)
    # where the palette steps (the coast) a row may blend its neighbours' colours
    step = np.abs(want[2:] - want[:-2]).max(1)
    err = np.abs(got - want).max(1)[1:-1]
    assert (err <= 3 + step).all(), (err - step).max()
    assert np.median(err) <= 3
    if case == "swatch":
        sw = water_swatch(pal, rng, height_tolerance(t))
        assert sw is not None and lay.swatch == sw
        fs = lay.fs
        sy = int(y1 + 0.6 * fs + 0.45 * fs)  # the swatch's middle row
        assert np.abs(out[sy, col].astype(int) - np.round(255 * np.array(sw))).max() <= 1
    else:
        assert lay.swatch is None


@pytest.mark.fast
def test_texts_are_legible_ink_inside_their_boxes(tmp_path_factory):
    """Each overlay's text (black on its white box): between 8 % and 60 % of the pixels
    of its ink box are dark (the colour bar's labels, spread down the bar, at least 1.5 %),
    none of it outside the box; the title centred in its box within a pixel."""
    t = synth_store(tmp_path_factory, "synth")
    out, ext, lay = _overlaid(t, title="Noise")
    assert set(ext) == {"title", "colorbar", "scale_bar", "north_arrow"}
    lum = out.astype(np.float64) @ [0.299, 0.587, 0.114]
    for name, (x0, y0, x1, y1) in ext.items():
        bx0, by0, bx1, by1 = lay.boxes[name]
        assert bx0 <= x0 and x1 <= bx1 and by0 <= y0 and y1 <= by1, name
        dark = lum[int(y0):int(np.ceil(y1)), int(x0):int(np.ceil(x1))] < 128
        assert (0.015 if name == "colorbar" else 0.08) <= dark.mean() <= 0.60, \
            (name, dark.mean())
    (x0, y0, x1, y1), (bx0, by0, bx1, by1) = ext["title"], lay.boxes["title"]
    assert abs(0.5 * (x0 + x1) - 0.5 * (bx0 + bx1)) <= 1.0
    assert abs(0.5 * (y0 + y1) - 0.5 * (by0 + by1)) <= 1.5


@pytest.mark.fast
def test_a_render_with_overlays_does_not_import_matplotlib(tmp_path_factory, tmp_path):
    """The default render (colour bar, scale bar, north arrow, a title) in a fresh
    process: matplotlib (about 0.4 s of a cold start) is never imported."""
    t = synth_store(tmp_path_factory, "synth")
    code = ("import sys, geoterrain\n"
            "from geoterrain.rendering.scene import render\n"
            f"with geoterrain.open({str(t.path)!r}) as t:\n"
            f"    render(t, None, {str(tmp_path / 'v.png')!r}, title='Noise')\n"
            "print(sorted(m for m in sys.modules if m.startswith('matplotlib')))\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.strip() == "[]", res.stdout
    assert (tmp_path / "v.png").stat().st_size > 0

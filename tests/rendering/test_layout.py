"""Legends and layout as a report needs them: a small picture's overlay column within a
tenth of its width, orbits that fill the frame on every frame, nice ticks, no colour-bar
range the data does not have, and no black hairlines in the default pictures."""

from __future__ import annotations

import math

import numpy as np
import pytest

import geoterrain
from geoterrain.exaggerate import exaggerated
from geoterrain.rendering.antialias import depth_buffer
from geoterrain.rendering.cameras import orbit_views
from geoterrain.rendering.colours import LAND, WATER, Palette, colorbar_map, water_swatch
from geoterrain.rendering.overlays import _ticks, compose, layout_for
from geoterrain.rendering.scene import TerrainScene, overview
from geoterrain.rendering.shading import AMBIENT
from geoterrain.rendering.textures import elevation_range
from geoterrain.rendering.window import pyvista_plotter
from tests.rendering.test_pictures import topobathy
from tests.rendering.test_render import real_store, synth_store

SMALL = (480, 270)
ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


def _column(lay) -> float:
    """The share of the picture's width the overlay column takes (its boxes' left edge to
    the picture's right edge)."""
    x0 = min(b[0] for k, b in lay.boxes.items() if k != "title")
    return (lay.size[0] - x0) / lay.size[0]


@pytest.mark.fast
def test_overlay_column_is_at_most_a_tenth_at_480x270(tmp_path_factory):
    t, _ = topobathy(tmp_path_factory)
    e = exaggerated(t, 3.0)  # a "VE ×3" line in the scale bar's box
    for terr, kw in ((t, {}), (e, {"title": "Topobathy"}),
                     (t, {"cmap": Palette("auto", water_level=40.0)})):
        lay = layout_for(terr, SMALL, **kw)
        assert {"colorbar", "scale_bar", "north_arrow"} <= set(lay.boxes)
        assert _column(lay) <= 0.10, (kw, _column(lay))
        # the text stays inside its boxes
        v = overview(terr, SMALL, **kw)
        ext: dict = {}
        compose(np.zeros((270, 480, 3), np.uint8), v, terr, extents=ext, **kw)
        for name, (x0, y0, x1, y1) in ext.items():
            bx0, by0, bx1, by1 = lay.boxes[name]
            assert bx0 - 0.5 <= x0 and x1 <= bx1 + 0.5 and by0 - 0.5 <= y0 and y1 <= by1 + 0.5
    # larger pictures keep to the tenth too, with the text scaled with them
    for size in ((640, 360), (1280, 720)):
        lay = layout_for(t, size, title="Topobathy")
        assert _column(lay) <= 0.10 and lay.fs == pytest.approx(min(size) / 45)


def _visible_terrain(scene, lay) -> float:
    z = depth_buffer(scene.plotter) < 1.0
    for x0, y0, x1, y1 in lay.boxes.values():
        z[int(y0):int(math.ceil(y1)) + 1, int(x0):int(math.ceil(x1)) + 1] = False
    return float(z.mean())


@pytest.mark.parametrize("which", ["synthetic", "srtm1_japan"])
def test_orbit_terrain_covers_half_of_every_frame(tmp_path_factory, which):
    """Terrain (by the depth buffer, not counting what the overlay boxes hide) covers at
    least half of each of 8 orbit frames at 480×270."""
    t = (synth_store(tmp_path_factory, "fbm") if which == "synthetic"
         else real_store(tmp_path_factory, "srtm1_japan.tif"))
    lay = layout_for(t, SMALL)
    scene = TerrainScene(pyvista_plotter(SMALL, "none"), t)
    try:
        got = []
        for v in orbit_views(t, 8, SMALL, fit_rect=lay.free):
            scene.frame(v, 2.0)
            got.append(_visible_terrain(scene, lay))
    finally:
        scene.plotter.close()
    assert min(got) >= 0.5, [round(g, 3) for g in got]


@pytest.mark.fast
def test_ticks_are_nice_and_the_bar_spans_only_the_data():
    for lo, hi in ((0.0, 1668.0), (236.0, 1446.0), (-37.5, 812.0), (1009.2, 1265.7)):
        vals = [v for v, _ in _ticks(lo, hi)]
        assert len(vals) >= 3 and all(lo <= v <= hi for v in vals)
        step = vals[1] - vals[0]
        mant = step / 10 ** math.floor(math.log10(step))
        assert round(mant, 9) in (1.0, 2.0, 2.5, 5.0), (lo, hi, step)
        assert all(abs(v / step - round(v / step)) < 1e-9 for v in vals)
    # a sea of zeros (no depth in the data): the bar is the land's, the water a swatch
    _, (lo, hi) = colorbar_map(Palette("auto"), (0.0, 1668.0))
    assert (lo, hi) == (0.0, 1668.0)
    assert water_swatch(Palette("auto"), (0.0, 1668.0)) is not None
    # depths in the data: they are on the bar, no swatch
    _, (lo, hi) = colorbar_map(Palette("auto"), (-300.0, 500.0))
    assert (lo, hi) == (-300.0, 500.0)
    assert water_swatch(Palette("auto"), (-300.0, 500.0)) is None
    # no water at all
    assert water_swatch(Palette("auto"), (12.0, 500.0)) is None


def _darkest_shade() -> float:
    """The luminance of the darkest colour the default style can give a texel: the
    palette's darkest colour at the hillshade's floor."""
    cols = np.array([c for _, c in LAND + WATER])
    lum = 0.299 * cols[:, 0] + 0.587 * cols[:, 1] + 0.114 * cols[:, 2]
    return float(lum.min() * AMBIENT * 255)


@pytest.mark.parametrize("which", ["demo", "srtm1_japan"])
@pytest.mark.parametrize("aa", ["auto", "msaa"])
def test_default_pictures_have_no_dark_hairlines(tmp_path_factory, which, aa):
    """The default render (1280×720 overview) of the demo DEM and of srtm1_japan: no
    terrain pixel darker than the darkest shade of the palette (a black seam or hairline
    would be)."""
    if which == "demo":
        d = tmp_path_factory.mktemp("demo")
        t = geoterrain.open(geoterrain.preprocess(ROOT / "sample_dems" / "fbm_513.tif",
                                                  d / "fbm_513.geoterrain"))
    else:
        t = real_store(tmp_path_factory, "srtm1_japan.tif")
    v = overview(t, (1280, 720))
    scene = TerrainScene(pyvista_plotter(v.size, aa), t)
    try:
        img, _ = scene.frame(v)
        terrain = depth_buffer(scene.plotter) < 1.0
    finally:
        scene.plotter.close()
    rgb = img.astype(np.float64)
    lum = 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
    assert terrain.mean() > 0.3
    dark = terrain & (lum < _darkest_shade() - 1.0)
    assert int(dark.sum()) == 0, f"{int(dark.sum())} dark terrain pixels"


@pytest.mark.fast
def test_colour_bar_limits_are_the_datas(tmp_path_factory):
    t, z = topobathy(tmp_path_factory)
    lay = layout_for(t, (640, 360))
    lo, hi = elevation_range(t)
    assert lay.limits == (lo, hi)

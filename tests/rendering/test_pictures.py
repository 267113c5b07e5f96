"""Pictures a report-writer would publish: colours, the top-down camera, the north
arrow against the rendered picture, overlays that never cover terrain, orbits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain import lod
from geoterrain.core.view import View
from geoterrain.exceptions import UsageError
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering.cameras import default_view, interpolate_views, orbit_views
from geoterrain.rendering.colours import Palette, colorize
from geoterrain.rendering.overlays import compose, layout_for, north_direction, over
from geoterrain.rendering.scene import TerrainScene, overview
from geoterrain.rendering.textures import texture_image
from geoterrain.rendering.window import pyvista_plotter
from tests.rendering.test_render import _cli, real_store, synth_store

_STORES: dict = {}


def array_store(tmp_path_factory, name, z, spacing=10.0):
    if name not in _STORES:
        d = tmp_path_factory.mktemp(name)
        dem = write_geotiff(d / f"{name}.tif", z.astype(np.float32), crs="EPSG:32633",
                            origin=(500000.0, 5000000.0), spacing=spacing)
        _STORES[name] = geoterrain.preprocess(dem, d / f"{name}.geoterrain")
    return geoterrain.open(_STORES[name])


def topobathy(tmp_path_factory):
    z = generate("fbm", 257, seed=3, relief=800.0) - 300.0  # a third or so under the sea
    return array_store(tmp_path_factory, "topobathy", z), z


def _render(t, view, palette="auto", shading="normals", strategy="rtin", selection=None):
    """(image, terrain mask from the depth buffer)."""
    scene = TerrainScene(pyvista_plotter(view.size), t, shading, palette)
    try:
        if selection is None:
            img, _ = scene.frame(view, 1.0, strategy)
        else:
            scene.update(selection)
            scene.set_camera(view)
            scene.plotter.render()
            img = np.asarray(scene.plotter.screenshot(return_img=True))[..., :3]
        depth = scene.plotter.get_image_depth(fill_value=np.nan)
    finally:
        scene.plotter.close()
    return img, np.isfinite(np.asarray(depth))


# ------------------------------------------------------------------------ colour
@pytest.mark.fast
def test_colorize_no_black_and_water_blue():
    h = np.linspace(-500, 3000, 2001)
    for p in (Palette(), Palette(water_level=0.0), Palette(water_level=120.0),
              Palette(clim=(0.0, 1000.0))):
        rgb = colorize(h, p, (-500.0, 3000.0))
        assert rgb.sum(-1).min() > 0.6  # no black anywhere
    rgb = colorize(h, Palette(), (-500.0, 3000.0))
    wet = h <= 0
    assert (rgb[wet, 2] > rgb[wet, 0] + 0.15).all()  # sea is blue
    assert (rgb[~wet, 2] < rgb[~wet, 0] + 0.15).all()  # land is not
    # --water-level: a lake level above 0 turns land below it into water
    rgb = colorize(h, Palette(water_level=120.0), (-500.0, 3000.0))
    assert (rgb[h <= 120, 2] > rgb[h <= 120, 0] + 0.15).all()
    # a land-only DEM gets no water at all
    rgb = colorize(np.linspace(150, 300, 50), Palette(), (150.0, 300.0))
    assert (rgb[:, 2] < rgb[:, 0] + 0.15).all()


@pytest.mark.fast
def test_palette_rejects_bad_input():
    with pytest.raises(UsageError, match="viridis"):
        Palette("not_a_map")
    with pytest.raises(UsageError, match="MIN < MAX"):
        Palette(clim=(5.0, 1.0))


def _coast_check(t, tex):
    g = t.grid
    L = 0
    h = np.full(g.level_shape(L), np.nan)  # either layout (srtm1_japan: a 1 × 1 root)
    step, T = 1 << g.t, g.tile_samples
    for (lv, x, y) in t.tile_keys(L):
        h[y * step:y * step + T, x * step:x * step + T] = t.tile(lv, x, y).heights
    h *= t.frame.z_to_m
    ok = np.isfinite(h)
    tex = tex.astype(np.int32)
    assert tex[ok].sum(-1).min() > 60, "a black pixel on land or sea"
    wet = ok & (h <= 0)
    land = ok & (h > 0)
    assert wet.any() and land.any()
    blue = tex[..., 2] > tex[..., 0] + 20
    # coastline: along every land/sea edge the two sides fall in different colour classes
    edge = land[:, :-1] & wet[:, 1:]
    assert edge.any()
    agree = (blue[:, 1:][edge] & ~blue[:, :-1][edge]).mean()
    assert agree >= 0.99, agree


@pytest.mark.fast
def test_topobathy_texture_sea_blue_coast_visible(tmp_path_factory):
    t, _ = topobathy(tmp_path_factory)
    _coast_check(t, texture_image(t, "normals", "auto", level=0))


def test_srtm1_japan_sea_blue_coast_visible(tmp_path_factory):
    t = real_store(tmp_path_factory, "srtm1_japan.tif")
    _coast_check(t, texture_image(t, "normals", "auto", level=0))


@pytest.mark.fast
def test_cli_cmap_and_elevation_are_usage_errors(tmp_path_factory, tmp_path):
    from click.testing import CliRunner

    t = synth_store(tmp_path_factory, "fbm")
    cli = _cli()
    r = CliRunner().invoke(cli, ["render", str(t.path), "-o", str(tmp_path / "a.png"),
                                 "--cmap", "viridiss"])
    assert r.exit_code == 2 and "viridis" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli, ["render", str(t.path), "-o", str(tmp_path / "a.png"),
                                 "--elevation", "-10"])
    assert r.exit_code == 2 and "(0, 90]" in r.output, r.output
    r = CliRunner().invoke(cli, ["render", str(t.path), "-o", str(tmp_path / "a.png"),
                                 "--clim", "5,1"])
    assert r.exit_code == 2
    assert not (tmp_path / "a.png").exists()


# ------------------------------------------------------------------------ camera
SLOW = pytest.mark.slow


@pytest.mark.parametrize("az", [pytest.param(0, marks=SLOW), pytest.param(90, marks=SLOW),
                                235, 300])
def test_top_down_misses_no_tile(tmp_path_factory, az):
    """Straight down: rtin and bruteforce cover the pixels an un-culled full mesh covers."""
    t = synth_store(tmp_path_factory, "fbm")
    v = default_view(t, (480, 320), az, 90.0)
    _, full = _render(t, v, selection=lod.static(t, 0.0))
    counts = {s: _render(t, v, strategy=s)[1].sum() for s in ("rtin", "bruteforce")}
    n = full.sum()
    assert 0.2 * full.size < n < 0.98 * full.size  # uncropped: background on some side
    assert not (full[0].any() and full[-1].any() and full[:, 0].any() and full[:, -1].any())
    for s, c in counts.items():
        assert abs(c - n) <= 0.005 * n, (s, c, n)


@pytest.mark.fast
def test_top_down_up_is_well_defined():
    for az in (0.0, 90.0, 235.0, 300.0):
        v = View((0, 0, 1000), (0, 0, 0), tuple(np.array([-math.sin(math.radians(az)),
                                                          -math.cos(math.radians(az)), 0.0])))
        r, u, f = v.basis()
        assert abs(r @ u) < 1e-9 and abs(u @ f) < 1e-9 and np.allclose(u, v.up)


def _local_gradient(t, v):
    """Luminance gradient (x right, y down) of the rendered ramp around the image centre."""
    img, mask = _render(t, v, Palette("Greys_r"), shading="elevation")
    lum = img.astype(np.float64).mean(-1)
    W, H = v.size
    win = np.zeros_like(mask)
    win[H // 2 - 25:H // 2 + 26, W // 2 - 25:W // 2 + 26] = True
    ys, xs = np.nonzero(mask & win)
    assert len(xs) > 1000
    A = np.stack([xs, ys, np.ones_like(xs)], 1).astype(np.float64)
    gx, gy, _ = np.linalg.lstsq(A, lum[ys, xs], rcond=None)[0]
    return np.array([gx, gy]) / math.hypot(gx, gy)


@pytest.mark.parametrize("az,el", [(0, 90), (90, 90), (235, 90), (300, 90), (190, 40),
                                   (35, 25), (120, 60), (300, 15)])
def test_north_arrow_matches_the_picture(tmp_path_factory, az, el):
    """The arrow against the rendered picture (VTK's projection, not ours).

    Heights rising to the east draw meridians as isolines: north lies along the
    isoline through the view centre. Heights rising to the north say which way along it.
    """
    n = 129
    ramp = np.arange(n, dtype=np.float64)
    t_e = array_store(tmp_path_factory, "ramp_e", 100.0 + 2.0 * ramp[None, :] * np.ones((n, 1)))
    t_n = array_store(tmp_path_factory, "ramp_n", 100.0 + 2.0 * ramp[::-1, None] * np.ones((1, n)))
    v = default_view(t_e, (400, 300), az, el)
    g_e = _local_gradient(t_e, v)
    meridian = np.array([-g_e[1], g_e[0]])
    g_n = _local_gradient(t_n, v)
    seen = meridian if meridian @ g_n > 0 else -meridian
    d = north_direction(v)
    angle = math.degrees(math.acos(np.clip(seen @ d, -1, 1)))
    assert angle < 3.0, (az, el, angle, seen, d)


@pytest.mark.fast
def test_negative_elevation_refused(tmp_path_factory):
    t = synth_store(tmp_path_factory, "fbm")
    with pytest.raises(UsageError, match="look_from"):
        default_view(t, (320, 240), 190.0, -5.0)


# ------------------------------------------------------------------------ layout
@pytest.mark.parametrize("size", [(640, 480), (1280, 720),
                                  pytest.param((1920, 1080), marks=SLOW)])
def test_overlays_never_cover_terrain(tmp_path_factory, size):
    """A flat one-colour terrain: no terrain pixel under an overlay box; text inside boxes."""
    z = np.full((129, 129), 50.0)
    t = array_store(tmp_path_factory, "flat", z)
    kw = dict(title="Flat land", shading="elevation")
    for az, el in ((190, 40), (35, 25), (120, 70)):
        v = overview(t, size, az, el, **kw)
        img, mask = _render(t, v, shading="elevation")
        lay = layout_for(t, size, **kw)
        assert set(lay.boxes) == {"title", "colorbar", "scale_bar", "north_arrow"}
        for name, (x0, y0, x1, y1) in lay.boxes.items():
            sub = mask[int(y0):int(math.ceil(y1)) + 1, int(x0):int(math.ceil(x1)) + 1]
            assert not sub.any(), (size, az, el, name, int(sub.sum()))
        ext: dict = {}
        out = compose(img, v, t, shading="elevation", title="Flat land", extents=ext)
        for name, (x0, y0, x1, y1) in ext.items():
            bx0, by0, bx1, by1 = lay.boxes[name]
            assert bx0 <= x0 and x1 <= bx1 and by0 <= y0 and y1 <= by1, (name, ext[name])
        # boxes are opaque white: their insides show no terrain colour
        bx0, by0, bx1, by1 = (int(round(c)) for c in lay.boxes["north_arrow"])
        assert (out[by0 + 2, bx0 + 2] == 255).all()


@pytest.mark.fast
def test_overlays_leave_the_picture_outside_their_boxes(tmp_path_factory):
    """compose blends the overlays over the picture: every pixel outside the boxes (with
    a 2-pixel margin for their anti-aliased edges) is the picture's, bit for bit."""
    t = synth_store(tmp_path_factory, "synth")
    v = overview(t, (640, 360), title="Noise")
    img = np.random.default_rng(3).integers(0, 256, (360, 640, 3), dtype=np.uint8)
    out = compose(img, v, t, title="Noise")
    inside = np.zeros((360, 640), bool)
    for x0, y0, x1, y1 in layout_for(t, (640, 360), title="Noise").boxes.values():
        inside[max(int(y0) - 2, 0):int(math.ceil(y1)) + 3,
               max(int(x0) - 2, 0):int(math.ceil(x1)) + 3] = True
    assert inside.any() and not inside.all()
    assert np.array_equal(out[~inside], img[~inside])
    assert (out[inside] != img[inside]).any()


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_over_is_rounded_porter_duff(seed):
    """``over`` against the float formula round((img·(255 − a) + rgb·a) / 255)."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (7, 9, 3), dtype=np.uint8)
    rgba = rng.integers(0, 256, (7, 9, 4), dtype=np.uint8)
    rgba[..., 3][rng.random((7, 9)) < 0.3] = 0
    rgba[..., 3][rng.random((7, 9)) < 0.2] = 255
    a = rgba[..., 3:4].astype(np.float64)
    ref = np.floor((img * (255 - a) + rgba[..., :3] * a) / 255 + 0.5)
    assert np.array_equal(over(img, rgba), ref.astype(np.uint8))


@pytest.mark.fast
def test_over_refuses_what_it_cannot_blend():
    img = np.zeros((4, 5, 3), np.uint8)
    with pytest.raises(ValueError, match="overlay must be"):
        over(img, np.zeros((4, 4, 4), np.uint8))  # a canvas a pixel narrower
    with pytest.raises(ValueError, match="picture must be"):
        over(img.astype(np.float32), np.zeros((4, 5, 4), np.uint8))


@pytest.mark.fast
@pytest.mark.parametrize("size", [(960, 540), pytest.param((1280, 720), marks=SLOW)])
def test_default_view_fills_the_frame(tmp_path_factory, size):
    """The default overview (azimuth 190, elevation 40) fills ≥ 40 % of the frame; a low
    diagonal view (35, 25: a diamond in its box) still fills ≥ 30 % (29 % before)."""
    t = synth_store(tmp_path_factory, "fbm")
    for az, el, least in ((190, 40, 0.40), (35, 25, 0.30)):
        _, mask = _render(t, overview(t, size, az, el))
        assert mask.mean() >= least, (size, az, el, mask.mean())


@pytest.mark.fast
def test_orbit_keeps_its_distance(tmp_path_factory):
    t = synth_store(tmp_path_factory, "fbm")
    lay = layout_for(t, (320, 240))
    vs = orbit_views(t, 12, (320, 240), 190.0, 35.0, fit_rect=lay.free)
    d = [np.linalg.norm(v.eye - np.asarray(v.look_at)) for v in vs]
    assert max(d) - min(d) < 1e-6 * max(d)
    assert len({v.look_at for v in vs}) == 1


@pytest.mark.fast
def test_interpolated_path_is_smooth():
    keys = [View((0, -1000, 500), (0, 0, 0)), View((1000, 0, 600), (0, 0, 0)),
            View((0, 1000, 400), (0, 0, 100)), View((-800, 0, 700), (0, 0, 0))]
    vs = interpolate_views(keys, 9)
    assert len(vs) == 3 * 10 + 1
    assert [vs[10 * k].look_from for k in range(4)] == [k.look_from for k in keys]
    E = np.array([v.look_from for v in vs])
    step = np.linalg.norm(np.diff(E, axis=0), axis=1)
    # eased: slow at each keyframe, no jump anywhere (no step > 3× the mean)
    assert step.max() < 3 * step.mean()
    assert step[0] < step[4] and step[9] < step[5]

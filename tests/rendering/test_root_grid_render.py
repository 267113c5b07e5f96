"""Rendering a store of rectangular root tiles (issue 45, ``preprocess --root-grid``): the
pictures of a wide raster preprocessed on its 2 × 1 root grid against those of the same
raster on the one padded square (PSNR, coverage), the frame's screen-space error measured
at every sample by :mod:`geoterrain.testing.measure` (independent of the selection), the
per-view atlas's footprints on a rectangle, the whole-level textures, the commands and the
viewer's controller."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.grid import Grid
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering.mapview import map_view
from geoterrain.testing.measure import screen_space_error
from tests.rendering.test_render import _cli, psnr
from tests.test_stress import REL, mesh_parts, z_roundoff

pytest.importorskip("pyvista")

from geoterrain.rendering.scene import TerrainScene, default_view, render_array  # noqa: E402
from geoterrain.rendering.window import pyvista_plotter  # noqa: E402

pytestmark = pytest.mark.fast
MIN_PSNR = 35.0  # dB, square against roots (the same heights, the same triangles)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 129 × 513 fBm (UTM, 10 m) preprocessed on the square (513², 32-sample tiles) and
    on its 2 × 1 root grid (129 × 513, the roots 257 × 513)."""
    d = tmp_path_factory.mktemp("rootrender")
    z = generate("fbm", 513, seed=3, relief=600.0)[:129, :513]
    dem = write_geotiff(d / "wide.tif", z, crs="EPSG:32633", origin=(500000.0, 5000000.0),
                        spacing=10.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32,
                                               root_grid=False))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert sq.grid.square and (rt.grid.layout, rt.grid.roots) == ("roots", (2, 1))
    return sq, rt, dem


def _views(t) -> dict[str, View]:
    size = (320, 180)
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    east = np.array([hi[0], c[1], c[2]])  # over the second root, low and close
    return {"overview": default_view(t, size), "map": map_view(t, size),
            "from above": default_view(t, size, azimuth=180.0, elevation=90.0),
            "east root, close": View(tuple(east + (-900.0, -700.0, 500.0)), tuple(east),
                                     size=size)}


def _pictures(sq, rt, view, **kw):
    (a, sa), (b, sb) = (render_array(t, view, **kw) for t in (sq, rt))
    return a, b, sa, sb


def test_root_grid_pictures_agree_with_the_square(pair):
    """The same views of the square and the root-grid store: the same picture within
    MIN_PSNR, the terrain covering the same share of it (the rtin meshes are the same
    triangles where the data is, the textures the same tiles' shading)."""
    sq, rt, _ = pair
    for name, view in _views(sq).items():
        a, b, sa, sb = _pictures(sq, rt, view)
        assert sb["triangles"] > 0 and b.std() > 10, name
        assert psnr(a, b) >= MIN_PSNR, (name, psnr(a, b))
        assert sa["terrain_fraction"] == sb["terrain_fraction"] > 0.05, name


def test_the_default_camera_frames_every_root(pair):
    """The overview's framing points come from every root tile: they span the data's
    box as the square's top tile does, and the default views frame alike."""
    from geoterrain.rendering.cameras import _coarse_points, project

    sq, rt, _ = pair
    lo, hi = rt.scene_box()
    for t in (sq, rt):
        p = _coarse_points(t)
        assert np.allclose(p[:, :2].min(0), lo[:2]) and np.allclose(p[:, :2].max(0), hi[:2])
    a, b = default_view(sq, (320, 180)), default_view(rt, (320, 180))
    for v in (a, b):  # the data's corners inside the picture
        px, depth = project(v, _coarse_points(rt))
        assert (depth > 0).all() and (px >= 0).all() and (px <= (320, 180)).all()
    assert np.linalg.norm(np.subtract(a.look_from, b.look_from)) < \
        0.05 * np.linalg.norm(np.subtract(a.look_from, a.look_at))


def test_styles_on_a_root_grid(pair):
    """Elevation colours, the sun with shadows and ambient occlusion (each tile's window
    reaching into the other root's tiles), triangle strips (the seed's order root by root)
    and the whole-level texture (a rectangle of the level's shape)."""
    from geoterrain.rendering.shading import Light

    sq, rt, _ = pair
    view = _views(sq)["overview"]
    for kw in ({"shading": "elevation"}, {"strips": True},
               {"light": Light(azimuth=250.0, elevation=20.0, shadows=True,
                               ambient_occlusion=True)}):
        a, b, sa, sb = _pictures(sq, rt, view, **kw)
        assert psnr(a, b) >= MIN_PSNR, (kw, psnr(a, b))
        assert sa["terrain_fraction"] == sb["terrain_fraction"], kw
    imgs = []
    for t in (sq, rt):
        scene = TerrainScene(pyvista_plotter(view.size), t, textures="global")
        try:
            imgs.append(render_array(t, view, scene=scene)[0])
        finally:
            scene.plotter.close()
    assert psnr(*imgs) >= MIN_PSNR


def test_the_shadows_reach_comes_from_the_highest_root(tmp_path):
    """The cast shadows' reach starts from the highest stored height: on a root grid, the
    highest of the roots' boxes (here the peak lies in the second root)."""
    from conftest import write_tif
    from geoterrain.rendering.shading import _highest

    z = np.zeros((33, 65), np.int16)
    z[10, 50] = 900  # the peak, in the east root
    t = geoterrain.open(geoterrain.preprocess(write_tif(tmp_path / "p.tif", z, dtype="int16"),
                                              tmp_path / "p.geoterrain", tile_size=8,
                                              root_grid=True))
    assert t.grid.roots == (2, 1)
    assert _highest(t) == max(i["zmax"] for i in t.tile_info.values()) > 0


def test_the_frames_screen_error_is_within_tau_on_a_root_grid(pair):
    """ρ ≤ τ at every valid sample in the frustum of the mesh each frame drew (the
    scene's selection, without horizon culling), measured by testing.measure on the
    store's own heights, with geomorphing off and on."""
    _, rt, _ = pair
    X, Y, Z = rt.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    views = _views(rt)
    for morph in (False, True):
        scene = TerrainScene(pyvista_plotter((320, 180)), rt, occlusion=False, morph=morph)
        try:
            for name in ("overview", "east root, close", "from above"):
                for tau in (1.0, 4.0):
                    view = views[name].clipped_to(*rt.scene_box())  # as the frame does
                    scene.frame(view, tau, "rtin")
                    ij, faces, vz = mesh_parts(scene.selection)
                    e = screen_space_error(ij, faces, vz, X, Y, Zt, valid, view.eye,
                                           view.planes, view.lam)
                    d = np.sqrt(((np.stack([X, Y, Zt], -1) - view.eye) ** 2).sum(-1))
                    slack = view.lam * z_roundoff(Z) / float(d[valid].min())
                    assert e.n_samples > 0, name
                    assert e.max <= tau * (1 + REL) + slack, (name, tau, morph, e.max)
        finally:
            scene.plotter.close()


def test_render_orbit_and_map_commands_on_a_root_grid(pair, tmp_path):
    import imageio.v3 as iio
    from click.testing import CliRunner

    _, rt, _ = pair
    run, cli = CliRunner(), _cli()
    out = tmp_path / "o.gif"
    res = run.invoke(cli, ["-q", "render", str(rt.path), "--orbit", "3", "-o", str(out),
                           "--size", "160x90"])
    assert res.exit_code == 0, res.output
    frames = iio.imread(out, index=None)
    assert frames.shape[:3] == (3, 90, 160) and frames.reshape(3, -1).std(1).min() > 5
    png = tmp_path / "m.png"
    res = run.invoke(cli, ["-q", "render", str(rt.path), "--map", "-o", str(png),
                           "--size", "320x180", "--title", "wide"])
    assert res.exit_code == 0, res.output
    assert iio.imread(png).shape[:2] == (180, 320)


def test_viewer_controller_on_a_root_grid(pair):
    """The interactive controller without a display: it draws, follows the camera, and
    its strategy key cycles through every strategy, each drawing the root grid."""
    from geoterrain.lod.registry import STRATEGIES
    from geoterrain.rendering.viewer import ViewerController

    _, rt, _ = pair
    p = pyvista_plotter((320, 180))
    try:
        c = ViewerController(p, rt, throttle_ms=0.0)
        c.bind()
        n0 = c.selections
        lo, hi = np.asarray(c.home.look_at), np.asarray(c.home.look_from)
        p.camera.position = tuple(lo + 0.4 * (hi - lo))
        assert c.selections > n0 and c.scene.mesh.n_cells == c.stats["triangles"] > 0
        seen = set()
        for _ in range(len(STRATEGIES)):
            c.next_strategy()
            seen.add(c.strategy)
            assert c.stats["triangles"] > 0, c.strategy
        assert seen == set(STRATEGIES)
    finally:
        p.close()


def test_whole_level_texture_and_drape_have_the_levels_shape(pair, tmp_path):
    """The whole-level texture and a drape cover the level's rectangle on a root grid,
    and equal the square's over it (the square's texture holds the same tiles)."""
    import rasterio
    from rasterio.transform import from_bounds

    from geoterrain.rendering.drape import drape_image
    from geoterrain.rendering.textures import build_texture_image

    sq, rt, _ = pair
    for L in (0, 2):
        a, b = (build_texture_image(t, "normals", level=L) for t in (sq, rt))
        R, C = rt.grid.level_shape(L)
        assert b.shape == (R, C, 3) and np.array_equal(a[:R, :C], b)
    f = rt.frame
    ta, _, c0, _, te, top = f.transform
    box = (c0, top + te * rt.grid.rows, c0 + ta * rt.grid.cols, top)
    p = tmp_path / "ortho.tif"
    ramp = np.broadcast_to(np.linspace(0, 255, 64).astype(np.uint8), (3, 16, 64))
    with rasterio.open(p, "w", driver="GTiff", width=64, height=16, count=3, dtype="uint8",
                       crs=f.crs_wkt, transform=from_bounds(*box, 64, 16)) as dst:
        dst.write(np.ascontiguousarray(ramp))
    a, b = drape_image(sq, p, 1), drape_image(rt, p, 1)
    R, C = rt.grid.level_shape(1)
    assert b.shape == (R, C, 3) and np.array_equal(a[:R, :C], b)


@settings(max_examples=60, deadline=None)
@given(st.integers(3, 200), st.integers(3, 200), st.sampled_from([2, 4, 8]), st.data())
def test_atlas_footprint_is_the_smallest_tile_of_the_grid_holding_a_face(rows, cols, ts,
                                                                         data):
    """On any root grid: the footprint is a tile of ``grid.tiles(L)`` holding the face, and
    no tile one level finer holds it (brute force over that level's tiles)."""
    from geoterrain.rendering.tiletextures import footprints

    g = Grid.for_shape(rows, cols, ts, roots=True)
    R, C = g.shape
    k = data.draw(st.integers(0, g.t + 1))  # corners on a 2^k lattice, like a mesh's
    pts = data.draw(st.lists(st.tuples(st.integers(0, (R - 1) >> k),
                                       st.integers(0, (C - 1) >> k)), min_size=3, max_size=3))
    ij = np.array(pts, np.int64) << k
    L, X, Y = (int(a[0]) for a in footprints(ij, np.array([[0, 1, 2]]), g))
    top = g.top_level
    s = g.tile_span(top)
    if not any(ij[:, 1].min() >= x * s and ij[:, 1].max() <= (x + 1) * s
               and ij[:, 0].min() >= y * s and ij[:, 0].max() <= (y + 1) * s
               for y in range(g.roots[1]) for x in range(g.roots[0])):
        assert (L, X, Y) == (top, 0, 0)  # across two roots (no rtin face is): the default
        return
    w = g.tile_span(L)
    held = [(x, y) for y in range(g.tiles(L)[1]) for x in range(g.tiles(L)[0])
            if ij[:, 1].min() >= x * w and ij[:, 1].max() <= (x + 1) * w
            and ij[:, 0].min() >= y * w and ij[:, 0].max() <= (y + 1) * w]
    assert (X, Y) in held
    if L > 0:
        w2 = g.tile_span(L - 1)
        tx, ty = g.tiles(L - 1)
        assert not any(ij[:, 1].min() >= x * w2 and ij[:, 1].max() <= (x + 1) * w2
                       and ij[:, 0].min() >= y * w2 and ij[:, 0].max() <= (y + 1) * w2
                       for y in range(ty) for x in range(tx))


@pytest.fixture(scope="module")
def geo_pair(tmp_path_factory):
    """A 129 × 513 fBm in EPSG:4326 (0.002° at 61–61.26° N, a void of nodata) on the
    square (513², 32-sample tiles) and on its 2 × 1 root grid: the scene is placed by the
    frame's azimuthal-equidistant x, y, curved on both."""
    d = tmp_path_factory.mktemp("georootrender")
    z = generate("fbm", 513, seed=3, relief=600.0)[:129, :513].astype(np.float32)
    z[40:52, 300:330] = -9999.0
    dem = write_geotiff(d / "geo.tif", z, crs="EPSG:4326", origin=(10.0, 61.26),
                        spacing=0.002, nodata=-9999.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32,
                                               root_grid=False))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert rt.frame.kind == sq.frame.kind == "geographic"
    assert sq.grid.square and (rt.grid.layout, rt.grid.roots) == ("roots", (2, 1))
    return sq, rt, dem


def test_geographic_root_grid_pictures_agree_with_the_square(geo_pair):
    """A geographic root grid renders the square's pictures (the overview, the map with
    its graticule of meridians and parallels, straight down, close over the east root):
    the same frame placement (scene box, framing), PSNR ≥ MIN_PSNR, the same coverage."""
    sq, rt, _ = geo_pair
    a, b = sq.scene_box(), rt.scene_box()
    assert np.allclose(a[0][:2], b[0][:2]) and np.allclose(a[1][:2], b[1][:2])
    for name, view in _views(sq).items():
        x, y, sa, sb = _pictures(sq, rt, view)
        assert sb["triangles"] > 0 and y.std() > 10, name
        assert psnr(x, y) >= MIN_PSNR, (name, psnr(x, y))
        assert sa["terrain_fraction"] == sb["terrain_fraction"] > 0.05, name


def test_the_frames_screen_error_on_a_geographic_root_grid(geo_pair):
    """ρ ≤ τ at every valid sample in the frustum of the frame's own mesh on the
    geographic root grid (no horizon culling), measured in the scene's curvilinear x, y
    by testing.measure on the store's own heights."""
    _, rt, _ = geo_pair
    X, Y, Z = rt.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    views = _views(rt)
    scene = TerrainScene(pyvista_plotter((320, 180)), rt, occlusion=False)
    try:
        for name in ("overview", "east root, close", "from above"):
            view = views[name].clipped_to(*rt.scene_box())  # as the frame does
            scene.frame(view, 1.0, "rtin")
            ij, faces, vz = mesh_parts(scene.selection)
            e = screen_space_error(ij, faces, vz, X, Y, Zt, valid, view.eye, view.planes,
                                   view.lam)
            d = np.sqrt(((np.stack([X, Y, Zt], -1) - view.eye) ** 2).sum(-1))
            slack = view.lam * z_roundoff(Z) / float(d[valid].min())
            assert e.n_samples > 0, name
            assert e.max <= 1.0 * (1 + REL) + slack, (name, e.max)
    finally:
        scene.plotter.close()

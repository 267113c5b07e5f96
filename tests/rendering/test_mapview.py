"""The map view (`render --map`): orthographic and north up, one scale everywhere (the scale
bar's), the whole DEM framed, and its grid labelled in the DEM's own coordinates: checked
through the camera VTK drew with and pyproj, not through the map's own code."""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner
from pyproj import Transformer

import geoterrain
from geoterrain.ingest.synth import generate
from geoterrain.rendering.cameras import project
from geoterrain.rendering.mapgrid import grid_lines, map_rect
from geoterrain.rendering.mapview import map_layout, map_view
from geoterrain.rendering.overlays import north_direction
from geoterrain.rendering.scene import TerrainScene, render
from geoterrain.rendering.window import pyvista_plotter
from tests.conftest import write_tif

SIZE = (640, 360)
_STORES: dict = {}


def _store(tmp_path_factory, kind: str):
    if kind not in _STORES:
        d = tmp_path_factory.mktemp(f"map_{kind}")
        z = generate("fbm", (81, 97), seed=9, base=-200.0, relief=900.0).astype(np.float32)
        if kind == "utm":
            dem = write_tif(d / "utm.tif", z, spacing=100.0)
        else:  # 3″ at 35° N
            dem = write_tif(d / "geo.tif", z, crs="EPSG:4326", origin=(139.0, 35.5),
                            spacing=3 / 3600)
        _STORES[kind] = geoterrain.preprocess(dem, d / f"{kind}.geoterrain")
    return geoterrain.open(_STORES[kind])


def _world_to_display(plotter, pts: np.ndarray) -> np.ndarray:
    """Picture coordinates (x right, y down; 0 at the left and top edges) of world points,
    by VTK's own camera."""
    ren = plotter.renderer
    h = plotter.render_window.GetSize()[1]
    out = []
    for p in pts:
        ren.SetWorldPoint(*p, 1.0)
        ren.WorldToDisplay()
        x, y, _ = ren.GetDisplayPoint()
        out.append((x, h - y))  # continuous: 0 at the left and top edges
    return np.array(out)


@pytest.mark.parametrize("kind", ["utm", "geo"])
def test_map_is_orthographic_north_up_and_framed(tmp_path_factory, kind):
    t = _store(tmp_path_factory, kind)
    v = map_view(t, SIZE)
    d = north_direction(v)
    assert np.allclose(d, (0.0, -1.0), atol=1e-9)  # north is straight up the picture
    _, (x0, y0, x1, y1) = map_layout(t, SIZE)
    mx0, my0, mx1, my1 = map_rect(t, v)
    # the data's rectangle fills the map's room along one side and fits in it
    assert mx0 >= x0 - 0.5 and my0 >= y0 - 0.5 and mx1 <= x1 + 0.5 and my1 <= y1 + 0.5
    assert max((mx1 - mx0) / (x1 - x0), (my1 - my0) / (y1 - y0)) > 0.999
    scene = TerrainScene(pyvista_plotter(SIZE, "msaa"), t)
    try:
        scene.frame(v)
        lo, hi = t.scene_box()
        z = float(v.look_at[2])
        # one scale at every point: 1 km east and 1 km north measure alike everywhere, in
        # VTK's parallel projection, and as much as the overlays' projection says
        pts = []
        for x in np.linspace(lo[0], hi[0] - 1000.0, 3):
            for y in np.linspace(lo[1], hi[1] - 1000.0, 3):
                for zz in (lo[2], hi[2]):  # at any height: parallel
                    pts += [(x, y, zz), (x + 1000.0, y, zz), (x, y + 1000.0, zz)]
        px = _world_to_display(scene.plotter, np.array(pts)).reshape(-1, 3, 2)
        east = np.linalg.norm(px[:, 1] - px[:, 0], axis=1)
        north = np.linalg.norm(px[:, 2] - px[:, 0], axis=1)
        ref, _ = project(v, np.array([[lo[0], lo[1], z], [lo[0] + 1000.0, lo[1], z]]))
        bar = float(np.linalg.norm(ref[1] - ref[0]))  # the scale bar's pixels per km
        assert np.allclose(east, bar, rtol=1e-6) and np.allclose(north, bar, rtol=1e-6)
        # the overlays' projection puts the data's corners where VTK draws them
        corners = np.array([[lo[0], lo[1], z], [hi[0], hi[1], z]])
        got = _world_to_display(scene.plotter, corners)
        want, _ = project(v, corners)
        assert np.abs(got - want).max() < 0.05
    finally:
        scene.plotter.close()


@pytest.mark.fast
def test_projected_grid_is_round_eastings_and_northings(tmp_path_factory):
    t = _store(tmp_path_factory, "utm")
    v = map_view(t, SIZE)
    lines = grid_lines(t, v)
    east = [ln for ln in lines if ln.side == "bottom"]
    north = [ln for ln in lines if ln.side == "left"]
    assert len(east) >= 3 and len(north) >= 3
    for ln in east + north:
        value = float(ln.label.replace(",", ""))
        assert value % 500 == 0  # round values of the CRS's metres
    # an easting's line is straight up the picture, at the easting's place
    f = t.frame
    for ln in east:
        x = float(ln.label.replace(",", ""))
        sx, _ = f.crs_to_scene(np.array([x]), np.array([f.origin_crs[1]]))
        (p,), _ = project(v, np.array([[sx[0], 0.0, v.look_at[2]]]))
        assert np.ptp(ln.px[:, 0]) < 1e-6 and abs(ln.at - p[0]) < 1e-6


def test_graticule_of_a_geographic_dem(tmp_path_factory):
    """Meridians meet the map's bottom edge where pyproj, from the camera VTK drew with,
    says their longitude is; labels in degrees and minutes."""
    t = _store(tmp_path_factory, "geo")
    v = map_view(t, SIZE)
    lines = grid_lines(t, v)
    mer = [ln for ln in lines if ln.side == "bottom"]
    par = [ln for ln in lines if ln.side == "left"]
    assert mer and par
    assert all(re.fullmatch(r"\d+°\d\d′E", ln.label) for ln in mer)
    assert all(re.fullmatch(r"\d+°\d\d′N", ln.label) for ln in par)
    _, _, _, y1 = map_rect(t, v)
    scene = TerrainScene(pyvista_plotter(SIZE, "none"), t)
    try:
        scene.frame(v)
        ren = scene.plotter.renderer
        h = scene.plotter.render_window.GetSize()[1]
        to_geo = Transformer.from_crs(t.frame.aeqd_wkt, "EPSG:4326", always_xy=True)
        for ln in mer:
            ren.SetDisplayPoint(ln.at, h - y1, 0.5)
            ren.DisplayToWorld()
            wx, wy, _, w = ren.GetWorldPoint()
            lon, _ = to_geo.transform(wx / w, wy / w)
            deg, mins = re.fullmatch(r"(\d+)°(\d\d)′E", ln.label).groups()
            assert lon == pytest.approx(int(deg) + int(mins) / 60, abs=1e-6)
    finally:
        scene.plotter.close()


def test_render_map_cli(tmp_path_factory, tmp_path):
    import imageio.v3 as iio

    from geoterrain.cli.main import cli

    t = _store(tmp_path_factory, "utm")
    out = tmp_path / "map.png"
    res = CliRunner().invoke(cli, ["-q", "render", str(t.path), "-o", str(out), "--map",
                                   "--size", "480x270"])
    assert res.exit_code == 0, res.output
    img = iio.imread(out)
    assert img.shape[:2] == (270, 480)
    v = map_view(t, (480, 270))
    x0, y0, x1, y1 = (int(round(c)) for c in map_rect(t, v))
    # the neat line: dark along the frame's left edge
    assert img[y0 + 5:y1 - 5, x0, :3].mean() < 90
    for bad in (["--elevation", "30"], ["--orbit", "4"], ["--look-from", "0,0,1000",
                                                         "--look-at", "0,0,0"]):
        res = CliRunner().invoke(cli, ["render", str(t.path), "-o", str(tmp_path / "x.png"),
                                       "--map", *bad])
        assert res.exit_code == 2 and "--map" in res.stderr, bad


def test_map_render_with_water_has_no_land_under_it(tmp_path_factory, tmp_path):
    """From straight above the water is drawn over the terrain's mesh whatever its height:
    it must still end at the shore, so no pixel of dry land (by the DEM) is water-blue."""
    import imageio.v3 as iio

    t = _store(tmp_path_factory, "utm")
    v = map_view(t, SIZE, colorbar=False, scale_bar=False, north_arrow=False)
    render(t, v, tmp_path / "m.png", colorbar=False, scale_bar=False, north_arrow=False)
    img = iio.imread(tmp_path / "m.png").astype(float)
    water = (img[..., 2] - img[..., 0]) > 0.1 * img[..., :3].sum(-1)
    assert water.mean() > 0.05
    h, valid = t.level_heights(0)
    g = t.grid
    x0, y0, x1, y1 = map_rect(t, v)
    ys, xs = np.mgrid[0:SIZE[1], 0:SIZE[0]]
    inside = (xs > x0 + 2) & (xs < x1 - 2) & (ys > y0 + 2) & (ys < y1 - 2)
    # picture pixel → DEM sample (nearest), by the map's rectangle: x east, y south
    j = np.clip(np.round((xs - x0) / (x1 - x0) * (g.cols - 1)).astype(int), 0, g.cols - 1)
    i = np.clip(np.round((ys - y0) / (y1 - y0) * (g.rows - 1)).astype(int), 0, g.rows - 1)
    high = inside & (h[i, j] * t.frame.z_to_m > 60.0)  # clearly dry land
    assert high.sum() > 1000
    assert water[high].mean() < 0.001

"""`render --globe` and `view --globe`: a whole-globe store (refused by the flat scene) and a
regional one drawn on one globe from the command line; the viewer driven offscreen."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from geoterrain.cli.main import cli
from tests.conftest import write_tif


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """A whole-globe store (2° cells) and a regional one (160² cells of 0.01°, the Alps)."""
    import geoterrain

    d = tmp_path_factory.mktemp("globecli")
    lat = np.radians(89 - 2 * np.arange(90))[:, None]
    lon = np.radians(-179 + 2 * np.arange(180))[None, :]
    z = (2000 * np.sin(3 * lon) * np.cos(2 * lat) + 500 * np.cos(lat)).astype(np.float32)
    world = geoterrain.preprocess(
        write_tif(d / "world.tif", z, crs="EPSG:4326", origin=(-180.0, 90.0), spacing=2.0),
        d / "world.geoterrain")
    yy, xx = np.mgrid[0:160, 0:160] / 160.0
    alps = (1500 + 1200 * np.sin(6 * xx) * np.cos(5 * yy)).astype(np.float32)
    region = geoterrain.preprocess(
        write_tif(d / "alps.tif", alps, crs="EPSG:4326", origin=(10.0, 46.5), spacing=0.01),
        d / "alps.geoterrain")
    return d, str(world), str(region)


def _one_line(res, code):
    assert res.exit_code == code, res.output
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in res.output, res.stderr
    return err[0]


def test_the_flat_refusal_names_globe_and_render_globe_draws_it(stores):
    d, world, region = stores
    r = CliRunner()
    line = _one_line(r.invoke(cli, ["render", world, "-o", str(d / "flat.png")]), 1)
    assert "--globe" in line
    out, st = d / "earth.png", d / "earth.json"
    res = r.invoke(cli, ["-q", "render", "--globe", world, region, "-o", str(out),
                         "--size", "160x120", "--title", "Earth", "--stats", str(st)])
    assert res.exit_code == 0, res.output
    import imageio.v3 as iio

    img = iio.imread(out)
    assert img.shape == (120, 160, 3)
    stats = json.loads(st.read_text())
    assert stats["triangles"] > 0 and len(stats["stores"]) == 2
    # the planet fills the middle of the default framing: not the white background
    assert (img[50:70, 60:100] < 250).any(-1).mean() > 0.9


def test_camera_option_heading_pitch_and_the_underground_warning(stores):
    d, world, region = stores
    r = CliRunner()
    out = d / "low.png"
    res = r.invoke(cli, ["render", "--globe", world, region, "-o", str(out), "--size",
                         "96x64", "--camera", "10.3,46.2,-500,90,-10"])
    assert res.exit_code == 0, res.output
    warn = [s for s in res.stderr.splitlines() if s.startswith("warning")]
    assert len(warn) == 1 and "under the ground" in warn[0], res.stderr
    res = r.invoke(cli, ["render", "--globe", world, region, "-o", str(out), "--overwrite",
                         "--size", "16x16", "--camera", "10.3,46.2,9000,90,-10"])
    assert res.exit_code == 0 and "under the ground" not in res.stderr, res.output


@pytest.mark.parametrize("args, words", [
    (["--camera", "10,46,1000"], "--globe"),  # a geodetic camera without the globe
    (["STORE2"], "--globe"),  # two stores on the flat scene
    (["--globe", "--orbit", "4"], "--orbit"),  # flat-only options are named
    (["--globe", "--camera", "10,95,1000"], "latitude"),
    (["--globe", "--camera", "10,46"], "3 to 5 numbers"),
])
def test_bad_globe_command_lines_are_one_line_usage_errors(stores, args, words):
    d, world, region = stores
    args = [region if a == "STORE2" else a for a in args]
    out = d / "bad.png"
    res = CliRunner().invoke(cli, ["render", region, *args, "-o", str(out)])
    assert words in _one_line(res, 2)
    assert not out.exists()


def test_view_globe_without_a_display_says_so(stores, monkeypatch):
    d, world, region = stores
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    res = CliRunner().invoke(cli, ["view", "--globe", world, region])
    assert "render --globe" in _one_line(res, 1)
    res = CliRunner().invoke(cli, ["view", "--globe", world, "--strategy", "rtin"])
    assert "--strategy" in _one_line(res, 2)


def test_globe_viewer_offscreen_follows_the_camera_with_a_floating_origin(stores):
    import pyvista as pv

    from geoterrain.globe import Globe
    from geoterrain.rendering.globeviewer import GlobeViewerController

    d, world, region = stores
    g = Globe([world, region], sync=True, node_cells=16)
    p = pv.Plotter(off_screen=True, window_size=(160, 120))
    try:
        c = GlobeViewerController(p, g, g.default_view((160, 120)))
        c.bind()
        n0, tris0 = c.selections, c.stats["triangles"]
        assert tris0 > 0 and c.mesh.n_cells == tris0
        # fly down to 20 km over the Alps store: a new selection, finer nodes
        eye = g.camera(10.3, 46.2, 2.0e4, 0.0, -60.0, (160, 120))
        p.camera.position = tuple(np.asarray(eye.eye) - c.origin)
        assert c.selections > n0
        # the floating origin is the new eye: the camera is back at (0, 0, 0)
        assert np.allclose(c.origin, eye.eye, atol=1e-6)
        assert np.allclose(p.camera.position, 0.0)
        for _ in range(50):  # payloads arriving: the poll selects again until settled
            if not c.poll():
                break
        lon, lat, h = c.geodetic()
        assert abs(lon - 10.3) < 1e-6 and abs(lat - 46.2) < 1e-6 and abs(h - 2e4) < 1e-3
        assert c.stats["max_depth"] > 4
        c.toggle_freeze()
        n1 = c.selections
        p.camera.position = (1000.0, 0.0, 0.0)
        assert c.selections == n1  # frozen
        c.toggle_freeze()
        assert c.selections == n1 + 1
        for _ in range(50):  # settled: no payload pending
            if not c.poll():
                break
        tris = c.stats["triangles"]
        c.tau_up()
        assert c.pixel_error == 2.0 and c.stats["triangles"] <= tris
        c.toggle_wireframe()
        assert "camera" in c._hud.GetText(0)
        c.reset_view()
        assert np.allclose(c.origin, c.home.eye)
        c.screenshot(str(d / "shot.png"))
        assert (d / "shot.png").stat().st_size > 0
    finally:
        p.close()
        g.close()


def test_bench_globe_flies_seed_001s_flyover_and_reports_each_frame(stores):
    d, world, region = stores
    out = d / "fly.json"
    res = CliRunner().invoke(cli, ["bench", "--globe", region, "--flight-fps", "0.5",
                                   "--measure-every", "4", "--size", "160x90", "-o",
                                   str(out)])
    assert res.exit_code == 0, res.output
    assert "frame ms: median" in res.stdout and "selection:" in res.stdout
    rep = json.loads(out.read_text())
    frames, s = rep["frames"], rep["summary"]
    assert len(frames) == s["frames"] == 13  # 24 s of flight at 0.5 frames a second
    h = [f["height_m"] for f in frames]
    # the seed's phases: from outside the atmosphere down to the ground, then away again
    assert h[0] > 1e7 and min(h) < 5e3 and h[-1] > 1e7
    assert all(f["triangles"] > 0 and f["nodes"] > 0 for f in frames)
    assert s["rho_frames"] >= 1 and s["budget_ms"] == 2000.0
    assert 0 < s["selection_share_median"] < 1
    res = CliRunner().invoke(cli, ["bench", "--globe", region, "--strategies", "rtin"])
    assert "--strategies" in _one_line(res, 2)

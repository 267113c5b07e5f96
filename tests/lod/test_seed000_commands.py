"""Seed 000's strategies through every command: ``mesh``, ``render``, ``bench`` and the
interactive viewer (driven offscreen), on a synthetic DEM and on a real one.

Slow (each strategy builds its tables and draws pictures): run with ``-m slow``.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff
from tests.conftest import has_real_dem, real_dem

NEW = ("gtr", "gtr_bounded", "lauritsen_nielsen", "roam", "roam_split", "clipmap",
       "clipmap_bounded", "clipmap_gpu", "rottger")

pytestmark = pytest.mark.slow


def run(*args):
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module", params=["synthetic", "srtm3_pysheds.tif"])
def store(request, tmp_path_factory):
    d = tmp_path_factory.mktemp("cmd")
    if request.param == "synthetic":
        dem = write_geotiff(d / "s.tif", generate("fbm", 257, seed=3, relief=500.0))
    else:
        if not has_real_dem(request.param):
            pytest.skip("the real DEMs are not here")
        dem = real_dem(request.param)
    out = d / "t.geoterrain"
    assert run("-q", "preprocess", dem, "-o", out).exit_code == 0
    return out


def _camera(store):
    with geoterrain.open(store) as t:
        lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    eye = c + [0.0, -0.9 * (hi[1] - lo[1]), 0.5 * (hi[1] - lo[1]) + hi[2] - c[2]]
    return ",".join(f"{v:.3f}" for v in eye), ",".join(f"{v:.3f}" for v in c)


@pytest.mark.parametrize("strategy", NEW)
def test_mesh_render_and_bench(store, strategy, tmp_path):
    eye, at = _camera(store)
    r = run("-q", "mesh", store, "-o", tmp_path / "m.vtp", "--look-from", eye, "--look-at", at,
            "--pixel-error", 4, "--strategy", strategy, "--size", "480x270")
    assert r.exit_code == 0, r.output
    import pyvista as pv

    assert pv.read(tmp_path / "m.vtp").n_cells > 0
    r = run("-q", "render", store, "-o", tmp_path / "r.png", "--look-from", eye, "--look-at",
            at, "--pixel-error", 4, "--strategy", strategy, "--size", "320x180")
    assert r.exit_code == 0, r.output
    from PIL import Image

    img = np.asarray(Image.open(tmp_path / "r.png"))
    assert img.shape[:2] == (180, 320) and img.std() > 1
    r = run("-q", "bench", store, "--strategies", strategy, "--views", 2, "--pixel-error", 4,
            "--size", "320x180", "--render", "--anti-aliasing", "msaa")
    assert r.exit_code == 0, r.output
    assert strategy in r.output


@pytest.mark.parametrize("strategy", NEW)
def test_the_viewer_draws_it_and_follows_a_move(store, strategy):
    from geoterrain.rendering import viewer
    from geoterrain.rendering.window import pyvista_plotter

    with geoterrain.open(store) as t:
        p = pyvista_plotter((320, 240))
        c = viewer.ViewerController(p, t, strategy, 4.0, background=True)
        try:
            c.bind()
            c.wait(timeout=120)
            assert c.scene.selection is not None and c.scene.selection.mesh.n_cells > 0
            lo, hi = np.asarray(c.home.look_at), np.asarray(c.home.look_from)
            first = c.scene.selection
            p.camera.position = tuple(lo + 0.5 * (hi - lo))
            while not c.poll():  # (as tests/rendering/test_render.py drives a move)
                c._future.result(120)
            c.wait(timeout=120)
            assert c.scene.selection is not first
            assert c.scene.selection.stats["strategy"] == strategy
        finally:
            c.close()
            p.close()

"""The picture measure's camera is the render's: the bound rtin keeps in pixels
(``tests/lod/test_picture_bound.py``) is measured through the projection VTK draws with."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering.scene import TerrainScene
from geoterrain.rendering.window import offscreen_plotter
from geoterrain.testing.measure import picture_coordinates


@pytest.mark.fast
def test_picture_coordinates_are_vtks_projection(tmp_path):
    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 65, seed=2))
    t = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "d.geoterrain"))
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    rng = np.random.default_rng(7)
    pts = lo + rng.random((500, 3)) * (hi - lo)
    for size, fov, eye in (((1280, 720), 45.0, (-300.0, -250.0, 400.0)),
                           ((640, 480), 30.0, (200.0, -600.0, 900.0)),
                           ((300, 500), 70.0, (10.0, 5.0, 700.0))):
        view = View(eye, tuple(c), fov_y_deg=fov, size=size).clipped_to(lo, hi)
        scene = TerrainScene(offscreen_plotter(size, "none"), t)
        try:
            scene.set_camera(view)
            cam = scene.plotter.camera
            m = cam.GetCompositeProjectionTransformMatrix(size[0] / size[1], -1, 1)
        finally:
            scene.plotter.close()
        M = np.array([[m.GetElement(r, k) for k in range(4)] for r in range(4)])
        h = M @ np.c_[pts, np.ones(len(pts))].T
        col, row = (h[0] / h[3] + 1) / 2 * size[0], (1 - h[1] / h[3]) / 2 * size[1]
        got_c, got_r, depth = picture_coordinates(*pts.T, view.look_from, view.look_at,
                                                  view.up, view.fov_y_deg, view.size)
        np.testing.assert_allclose(got_c, col, atol=1e-6 * size[0])
        np.testing.assert_allclose(got_r, row, atol=1e-6 * size[1])
        np.testing.assert_allclose(depth, (pts - view.eye) @ view.forward, rtol=1e-12)

"""Faces turned away from the eye: culled by the renderer where the eye is above the
terrain and inside its footprint (geoterrain.rendering.scene's BACKFACE_CULLING,
TerrainScene.cull_faces_turned_away), which is right because every selection winds its
faces counter-clockwise seen from above; it moves a picture only where a face turned away
tied with the one in front of it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain import lod
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering import scene as scene_mod
from geoterrain.rendering.scene import TerrainScene, default_view
from geoterrain.rendering.window import offscreen_plotter

SIZE = (320, 240)
# skirted and unskirted, regular and irregular triangulations
STRATEGIES = (
    "rtin",
    "bruteforce",
    "chunked",
    "geomipmap",
    "quadtree",
    "roam",
    "clipmap",
    "rottger",
    "gtr",
)


def _dem(tmp_path_factory, name, dem):
    d = tmp_path_factory.mktemp(name)
    tif = write_geotiff(
        d / f"{name}.tif", dem, crs="EPSG:32633", origin=(500000.0, 5000000.0), spacing=10.0
    )
    return geoterrain.preprocess(tif, d / f"{name}.geoterrain")


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return _dem(tmp_path_factory, "backface", generate("fbm", 129, seed=5, relief=400.0))


def _upward(sel) -> tuple[np.ndarray, np.ndarray]:
    """Each face's z of (b − a) × (c − a) (> 0: counter-clockwise seen from above) and
    whether it is a skirt face."""
    p = np.asarray(sel.parts.points)
    f = np.asarray(sel.parts.regular_faces).reshape(-1, 3)
    nz = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])[:, 2]
    skirt = np.asarray(sel.parts.cell_data.get("skirt", np.zeros(len(f), np.uint8))) != 0
    return nz, skirt


def _inside(t, fx: float, fy: float, up: float = 0.25) -> View:
    """A low, oblique view from above the terrain's top, inside its footprint (at the
    fractions fx, fy of its box), looking ahead and down."""
    lo, hi = t.scene_box()
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    eye = np.array(
        [lo[0] + fx * (hi[0] - lo[0]), lo[1] + fy * (hi[1] - lo[1]), hi[2] + up * (hi[2] - lo[2])]
    )
    at = eye + np.array([0.3 * ext, 0.2 * ext, -0.06 * ext])
    return View(tuple(eye), tuple(at), fov_y_deg=45.0, size=SIZE)


@pytest.mark.fast
@settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    az=st.floats(0, 360),
    el=st.floats(5, 85),
    dist=st.floats(0.3, 1.5),
    strategy=st.sampled_from(STRATEGIES),
)
def test_every_selection_winds_its_faces_counter_clockwise_from_above(
    store, az, el, dist, strategy
):
    with geoterrain.open(store) as t:
        home = default_view(t, SIZE, az, el)
        c, e = np.asarray(home.look_at), np.asarray(home.look_from)
        v = View(tuple(c + dist * (e - c)), tuple(c), fov_y_deg=30.0, size=SIZE)
        sel = lod.select(t, v, pixel_error=1.0, strategy=strategy)
        nz, skirt = _upward(sel)
    # the renderer culls by this winding: a face with its upward side away from the eye
    assert (nz[~skirt] > 0).all(), (strategy, int((nz[~skirt] <= 0).sum()))


@pytest.mark.fast
def test_faces_turned_away_are_culled_only_from_above_inside_and_without_skirts(store):
    with geoterrain.open(store) as t:
        sc = TerrainScene(offscreen_plotter(SIZE, "msaa"), t)

        def culled() -> bool:
            return bool(sc.actor.GetProperty().GetBackfaceCulling())

        try:
            sc.frame(_inside(t, 0.2, 0.3), 1.0, "rtin")
            assert culled()
            sc.frame(_inside(t, 0.2, 0.3), 1.0, "gtr")  # skirts: wound either way
            assert int(np.asarray(sc.selection.parts.cell_data["skirt"]).sum()) > 0
            assert not culled()
            sc.frame(default_view(t, SIZE, 330.0, 8.0), 1.0, "rtin")  # outside the footprint
            assert not culled()
            sc.frame(_inside(t, 0.5, 0.5, up=-0.2), 1.0, "rtin")  # below the highest point
            assert not culled()
            sc.frame(_inside(t, 0.6, 0.4), 1.0, "rtin")
            assert culled()
        finally:
            sc.plotter.close()


@pytest.mark.fast
def test_a_terrain_with_nodata_is_drawn_whole(tmp_path_factory):
    dem = generate("fbm", 129, seed=6, relief=300.0)
    dem[40:60, 50:80] = np.nan  # a hole: its rim's undersides can be seen through it
    with geoterrain.open(_dem(tmp_path_factory, "holed", dem)) as t:
        sc = TerrainScene(offscreen_plotter(SIZE, "msaa"), t)
        try:
            sc.frame(_inside(t, 0.2, 0.3), 1.0, "rtin")
            assert not sc.actor.GetProperty().GetBackfaceCulling()
        finally:
            sc.plotter.close()


def _pictures(t, views, cull: bool, monkeypatch, aa: str) -> list[np.ndarray]:
    monkeypatch.setattr(scene_mod, "BACKFACE_CULLING", cull)
    sc = TerrainScene(offscreen_plotter(SIZE, aa), t)
    try:
        return [sc.frame(v, 1.0, "rtin")[0] for v in views]
    finally:
        sc.plotter.close()


@pytest.mark.fast
@pytest.mark.parametrize("aa", ["auto", "msaa"])
def test_culling_moves_a_picture_only_where_faces_tied(store, monkeypatch, aa):
    """From above the terrain, inside its footprint, a face turned away lies behind one
    turned towards the eye: culling it moves only pixels where the two tied in the depth
    test (along silhouettes), and none from outside (nothing is culled there)."""
    with geoterrain.open(store) as t:
        inside = [_inside(t, fx, fy) for fx, fy in ((0.1, 0.1), (0.3, 0.2), (0.5, 0.4))]
        outside = [default_view(t, SIZE, az, el) for az, el in ((200, 35), (330, 8))]
        drawn = _pictures(t, inside + outside, False, monkeypatch, aa)
        culled = _pictures(t, inside + outside, True, monkeypatch, aa)
    for k, (a, b) in enumerate(zip(drawn, culled, strict=True)):
        moved = (a != b).any(-1)
        if k >= len(inside):
            assert not moved.any()
        else:
            assert moved.mean() <= 0.002, moved.sum()


@pytest.mark.fast
def test_triangle_strips_keep_the_winding_the_culling_reads(store, monkeypatch):
    """Strips (seed 002's triangle strips, ``strips=True``) are culled by the winding of
    their triangles as the renderer unrolls them: the lists' picture, culled alike."""
    with geoterrain.open(store) as t:
        views = [_inside(t, 0.2, 0.3), _inside(t, 0.5, 0.4)]
        lists = _pictures(t, views, True, monkeypatch, "none")
        sc = TerrainScene(offscreen_plotter(SIZE, "none"), t, strips=True)
        try:
            strips = [sc.frame(v, 1.0, "rtin")[0] for v in views]
            assert sc.actor.GetProperty().GetBackfaceCulling() == 1
        finally:
            sc.plotter.close()
    for a, b in zip(lists, strips, strict=True):
        assert (a != b).any(-1).mean() < 0.002  # the same triangles, rasterised alike

import numpy as np
import pytest

from geoterrain.core.view import INSIDE, OUTSIDE, View

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def test_lambda_and_from_camera():
    import pyvista as pv

    cam = pv.Camera()
    cam.position, cam.focal_point, cam.up = (0, -100, 50), (0, 0, 0), (0, 0, 1)
    cam.view_angle = 40.0
    v = View.from_camera(cam, (800, 600))
    assert v.fov_y_deg == 40.0 and v.size == (800, 600)
    assert v.lam == pytest.approx(300 / np.tan(np.radians(20)))
    np.testing.assert_allclose(v.eye, [0, -100, 50])


def test_frustum_planes_classify_points_and_boxes():
    v = View((0, 0, 0), (0, 1, 0), fov_y_deg=90, size=(100, 100), near=0.1, far=10)
    assert v.points_inside(np.array([[0, 5, 0], [0, -5, 0], [0, 20, 0], [6, 5, 0]])).tolist() == [
        True, False, False, False]
    lo = np.array([[-1, 4, -1], [-1, -9, -1], [-100, 1, -100]])
    hi = np.array([[1, 6, 1], [1, -8, 1], [100, 9, 100]])
    vis = v.box_visibility(lo, hi)
    assert vis[0] == INSIDE and vis[1] == OUTSIDE and vis[2] != OUTSIDE
    assert v.spheres_visible(np.array([[0, 5, 0], [0, -5, 0]]), np.array([1.0, 4.0])).tolist() \
        == [True, False]
    assert v.box_distance(lo[:1], hi[:1])[0] == pytest.approx(4.0)  # nearest point (0, 4, 0)


def test_straight_down_view_has_a_basis():
    v = View((0, 0, 100), (0, 0, 0))
    r, u, f = v.basis()
    assert np.isfinite(v.planes).all() and abs(r @ f) < 1e-12 and abs(u @ f) < 1e-12


def test_cameras_json_in_scene_and_crs_coordinates(tmp_path):
    import json

    from geoterrain.core.frame import Frame
    from geoterrain.core.view import load_views
    from geoterrain.exceptions import InputError

    p = tmp_path / "c.json"
    p.write_text(json.dumps({"crs": True, "fov": 40,
                             "cameras": [{"look_from": [3, -3, 10], "look_at": [5, -3, 0]}]}))
    with pytest.raises(InputError, match="need a store"):
        load_views(p)
    (v,) = load_views(p, (640, 360), frame=Frame.pixel(3, 3, 2.0, z_scale=2.0))
    assert v.look_from == (0.0, 0.0, 20.0) and v.look_at == (2.0, 0.0, 0.0)
    assert v.fov_y_deg == 40 and v.size == (640, 360)
    for bad in ([], [{"look_from": [0, 0, 0]}], [{"look_from": [1, 1, 1], "look_at": [1, 1, 1]}],
                [{"look_from": [0, 0, float("inf")], "look_at": [1, 1, 1]}]):
        p.write_text(json.dumps(bad))
        with pytest.raises(InputError):
            load_views(p)

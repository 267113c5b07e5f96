"""The planet models: pyproj's geodetic ↔ ECEF, and vertices placed on their rays."""

from __future__ import annotations

import numpy as np
import pytest
from pyproj import Transformer

from geoterrain.exceptions import UsageError
from geoterrain.globe.model import SPHERE_R, WGS84_A, WGS84_B, Model
from geoterrain.globe.polyhedron import face_directions


def test_models_by_name_and_a_bad_name_is_a_usage_error():
    assert Model.get("wgs84").a == WGS84_A and Model.get("wgs84").b == WGS84_B
    assert Model.get("sphere").a == SPHERE_R == Model.get("sphere").b
    with pytest.raises(UsageError, match="wgs84, sphere"):
        Model.get("mars")


def test_ecef_agrees_with_pyproj_epsg4979_to_4978_and_round_trips():
    rng = np.random.default_rng(1)
    lon, lat = rng.uniform(-180, 180, 200), rng.uniform(-90, 90, 200)
    h = rng.uniform(-500, 9000, 200)
    m = Model.get("wgs84")
    P = m.to_ecef(lon, lat, h)
    x, y, z = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(
        lon, lat, h)
    assert np.abs(P - np.stack([x, y, z], -1)).max() < 1e-6
    lo2, la2, h2 = m.to_geodetic(P)
    assert np.abs(la2 - lat).max() < 1e-9 and np.abs(h2 - h).max() < 1e-6


@pytest.mark.parametrize("name", ["wgs84", "sphere"])
def test_placed_vertices_lie_on_their_rays_at_the_height_read_where_they_are(name):
    m = Model.get(name)
    g = np.linspace(0, 1, 33)
    d = face_directions(7, g[None, :], g[:, None]).reshape(-1, 3)

    def heights(lon, lat):  # a smooth relief up to ±3 km
        return 3000.0 * np.sin(np.radians(lon) * 40) * np.cos(np.radians(lat) * 30)

    r, lon, lat = m.place(d, heights)
    P = d * r[:, None]
    lo2, la2, h2 = m.to_geodetic(P)
    # the vertex's own geodetic height is the terrain's at its own position (to 1 mm per
    # metre of height change over the correction), and it sits on its ray by construction
    assert np.abs(h2 - heights(lo2, la2)).max() < 0.5
    if name == "sphere":
        assert np.abs(r - SPHERE_R - heights(lon, lat)).max() < 1e-6

"""Seed 001 §3.4's collision meshes from a real DEM on the WGS 84 ellipsoid, and §3.2.2's
horizon culling on a low view: measured against the DEM file read independently."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

import geoterrain
from geoterrain.globe import Globe
from geoterrain.globe.nodes import horizon_hidden
from tests.conftest import real_dem

pytestmark = pytest.mark.slow  # a real store measured on the globe: ~30 s to set up


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    src = real_dem("srtm1_japan.tif")
    store = geoterrain.preprocess(src, tmp_path_factory.mktemp("globe") / "japan.geoterrain")
    g = Globe([store], node_cells=16, sync=True)
    with rasterio.open(src) as ds:
        z, T = ds.read(1).astype(np.float64), ds.transform
    yield g, z, T
    g.close()


def _dem_bilinear(z, T, lon, lat):
    """The DEM's bilinear height at lon, lat between pixel centres (NaN outside)."""
    r = (lat - T.f) / T.e - 0.5
    c = (lon - T.c) / T.a - 0.5
    ok = (r >= 0) & (c >= 0) & (r <= z.shape[0] - 1) & (c <= z.shape[1] - 1)
    r0 = np.clip(np.floor(r).astype(int), 0, z.shape[0] - 2)
    c0 = np.clip(np.floor(c).astype(int), 0, z.shape[1] - 2)
    fr, fc = r - r0, c - c0
    v = (z[r0, c0] * (1 - fr) * (1 - fc) + z[r0 + 1, c0] * fr * (1 - fc)
         + z[r0, c0 + 1] * (1 - fr) * fc + z[r0 + 1, c0 + 1] * fr * fc)
    return np.where(ok, v, np.nan)


def test_collision_mesh_heights_are_within_the_nodes_error_of_the_dem(japan):
    g, z, T = japan
    for level in (9, 11, g.surface.measured_depth):  # (the deepest measured level: the
        # levels beyond it hold 4 mm vertices, 10^10 nodes within 4 km)
        V, F = g.collision_mesh([(139.25, 35.35, 500.0)], radius=4000.0, level=level)
        assert V.dtype == np.float64 and F.shape[1] == 3 and F.max() < len(V)
        lon, lat, h = g.model.to_geodetic(V)  # pyproj: the vertices' own geodetic heights
        dem = _dem_bilinear(z, T, lon, lat)
        ok = np.isfinite(dem)
        assert ok.sum() > 100  # coarse nodes reach beyond the DEM
        err = np.abs(h - dem)[ok].max()
        # the level's largest node error, plus the store's codec step and the vertex
        # placement's tolerance (model.place)
        assert err <= g.table.e[level] + 0.6, (level, err, g.table.e[level])
        print(f"collision level {level}: max |h - DEM| {err:.3f} m, e {g.table.e[level]:.3f} m")
        # the mesh covers the objects' surroundings
        assert lon.min() < 139.21 and lon.max() > 139.29


def test_horizon_culling_removes_nodes_behind_the_horizon_and_no_visible_one(japan):
    g, _, _ = japan
    ground = float(g.surface.heights(np.array([139.25]), np.array([35.35]), g.max_depth)[0])
    v = g.camera(139.25, 35.35, ground + 50.0, 0.0, -5.0, size=(160, 120))  # a low view
    # the frustum off, so that the nodes behind the horizon are drawn without its culling
    on = g.select(v, 8.0, wait=True, frustum=False)
    off = g.select(v, 8.0, wait=True, frustum=False, horizon=False)
    # the nodes drawn without horizon culling that lie wholly behind the horizon
    pool = g.nodes
    eye = np.asarray(v.eye)
    behind = horizon_hidden(g.occluder, eye, pool.corners[off.rows])[0]
    # independent check of "behind": every corner's sight line dips below the lowest
    # possible surface radius somewhere between the eye and the corner
    C = pool.corners[off.rows]
    t = np.linspace(0.0, 1.0, 65)[None, None, :, None]
    line = eye[None, None, None, :] + t * (C[:, :, None, :] - eye)
    s = np.array([1 / g.occluder.a, 1 / g.occluder.a, 1 / g.occluder.b])
    below = (np.linalg.norm(line * s, axis=-1) < 1.0).any(2).all(1)
    assert below[behind].all()
    drawn_on = {int(k) for k in pool.key[on.rows]}
    hidden_keys = {int(k) for k in pool.key[off.rows[behind]]}
    culled = len(hidden_keys - drawn_on)
    assert behind.sum() > 0 and culled >= 0.9 * len(hidden_keys)
    # no visible node lost: every node drawn without culling and not behind the horizon is
    # drawn with it too, or covered by its drawn ancestors/descendants
    visible = [int(k) for k in pool.key[off.rows[~behind]]]
    lost = [k for k in visible if k not in drawn_on]
    assert not lost
    print(f"horizon: {culled}/{len(hidden_keys)} behind culled, {len(lost)} visible lost, "
          f"nodes {on.stats['nodes']} vs {off.stats['nodes']}")
    assert on.stats["nodes"] < off.stats["nodes"]


def test_a_collision_mesh_too_deep_to_hold_is_refused_in_one_line(japan):
    """The levels beyond the measured depth hold 4 mm vertices: a collision mesh of 4 km
    there would be 10^10 nodes; it is refused before a payload is made."""
    from geoterrain.exceptions import UsageError

    g, _, _ = japan
    with pytest.raises(UsageError, match="coarser level") as err:
        g.collision_mesh([(139.25, 35.35, 500.0)], radius=4000.0, level=g.max_depth)
    assert "\n" not in str(err.value)

"""ρ ≤ τ on the globe, measured by the project's independent measure.

The truth is srtm1_japan as its store holds it (the decoded full resolution): each sample
placed by pyproj at its geodetic lon, lat and height (EPSG:4979 → EPSG:4978). The drawn
mesh and the samples are carried by a central (gnomonic) projection from the planet's
centre onto the tangent plane at the DEM: a ray from the centre becomes one point (x, y),
a flat triangle a flat triangle, and along the rays through a flat triangle 1/ρ (ρ the
distance along the plane's normal axis) is affine in (x, y). The DEM's outer FEATHER
samples, where the store blends into the layer under it, are left out.
:func:`geoterrain.testing.metricmeasure.metric_errors` then finds each sample's triangle
and the mesh's 1/ρ there, with no code of the globe in between; the radial gap is
|Δ(1/ρ)|·ρ_mesh·ρ_true·|(x, y, 1)|, and ρ_px = λ·gap / ‖sample − eye‖ (the flat
measure's definition).
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from pyproj import Transformer

import geoterrain
from geoterrain.globe import Globe
from geoterrain.globe.layers import FEATHER
from geoterrain.testing.metricmeasure import metric_errors
from tests.conftest import real_dem

pytestmark = pytest.mark.slow  # 40 converged views of a real store on the globe


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    src = real_dem("srtm1_japan.tif")
    store = geoterrain.preprocess(src, tmp_path_factory.mktemp("globe") / "japan.geoterrain")
    with rasterio.open(src) as ds:
        T = ds.transform
    # the heights the store holds (its codec's full resolution), which the globe's errors
    # are measured against; the DEM file differs from them by the codec's bound
    with geoterrain.open(store) as t:
        z = t.scene_xyz()[2] / (t.frame.z_to_m * t.frame.z_scale)
    lat = T.f + (np.arange(z.shape[0]) + 0.5) * T.e
    lon = T.c + (np.arange(z.shape[1]) + 0.5) * T.a
    LON, LAT = np.meshgrid(lon, lat)
    x, y, zz = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(
        LON.ravel(), LAT.ravel(), z.ravel())
    truth = np.stack([x, y, zz], -1)
    # a store's edge blends into the layer under it over FEATHER samples (by design: no
    # cliff at its border): the truth there is not the DEM, so those samples are left out
    b = int(FEATHER) + 1
    core = np.zeros(z.shape, bool)
    core[b:-b, b:-b] = True
    truth = truth[core.ravel() & np.isfinite(z).ravel()]
    g = Globe([store], node_cells=16, sync=True)
    yield g, truth, (float(lon.mean()), float(lat.mean()))
    g.close()


def _gnomonic(P, c, e1, e2):
    """(x, y, ρ) of points P by central projection onto the plane c·p = 1 (unit c)."""
    w = P @ c
    return (P @ e1) / w, (P @ e2) / w, w


def measured_rho(sel, truth, view, centre_dir):
    c = centre_dir / np.linalg.norm(centre_dir)
    e1 = np.cross([0.0, 0.0, 1.0], c)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    W = sel.world
    near = (W @ c) / np.linalg.norm(W, axis=1) > 0.995  # the mesh around the DEM
    F = sel.faces[near[sel.faces].all(1)]
    vx, vy, vw = _gnomonic(W, c, e1, e2)
    sx, sy, sw = _gnomonic(truth, c, e1, e2)
    eye = np.asarray(view.eye, np.float64)
    inside = np.ones(len(truth), bool)
    for a, b, cc, d in view.planes:  # the frustum's inward planes, in ECEF
        inside &= truth @ np.array([a, b, cc]) + d >= 0
    err, outside = metric_errors(F, vx, vy, 1.0 / vw, sx, sy, 1.0 / sw, inside)
    ok = np.isfinite(err)
    if not ok.any():
        return 0.0, 0, int(outside.sum())
    # 1/ρ_mesh = 1/ρ_true ± err: the radial gap along the sample's ray
    rho_mesh = 1.0 / (1.0 / sw[ok] + err[ok])
    gap = err[ok] * rho_mesh * sw[ok] * np.sqrt(1 + sx[ok] ** 2 + sy[ok] ** 2)
    dist = np.linalg.norm(truth[ok] - eye, axis=1)
    return float((view.lam * gap / dist).max()), int(ok.sum()), int(outside.sum())


@pytest.mark.parametrize("tau", [1.0, 4.0])
def test_measured_screen_error_within_tau_on_20_random_views(japan, tau):
    g, truth, (lon0, lat0) = japan
    centre = truth.mean(0)
    rng = np.random.default_rng(int(tau))
    worst, views, samples = 0.0, 0, 0
    for _ in range(80):  # 20 views that see the DEM (some random ones look past it)
        lon = lon0 + rng.uniform(-0.1, 0.1)
        lat = lat0 + rng.uniform(-0.1, 0.1)
        ground = float(g.surface.heights(np.array([lon]), np.array([lat]), g.max_depth)[0])
        v = g.camera(lon, lat, ground + rng.uniform(50.0, 20000.0), rng.uniform(0, 360),
                     rng.uniform(-60.0, -10.0), size=(320, 240))
        sel = g.select(v, tau, wait=True)
        rho, n, out = measured_rho(sel, truth, v, centre)
        if n < 1000:
            continue
        assert out == 0  # every sample in the frustum lies under the mesh
        worst, views, samples = max(worst, rho), views + 1, samples + n
        if views == 20:
            break
    assert views == 20
    print(f"tau {tau}: worst measured rho {worst:.3f} px over {views} views, {samples} samples")
    assert worst <= tau

"""No tear at the antimeridian or the poles: a synthetic store crossing ±180° and a polar cap
reaching the north pole, drawn on the globe.

The mesh is checked as the whole closed planet is (0 edges shared by more than two
triangles, every boundary edge lying on another: T-junctions only), with views centred
on the antimeridian and on the pole; the heights across the seam and at the pole are
checked against the rasters' own function, evaluated here without any globe code.
"""

from __future__ import annotations

import numpy as np
import pytest

from geoterrain.globe import Globe
from tests.conftest import write_tif
from tests.globe.test_globe_cdlod import _gaps

pytestmark = pytest.mark.slow  # two stores measured on the globe, two whole planets: ~60 s

STEP = 0.1  # degrees a cell of the dateline store


def f_dateline(lon, lat):
    """The dateline store's heights: smooth in the continuous longitude 177…183°."""
    return 1000.0 + 600.0 * np.sin(np.radians(lon - 177.0) * 20) * np.cos(np.radians(lat) * 30)


def f_cap(lon, lat):
    """The polar cap's heights: a function of the distance from the pole (and a longitude
    wave that vanishes at the pole), so the pole has one height."""
    c = 90.0 - lat
    return 300.0 + 20.0 * c + 15.0 * c * np.sin(np.radians(lon) * 3)


@pytest.fixture(scope="module")
def globe(tmp_path_factory):
    import geoterrain

    d = tmp_path_factory.mktemp("seams")
    # 177°E … 183°E (= 177°W), 2°S … 2°N: across the antimeridian
    lat = 2.0 - (np.arange(40) + 0.5) * STEP
    lon = 177.0 + (np.arange(60) + 0.5) * STEP
    z = f_dateline(lon[None, :], lat[:, None]).astype(np.float32)
    dl = geoterrain.preprocess(write_tif(d / "dateline.tif", z, crs="EPSG:4326",
                                         origin=(177.0, 2.0), spacing=STEP),
                               d / "dateline.geoterrain")
    # every longitude, 87°N … 90°N: a cap reaching the pole (1° cells)
    lat = 90.0 - (np.arange(3) + 0.5)
    lon = -180.0 + (np.arange(360) + 0.5)
    z = f_cap(lon[None, :], lat[:, None]).astype(np.float32)
    cap = geoterrain.preprocess(write_tif(d / "cap.tif", z, crs="EPSG:4326",
                                          origin=(-180.0, 90.0), spacing=1.0),
                                d / "cap.geoterrain")
    # a narrow feather (2 samples): the stores' own heights reach the seam, which the
    # heights' test compares with the rasters' function
    g = Globe([dl, cap], node_cells=8, sync=True, feather=2.0)
    yield g
    g.close()


@pytest.mark.parametrize("lon, lat", [(180.0, 0.0), (0.0, 90.0)])
def test_the_planet_stays_closed_around_the_antimeridian_and_the_pole(globe, lon, lat):
    v = globe.camera(lon, lat, 4.0e5, 0.0, -90.0, size=(320, 240))
    sel = globe.select(v, 4.0, wait=True, frustum=False, horizon=False)
    assert sel.stats["max_depth"] >= 4  # refined around the seam
    over, boundary, worst = _gaps(sel.world, sel.faces)
    assert over == 0 and boundary > 0  # T-junctions between levels, nothing else
    assert worst < 1e-4  # metres: no crack, no gap
    # the mesh reaches across the seam: vertices on both sides of ±180° (or all round the
    # pole) near the view's centre
    glon, glat, _ = globe.model.to_geodetic(sel.world)
    near = np.abs(glat - lat) < 2.0 if lat == 90.0 else (np.abs(glat) < 2.0) & (
        np.abs(glon) > 178.0)
    if lat == 90.0:
        assert np.ptp(glon[near]) > 300  # every longitude round the pole
    else:
        assert (glon[near] > 0).any() and (glon[near] < 0).any()


def test_heights_run_across_the_antimeridian_without_a_step(globe):
    lon = np.arange(179.0, 181.0, 0.005)
    lat = np.full(lon.shape, 0.567)
    wrapped = np.where(lon > 180.0, lon - 360.0, lon)  # the globe's longitudes
    h = globe.surface.heights(wrapped, lat, globe.max_depth)
    truth = f_dateline(lon, lat)
    # the store's own samples, interpolated bilinearly: within the function's curvature
    # over a cell and the codec's step
    assert np.isfinite(h).all()
    assert np.abs(h - truth).max() < 2.0, np.abs(h - truth).max()
    assert np.abs(np.diff(h)).max() < 1.5 * np.abs(np.diff(truth)).max() + 0.5


def test_the_pole_has_one_height_from_every_longitude(globe):
    lon = np.arange(-180.0, 180.0, 15.0)
    at = globe.surface.heights(lon, np.full(lon.shape, 90.0), globe.max_depth)
    assert np.isfinite(at).all() and np.ptp(at) < 1e-6
    # the pole takes the polar row's mean (the row 0.5° from it: 310 m) ...
    row = f_cap(-179.5 + np.arange(360.0), 89.5)
    assert abs(at[0] - row.mean()) < 0.5
    # ... and between the row and the pole the heights stay within the row's range: no
    # spike, no hole (NaN), no step
    for lat in (89.6, 89.8, 89.95):
        near = globe.surface.heights(lon, np.full(lon.shape, lat), globe.max_depth)
        assert np.isfinite(near).all()
        assert row.min() - 0.5 <= near.min() and near.max() <= row.max() + 0.5

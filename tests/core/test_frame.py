import numpy as np
import pytest
from pyproj import CRS, Geod

import geoterrain
from geoterrain.core.frame import Frame
from geoterrain.ingest.raster import read_raster
from geoterrain.ingest.synth import generate, write_geotiff
from tests.conftest import real_dem


def test_projected_feet_are_converted_to_metres():
    r = read_raster(real_dem("roi_epsg3089.tif"))
    f = Frame.from_raster(r.transform, r.crs_wkt, *r.shape)
    assert f.kind == "projected"
    assert f.unit_to_m == pytest.approx(1200 / 3937)  # US survey foot
    X, Y = f.xy(np.array([0, 0]), np.array([0, 1]))
    assert X[1] - X[0] == pytest.approx(r.transform[0] * 1200 / 3937)
    # the scene origin is the raster centre: coordinates stay small
    assert abs(X[0]) < 1e4 and abs(Y[0]) < 1e4


@pytest.mark.parametrize("name", ["srtm1_japan.tif", "srtm3_pysheds.tif"])
def test_geographic_extent_matches_geodesic_distances(name):
    r = read_raster(real_dem(name))
    H, W = r.shape
    f = Frame.from_raster(r.transform, r.crs_wkt, H, W)
    assert f.kind == "geographic"
    geod = CRS.from_wkt(r.crs_wkt).get_geod()
    for i0, j0, i1, j1 in [(0, 0, 0, W - 1), (H - 1, 0, H - 1, W - 1), (0, 0, H - 1, 0),
                           (H // 2, 0, H // 2, W - 1), (0, 0, H - 1, W - 1)]:
        X, Y = f.xy(np.array([i0, i1]), np.array([j0, j1]))
        lon, lat = f._crs_xy(np.array([i0, i1]), np.array([j0, j1]))
        _, _, d = geod.inv(lon[0], lat[0], lon[1], lat[1])
        assert np.hypot(X[1] - X[0], Y[1] - Y[0]) == pytest.approx(d, rel=1e-3)


@pytest.mark.fast
def test_one_degree_tile_has_true_proportions():
    # a synthetic 1°×1° tile at 45°N: east-west extent shrinks with cos(lat)
    t = (1 / 100, 0.0, 10.0, 0.0, -1 / 100, 46.0)
    f = Frame.from_raster(t, CRS.from_epsg(4326).to_wkt(), 100, 100)
    geod = Geod(ellps="WGS84")
    for i in (0, 50, 99):
        X, Y = f.xy(np.array([i, i]), np.array([0, 99]))
        lon, lat = f._crs_xy(np.array([i, i]), np.array([0, 99]))
        d = geod.inv(lon[0], lat[0], lon[1], lat[1])[2]
        assert np.hypot(X[1] - X[0], Y[1] - Y[0]) == pytest.approx(d, rel=1e-3)


@pytest.mark.fast
def test_crs_round_trip_and_pixel_frame():
    f = Frame.pixel(5, 7, 30.0)
    X, Y = f.xy(np.array([0, 4]), np.array([0, 6]))
    assert X.tolist() == [-90.0, 90.0] and Y.tolist() == [60.0, -60.0]
    x, y = f.scene_to_crs(X, Y)
    X2, Y2 = f.crs_to_scene(x, y)
    np.testing.assert_allclose([X2, Y2], [X, Y])


@pytest.mark.fast
def test_z_units_and_scale():
    f = Frame.pixel(2, 2, z_to_m=0.3048, z_scale=2.0)
    assert f.z(np.array([10.0]))[0] == pytest.approx(6.096)


@pytest.mark.parametrize("version", ["WKT1_GDAL", "WKT2_2019"])
@pytest.mark.parametrize("epsg", [4326, 4269, 32633, 3857, 3089, 2056, 27700, 4978, 3035, 6933,
                                  5070, 4258, 7415])
def test_crs_name_without_pyproj_is_pyprojs(epsg, version):
    """The name read from the WKT's root (no pyproj import) is pyproj's CRS.name, for plain
    and compound CRSs, WKT 1 and 2; a root it does not read goes to pyproj."""
    wkt = CRS.from_epsg(epsg).to_wkt(version)
    f = Frame("projected", 3, 3, (1.0, 0.0, 0.0, 0.0, -1.0, 0.0), wkt)
    assert f.crs_name == CRS.from_wkt(wkt).name


def test_info_does_not_import_pyproj(tmp_path):
    """``geoterrain info`` reads a store's numbers only: pyproj stays unloaded."""
    import subprocess
    import sys

    z = generate("fbm", 65, seed=1)
    store = geoterrain.preprocess(write_geotiff(tmp_path / "d.tif", z), tmp_path / "d.geoterrain")
    code = ("import sys; from geoterrain.cli.main import main\n"
            f"sys.argv = ['geoterrain', 'info', {str(store)!r}]\n"
            "try:\n    main()\nexcept SystemExit:\n    pass\n"
            "print('PYPROJ', 'pyproj' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "PYPROJ False" in out, out


@pytest.mark.fast
def test_geographic_xy_is_one_pyproj_call_bit_for_bit():
    # Frame.xy transforms its own arrays in place, split over threads: the values of one
    # plain pyproj call on the same points, bit for bit, whether the indices come meshed or
    # as a column and a row (the streamed xy pass), and the caller's arrays untouched
    from geoterrain.core.frame import _transform_threads

    t = (3 / 3600, 0.0, 10.0, 0.0, -3 / 3600, 47.0)
    f = Frame.from_raster(t, CRS.from_epsg(4326).to_wkt(), 700, 1000)
    i, j = np.arange(-5, 710)[:, None], np.arange(1000)[None, :]  # > 2 chunks; padding rows
    ii, jj = (a.copy() for a in np.broadcast_arrays(i, j))
    x, y = f._crs_xy(ii, jj)
    want = [np.asarray(a) for a in f._to_scene.transform(x, np.clip(y, -90.0, 90.0))]
    for args in ((i, j), (ii, jj)):
        got = f.xy(*args)
        assert [a.shape for a in got] == [ii.shape] * 2
        assert [a.tobytes() for a in got] == [a.tobytes() for a in want]
    assert (ii == np.arange(-5, 710)[:, None]).all() and (jj == np.arange(1000)).all()
    X, Y = f.xy(np.array(3), np.array(4))  # 0-d
    assert (X.shape, float(X), float(Y)) == ((), *map(float, f._to_scene.transform(
        *f._crs_xy(np.array(3), np.array(4)))))
    # not owned (or a read-only view): the inputs are left as they were
    xc, yc = x.copy(), y.copy()
    for owned in (False, True):
        got = _transform_threads(f._to_scene, x, np.broadcast_to(y[:1], y.shape), owned)
        assert (x == xc).all() and (y == yc).all()
        assert got[0].tobytes() == np.asarray(f._to_scene.transform(
            x, np.broadcast_to(y[:1], y.shape))[0]).tobytes()


@pytest.mark.fast
def test_transform_threads_are_kept_and_a_fork_child_makes_its_own():
    # the threads beside the caller's are made once (each builds its PROJ object once per
    # Transformer, not once per call: a band of the streamed xy pass) and a fork child,
    # which has none of them, makes its own: the same values, no hang
    import multiprocessing
    import os
    import threading

    from geoterrain.core import frame as fm

    t = (3 / 3600, 0.0, 10.0, 0.0, -3 / 3600, 47.0)
    f = Frame.from_raster(t, CRS.from_epsg(4326).to_wkt(), 700, 1000)
    x, y = f._crs_xy(np.arange(700)[:, None], np.arange(1000)[None, :])

    def ours():
        return {th.ident for th in threading.enumerate()
                if th.name.startswith("geoterrain-pyproj")}

    want = [a.tobytes() for a in f._to_scene.transform(x, y)]
    assert [a.tobytes() for a in fm._transform_threads(f._to_scene, x, y)] == want
    first = ours()
    assert [a.tobytes() for a in fm._transform_threads(f._to_scene, x, y)] == want
    assert ours() == first
    assert len(first) == (max(1, os.cpu_count() - 1) if (os.cpu_count() or 1) > 1 else 0)
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(1) as pool:
        got = pool.apply_async(_child_transform, (f.to_json(), x, y)).get(timeout=60)
    assert got == want


def _child_transform(frame, x, y):
    from geoterrain.core.frame import _transform_threads

    f = Frame.from_json(frame)
    return [a.tobytes() for a in _transform_threads(f._to_scene, x, y)]


@pytest.mark.fast
def test_the_aeqd_frame_is_rebuilt_from_the_crs_and_the_origin():
    """Schema 23: a store's frame holds no aeqd_wkt; Frame.aeqd_wkt builds it from crs_wkt
    and origin_crs: the azimuthal equidistant projection of the datum about the origin
    (the origin maps to (0, 0), a point 1 km east lies 1 km away), the same after a JSON
    round trip, and None on the other kinds; an old frame dict with the field reads."""
    t = (1 / 1200, 0.0, 138.0, 0.0, -1 / 1200, 36.0)
    f = Frame.from_raster(t, CRS.from_epsg(4326).to_wkt(), 359, 367)
    d = f.to_json()
    assert "aeqd_wkt" not in d
    g = Frame.from_json(d)
    assert g == f and g.aeqd_wkt == f.aeqd_wkt
    aeqd = CRS.from_wkt(g.aeqd_wkt)
    assert aeqd.coordinate_operation.method_name.endswith("Azimuthal Equidistant")
    from pyproj import Transformer

    tr = Transformer.from_crs(CRS.from_epsg(4326), aeqd, always_xy=True)
    x0, y0 = tr.transform(*f.origin_crs)
    assert abs(x0) < 1e-6 and abs(y0) < 1e-6
    lon1, lat1, _ = Geod(ellps="WGS84").fwd(*f.origin_crs, 90.0, 1000.0)
    assert np.hypot(*tr.transform(lon1, lat1)) == pytest.approx(1000.0, abs=1e-6)
    assert Frame.from_json({**d, "aeqd_wkt": "ignored"}) == f  # derived, not read
    assert Frame.pixel(3, 3).aeqd_wkt is None

"""surface_area and volume against GEOS on the full-resolution triangulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import real_dem, write_tif
from geoterrain.analysis import Plane, surface_area, volume
from geoterrain.exceptions import InputError, UsageError
from geoterrain.testing.analysisref import triangulated_reference
from tests.analysis.stores import read_source, store_of


def _metres(t):
    """Source CRS → metres, built here from pyproj CRS objects (not from the store's frame
    or the library's pipeline): on a geographic grid each triangle through a Lambert
    azimuthal equal-area projection about the centre sample of the level-0 tile that
    holds its cell (the surface's definition, docs: analysis/areas.py), on the WGS 84
    ellipsoid."""
    f = t.frame
    if f.kind != "geographic":
        return lambda x, y: (x * f.unit_to_m, y * f.unit_to_m)
    from pyproj import CRS, Transformer

    a, _, c, _, e, top = f.transform[:6]
    n = t.grid.tile_samples - 1  # cells per level-0 tile
    src = CRS.from_wkt(f.crs_wkt)

    def to_metres(x, y):
        col = np.round((x - c) / a - 0.5).min(axis=1)  # each triangle's cell
        row = np.round((y - top) / e - 0.5).min(axis=1)
        tile = (row // n).astype(int), (col // n).astype(int)
        X, Y = np.empty_like(x), np.empty_like(y)
        for ty, tx in set(zip(*tile, strict=True)):
            m = (tile[0] == ty) & (tile[1] == tx)
            lon0, lat0 = c + a * (tx * n + n // 2 + 0.5), top + e * (ty * n + n // 2 + 0.5)
            laea = CRS.from_proj4(f"+proj=laea +lat_0={lat0} +lon_0={lon0} +ellps=WGS84")
            X[m], Y[m] = Transformer.from_crs(src, laea, always_xy=True).transform(x[m], y[m])
        return X, Y

    return to_metres


def _star(rng, cx, cy, r, n, hole=False):
    """A random star-shaped polygon (and sometimes a hole in it), shapely."""
    from shapely.geometry import Polygon

    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = r * rng.uniform(0.3, 1.0, n)
    outer = np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)])
    holes = []
    if hole:
        k = np.linspace(0, 2 * np.pi, 7)[:-1]
        holes = [np.column_stack([cx + 0.2 * r * np.cos(k), cy + 0.2 * r * np.sin(k)])]
    p = Polygon(outer, holes)
    p = p if p.is_valid else Polygon(outer)  # a hole across the outline: none
    assume(p.is_valid and p.area > 0)
    return p


def _check(t, src, poly, base, rel=1e-9):
    z, valid, tr = read_source(src)
    ref = triangulated_reference(z, valid, tr, _metres(t), poly, base, t.frame.z_to_m)
    a = surface_area(t, poly)
    v = volume(t, poly, Plane(*base))
    scale = ref["area_2d"] + ref["nodata_area"]
    assert a.area_2d == pytest.approx(ref["area_2d"], rel=rel, abs=rel * scale)
    assert a.area_3d == pytest.approx(ref["area_3d"], rel=rel, abs=rel * scale)
    assert a.nodata_area == pytest.approx(ref["nodata_area"], rel=rel, abs=rel * scale)
    vscale = max(ref["cut"] + ref["fill"], 1.0)
    assert v.cut == pytest.approx(ref["cut"], rel=rel, abs=rel * vscale)
    assert v.fill == pytest.approx(ref["fill"], rel=rel, abs=rel * vscale)
    assert a.bound_3d == 0 and v.bound == 0
    return a, v


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    src = real_dem("srtm1_japan.tif")
    return store_of(tmp_path_factory, src), src


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(3, 14), hole=st.booleans(),
       r=st.floats(0.002, 0.03))
def test_srtm1_japan_areas_and_volumes_match_geos(japan, seed, n, hole, r):
    t, src = japan
    rng = np.random.default_rng(seed)
    cx, cy = rng.uniform(139.14, 139.32), rng.uniform(35.28, 35.45)
    poly = _star(rng, cx, cy, r, n, hole)
    base = (rng.uniform(-2000, 2000), rng.uniform(-2000, 2000), 0.0)
    base = (base[0], base[1], rng.uniform(0, 600) - base[0] * cx - base[1] * cy)
    _check(t, src, poly, base)


@pytest.fixture(scope="module")
def holed(tmp_path_factory):
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("areas")
    z = generate("fbm", 129, seed=2)[:120].astype(np.float32) * 0.2
    z[50:58, 60:75] = -9999.0
    src = write_tif(d / "h.tif", z, nodata=-9999.0, crs="EPSG:2263", origin=(9e5, 2e5),
                    spacing=30.0)  # New York state plane: US survey feet both ways
    t = geoterrain.open(geoterrain.preprocess(src, d / "h.geoterrain", tile_size=16))
    return t, src


@pytest.mark.fast
def test_feet_and_nodata(holed):
    t, src = holed
    assert t.frame.z_to_m != 1.0
    a, _, c, _, e, f = t.frame.transform[:6]
    poly = _star(np.random.default_rng(3), c + a * 65, f + e * 55, 40 * a, 9, hole=True)
    ar, v = _check(t, src, poly, (0.0, 0.0, 150.0))
    assert ar.nodata_area > 0 and v.cut > 0 and v.fill > 0


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), e=st.sampled_from([0.5, 2.0, 8.0, 30.0]))
def test_max_error_answer_is_within_its_bound(holed, seed, e):
    t, src = holed
    rng = np.random.default_rng(seed)
    a, _, c, _, ee, f = t.frame.transform[:6]
    u, w = rng.uniform(6, 122), rng.uniform(6, 113)  # column, row of the centre
    room = min(u, 128 - u, w, 119 - w) - 1
    poly = _star(rng, c + a * u, f + ee * w, a * rng.uniform(5, room),
                 int(rng.integers(3, 12)))
    base = Plane(0.0, 0.0, float(rng.uniform(50, 250)))
    exact_a, exact_v = surface_area(t, poly), volume(t, poly, base)
    ar, v = surface_area(t, poly, max_error=e), volume(t, poly, base, max_error=e)
    assert abs(ar.area_3d - exact_a.area_3d) <= ar.bound_3d + 1e-6
    for k in ("cut", "fill", "net"):
        assert abs(getattr(v, k) - getattr(exact_v, k)) <= v.bound + 1e-6
    assert ar.area_2d == pytest.approx(exact_a.area_2d, rel=1e-9, abs=1e-6)


@pytest.mark.fast
def test_coarse_levels_read_fewer_tiles(japan):
    t, _ = japan
    poly = _star(np.random.default_rng(0), 139.2, 35.35, 0.05, 12)
    t.clear_cache()
    fine = volume(t, poly, 100.0)
    t.clear_cache()
    coarse = volume(t, poly, 100.0, max_error=25.0)
    assert max(coarse.levels) > 0
    assert coarse.stats["tiles_decoded"] < fine.stats["tiles_decoded"]
    assert abs(coarse.net - fine.net) <= coarse.bound


@pytest.mark.fast
def test_fitted_base_of_a_mound(tmp_path):
    # a cone of height 10 m, radius 100 m on a tilted plane: its volume is π r² h / 3
    n = 257
    yy, xx = np.mgrid[0:n, 0:n] * 1.0
    r = np.hypot(xx - 128, yy - 128)
    z = 0.05 * xx + 0.02 * yy + np.clip(10 * (1 - r / 100), 0, None)
    src = write_tif(tmp_path / "cone.tif", z, spacing=1.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "cone.geoterrain"))
    a, _, c, _, e, f = t.frame.transform[:6]
    k = np.linspace(0, 2 * np.pi, 200)[:-1]
    ring = np.column_stack([c + a * (128.5 + 120 * np.cos(k)), f + e * (128.5 + 120 * np.sin(k))])
    v = volume(t, ring, base="fit")
    assert v.base.a == pytest.approx(0.05, abs=1e-3) and v.base.b == pytest.approx(-0.02, abs=1e-3)
    assert v.net == pytest.approx(math.pi * 100 ** 2 * 10 / 3, rel=0.01)


@pytest.mark.fast
def test_polygon_errors_are_one_line(japan):
    t, _ = japan
    cases = [("POLYGON EMPTY", UsageError, "empty"),
             ("POLYGON ((139.2 35.3, 139.3 35.3, 139.2 35.3))", UsageError, "empty"),
             ("POLYGON ((139.2 35.3, 139.3 35.4, 139.3 35.3, 139.2 35.4, 139.2 35.3))",
              UsageError, "not valid"),
             ("LINESTRING (139.2 35.3, 139.3 35.4)", UsageError, "polygon"),
             ("POLYGON ((139.2 35.3, 142 35.3, 139.2 35.4, 139.2 35.3))", InputError,
              "outside"),
             ("not wkt", UsageError, "cannot read")]
    for poly, exc, word in cases:
        with pytest.raises(exc, match=word) as info:
            surface_area(t, poly)
        assert "\n" not in str(info.value)
    with pytest.raises(UsageError, match="one line"):
        volume(t, "POLYGON ((139.2 35.3, 139.3 35.3, 139.2 35.4, 139.2 35.3))",
               [(1, 1, 1), (2, 2, 2), (3, 3, 3)])


def _rectangle_on_the_ellipsoid(lon0, lon1, lat0, lat1, n=4000):
    """The WGS 84 area of a longitude-latitude rectangle (its edges along meridians and
    parallels, densified for pyproj's geodesic polygon area)."""
    from pyproj import Geod

    lo = np.r_[np.linspace(lon0, lon1, n), np.full(n, lon1), np.linspace(lon1, lon0, n),
               np.full(n, lon0)]
    la = np.r_[np.full(n, lat0), np.linspace(lat0, lat1, n), np.full(n, lat1),
               np.linspace(lat1, lat0, n)]
    return abs(Geod(ellps="WGS84").polygon_area_perimeter(lo, la)[0])


def test_geographic_areas_are_the_ellipsoids_anywhere_on_a_whole_globe_grid(tmp_path):
    """A whole-globe grid of 1° cells: a rectangle's planimetric area is its area on the
    ellipsoid (to the second order of the cell: 3e-4), at the DEM's centre, far from it,
    near the poles and at the antipode of the scene's centre (180°), where the scene's
    azimuthal-equidistant positions gave 1 039× the area (and 1.007× at 11°)."""
    z = np.random.default_rng(0).uniform(0, 500, (180, 360)).astype(np.float32)
    src = write_tif(tmp_path / "globe.tif", z, crs="EPSG:4326", origin=(-180.0, 90.0),
                    spacing=1.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "globe.geoterrain"))
    assert t.frame.columns_per_turn == 360
    for lon0, lon1, lat0, lat1 in [(-2, 3, -1, 2), (176, 179, 0, 2), (10, 13, 0, 2),
                                   (-170, -150, 40, 70), (100, 140, -85, -75)]:
        ring = [(lon0, lat0), (lon1, lat0), (lon1, lat1), (lon0, lat1)]
        a = surface_area(t, ring)
        want = _rectangle_on_the_ellipsoid(lon0, lon1, lat0, lat1)
        assert a.area_2d == pytest.approx(want, rel=3e-4), (lon0, lat0)
        assert a.area_3d >= a.area_2d and a.nodata_area == 0
        flat = volume(t, ring, base=-1000.0)  # every height above: cut = ∫ (z + 1000) dA
        assert flat.fill == 0 and flat.cut > 1000.0 * a.area_2d

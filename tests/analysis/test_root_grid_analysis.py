"""Height queries, normals, profiles and contours on a store of rectangular root tiles
(issue 45, ``preprocess --root-grid``): against the input raster's own bilinear heights
(numpy, not the store) and against the same raster on the square grid."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain.analysis.contours import contours
from geoterrain.analysis.heights import height_at, normal_at
from geoterrain.analysis.profile import profile
from geoterrain.ingest.synth import generate, write_geotiff

pytestmark = pytest.mark.fast


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 129 × 513 fBm (UTM, 10 m, a nodata void in the east root) on the square and on
    2 × 1 roots of 32-sample tiles; the raster (NaN at nodata) and its transform."""
    d = tmp_path_factory.mktemp("rootanalysis")
    z = np.rint(generate("fbm", 513, seed=8, relief=600.0)[:129, :513] * 10) / 10
    z = z.astype(np.float32)
    z[60:75, 380:420] = -9999.0
    dem = write_geotiff(d / "wide.tif", z, crs="EPSG:32633", origin=(500000.0, 5000000.0),
                        spacing=10.0, nodata=-9999.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert rt.grid.roots == (2, 1)
    return sq, rt, np.where(z == -9999.0, np.nan, z.astype(np.float64))


def _points(n, seed=0):
    """Points over the whole raster (both roots), x, y in metres (pixel-corner origin
    at (500000, 5000000), 10 m pixels): fractional grid (row, col) and x, y."""
    rng = np.random.default_rng(seed)
    fi, fj = rng.uniform(0, 128, n), rng.uniform(0, 512, n)
    return fi, fj, np.column_stack([500000.0 + 10.0 * (fj + 0.5),
                                    5000000.0 - 10.0 * (fi + 0.5)])


def _bilinear(z, fi, fj):
    i0 = np.minimum(np.floor(fi).astype(int), z.shape[0] - 2)
    j0 = np.minimum(np.floor(fj).astype(int), z.shape[1] - 2)
    u, v = fi - i0, fj - j0
    return ((1 - u) * (1 - v) * z[i0, j0] + (1 - u) * v * z[i0, j0 + 1]
            + u * (1 - v) * z[i0 + 1, j0] + u * v * z[i0 + 1, j0 + 1])


@pytest.mark.parametrize("level", [0, 1, 3])
def test_heights_are_within_their_bound_of_the_rasters(pair, level):
    """|height − the raster's bilinear height| ≤ bound at every point (both roots, near
    the void), NaN where the raster's cell holds nodata; level 0 is the square's
    answer exactly."""
    sq, rt, z = pair
    fi, fj, xy = _points(3000, seed=level)
    ref = _bilinear(z, fi, fj)
    h = height_at(rt, xy, level)
    ok = np.isfinite(ref)
    assert (np.isnan(h.height) == ~ok).all()
    assert (np.abs(h.height[ok] - ref[ok]) <= h.bound[ok] + 1e-9).all()
    assert (xy[:, 0] > 500000.0 + 2560.0).sum() > 1000  # many in the east root
    if level == 0:
        np.testing.assert_array_equal(h.height, height_at(sq, xy).height)
    else:
        assert (h.level[ok] == level).mean() > 0.5  # most answered at the level asked


def test_normals_profiles_and_contours_are_the_squares(pair):
    sq, rt, z = pair
    _, _, xy = _points(500, seed=9)
    a, b = normal_at(sq, xy), normal_at(rt, xy)
    np.testing.assert_array_equal(a.normal, b.normal)
    line = [(500005.0, 4999500.0), (505100.0, 4999000.0), (503000.0, 4998800.0)]
    pa, pb = profile(sq, line), profile(rt, line)
    np.testing.assert_array_equal(pa.height, pb.height)
    assert np.isfinite(pb.height).sum() > 100
    ca, cb = contours(sq, 50.0), contours(rt, 50.0)
    assert len(cb.lines) == len(ca.lines) > 10
    np.testing.assert_array_equal(ca.heights, cb.heights)
    for la, lb in zip(ca.lines, cb.lines, strict=True):
        np.testing.assert_array_equal(la, lb)
    ca, cb = contours(sq, 50.0, max_error=40.0), contours(rt, 50.0, max_error=40.0)
    assert cb.level == ca.level >= 1 and cb.bound == ca.bound
    assert len(cb.lines) == len(ca.lines)


def test_areas_and_volumes_are_the_squares(pair):
    """A polygon across both roots (and the void): the same areas, volumes and bounds as
    the square store's, exact and with a coarser level."""
    from geoterrain.analysis.areas import surface_area, volume

    sq, rt, _ = pair
    poly = [(500500.0, 4999900.0), (504900.0, 4999700.0), (504000.0, 4998900.0),
            (501000.0, 4999000.0)]
    for kw in ({}, {"max_error": 40.0}):
        a, b = surface_area(sq, poly, **kw), surface_area(rt, poly, **kw)
        assert (b.area_2d, b.area_3d, b.nodata_area, b.bound_3d) == \
            (a.area_2d, a.area_3d, a.nodata_area, a.bound_3d) and b.area_3d > b.area_2d > 0
        va, vb = volume(sq, poly, base=300.0, **kw), volume(rt, poly, base=300.0, **kw)
        assert (vb.cut, vb.fill, vb.bound) == (va.cut, va.fill, va.bound) and vb.cut > 0
    assert max(surface_area(rt, poly, max_error=40.0).levels) > 0


def test_viewsheds_and_lines_of_sight_are_the_squares(pair):
    """A viewshed over both roots, the void and the raster's last row (which the root
    grid's last tile row holds as its far border; the square has a tile row of its own
    there): at level 0 the square store's codes. Read from level 2, every certain answer
    is level 0's on both stores (they differ only in which cells stay uncertain: the
    square reads its last row at level 0, its level-2 tile there having no finite error).
    Lines of sight across the roots' shared edge: the square's answers."""
    from geoterrain.analysis.sweep import HIDDEN, VISIBLE
    from geoterrain.analysis.visibility import line_of_sight, viewshed

    sq, rt, _ = pair
    obs = (502600.0, 4999100.0)  # near the roots' shared edge (column 256), row 90
    a = viewshed(sq, obs, 2500.0, 10.0)
    b = viewshed(rt, obs, 2500.0, 10.0)
    assert b.codes.shape == a.codes.shape and b.codes.shape[0] == 129  # every row
    np.testing.assert_array_equal(b.codes, a.codes)
    assert (b.codes == VISIBLE).sum() > 1000 and (b.codes == HIDDEN).sum() > 1000
    assert b.transform == a.transform and b.observer == a.observer
    for t in (sq, rt):
        c = viewshed(t, obs, 2500.0, 10.0, level=2).codes
        sure = (c == VISIBLE) | (c == HIDDEN)
        assert sure.mean() > 0.5
        np.testing.assert_array_equal(c[sure], b.codes[sure])
    for p, q in (((500200.0, 4999900.0), (505000.0, 4998800.0)),
                 ((504000.0, 4998720.0), (501000.0, 4999500.0))):
        la, lb = line_of_sight(sq, p, q, 5.0, 5.0), line_of_sight(rt, p, q, 5.0, 5.0)
        assert (lb.visible, lb.certain, lb.clearance, lb.obstruction) == \
            (la.visible, la.certain, la.clearance, la.obstruction)


@pytest.fixture(scope="module")
def geo_pair(tmp_path_factory):
    """A 129 × 513 fBm in EPSG:4326 (0.002°, 10–11.03° E, 61.0–61.26° N; a nodata void
    in the east root) on the square and on 2 × 1 roots of 32-sample tiles."""
    d = tmp_path_factory.mktemp("georootanalysis")
    z = np.rint(generate("fbm", 513, seed=8, relief=600.0)[:129, :513] * 10) / 10
    z = z.astype(np.float32)
    z[60:75, 380:420] = -9999.0
    dem = write_geotiff(d / "geo.tif", z, crs="EPSG:4326", origin=(10.0, 61.26),
                        spacing=0.002, nodata=-9999.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert rt.grid.roots == (2, 1) and rt.frame.kind == "geographic"
    return sq, rt


def test_a_geographic_root_grids_analysis_is_the_squares(geo_pair):
    """Heights (level 0, and their bound at level 2), normals, a geodesic profile,
    contours, an area and a volume, a viewshed and a line of sight over both roots of a
    geographic root grid: the square store's answers."""
    from geoterrain.analysis.areas import surface_area, volume
    from geoterrain.analysis.visibility import line_of_sight, viewshed

    sq, rt = geo_pair
    rng = np.random.default_rng(3)
    xy = np.column_stack([rng.uniform(10.001, 11.02, 2000), rng.uniform(61.005, 61.255, 2000)])
    a, b = height_at(sq, xy), height_at(rt, xy)
    np.testing.assert_array_equal(a.height, b.height)
    assert np.isfinite(b.height).sum() > 1500 and (xy[:, 0] > 10.513).sum() > 500
    b2 = height_at(rt, xy, 2)
    ok = np.isfinite(b.height) & np.isfinite(b2.height)
    assert (np.abs(b2.height[ok] - b.height[ok]) <= b2.bound[ok] + 1e-9).all()
    np.testing.assert_array_equal(normal_at(sq, xy).normal, normal_at(rt, xy).normal)
    line = [(10.01, 61.25), (11.0, 61.1), (10.6, 61.01)]
    pa, pb = profile(sq, line), profile(rt, line)
    np.testing.assert_array_equal(pa.height, pb.height)
    np.testing.assert_array_equal(pa.distance, pb.distance)
    ca, cb = contours(sq, 50.0), contours(rt, 50.0)
    assert len(cb.lines) == len(ca.lines) > 10
    for la, lb in zip(ca.lines, cb.lines, strict=True):
        np.testing.assert_array_equal(la, lb)
    poly = [(10.1, 61.24), (10.9, 61.22), (10.85, 61.03), (10.2, 61.05)]
    sa, sb = surface_area(sq, poly), surface_area(rt, poly)
    assert (sb.area_2d, sb.area_3d, sb.nodata_area) == (sa.area_2d, sa.area_3d, sa.nodata_area)
    assert volume(rt, poly, base=300.0).cut == volume(sq, poly, base=300.0).cut > 0
    obs = (10.512, 61.08)  # near the roots' shared edge (column 256)
    va, vb = viewshed(sq, obs, 20000.0, 10.0), viewshed(rt, obs, 20000.0, 10.0)
    np.testing.assert_array_equal(vb.codes, va.codes)
    p, q = (10.05, 61.2), (10.95, 61.05)
    la, lb = line_of_sight(sq, p, q, 5.0, 5.0), line_of_sight(rt, p, q, 5.0, 5.0)
    assert (lb.visible, lb.certain, lb.clearance) == (la.visible, la.certain, la.clearance)

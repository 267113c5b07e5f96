"""height_at and normal_at against a bilinear read of the source raster (numpy oracle)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import real_dem, write_tif
from geoterrain.analysis import height_at, normal_at
from geoterrain.testing.analysisref import bilinear_reference
from tests.analysis.stores import read_source, source_dems, store_of


def _random_points(t, n, rng):
    """n points over the raster's extent: uniform, plus sample centres and edges."""
    a, _, c, _, e, f = t.frame.transform[:6]
    H, W = t.grid.rows, t.grid.cols
    k = n - n // 5
    fj = rng.uniform(-0.5, W - 0.5, k)
    fi = rng.uniform(-0.5, H - 0.5, k)
    ci = rng.integers(0, H, n // 10).astype(float)  # on sample centres
    cj = rng.integers(0, W, n // 10).astype(float)
    ei = np.r_[np.full(n // 20, -0.5), np.full(n // 20, H - 0.5)]  # on the extent's edge
    ej = rng.uniform(-0.5, W - 0.5, n // 10)
    fi, fj = np.r_[fi, ci, ei], np.r_[fj, cj, ej]
    return np.column_stack([a * (fj + 0.5) + c, e * (fi + 0.5) + f])


@pytest.mark.parametrize("name", source_dems())
def test_height_at_is_the_source_raster_read_bilinear(tmp_path_factory, name):
    src = real_dem(name)
    t = store_of(tmp_path_factory, src)
    z, valid, tr = read_source(src)
    tr = tr or t.frame.transform  # PNG tiles: the store's pixel grid
    pts = _random_points(t, 10_000, np.random.default_rng(47))
    got = height_at(t, pts)
    want = bilinear_reference(z, valid, tr, pts)
    assert np.array_equal(np.isnan(got.height), np.isnan(want))  # NaN exactly at nodata
    ok = ~np.isnan(want)
    eps = t.quantizer.codec_error
    assert np.abs(got.height[ok] - want[ok]).max(initial=0) <= eps
    assert (got.bound[ok] == eps).all() and (got.level == 0).all()
    assert got.stats["tiles_decoded"] <= len(t.tile_info)


def _holed(tmp_path, eps=None, scattered=True):
    rng = np.random.default_rng(5)
    from geoterrain.ingest.synth import generate

    z = generate("fbm", 200, seed=9)[:181, :]  # not 2^n + 1: padded
    if scattered:
        z = np.where(rng.random(z.shape) < 0.002, -9999.0, z)  # scattered voids
    z[40:60, 100:130] = -9999.0  # and a lake of them
    src = write_tif(tmp_path / "holed.tif", z.astype(np.float32), nodata=-9999.0)
    p = geoterrain.preprocess(src, tmp_path / "holed.geoterrain", tile_size=32,
                              codec_error=eps)
    return geoterrain.open(p), src


@pytest.mark.fast
@pytest.mark.parametrize("eps", [None, 0.25])
def test_nodata_and_codec_error(tmp_path, eps):
    t, src = _holed(tmp_path, eps)
    z, valid, tr = read_source(src)
    pts = _random_points(t, 4000, np.random.default_rng(1))
    got = height_at(t, pts)
    want = bilinear_reference(z, valid, tr, pts)
    assert np.array_equal(np.isnan(got.height), np.isnan(want))
    ok = ~np.isnan(want)
    err = np.abs(got.height[ok] - want[ok]).max()
    assert err <= (eps or 0.0) + 1e-9
    if eps:
        assert err > 0  # a lossy store does differ, within ε
        assert got.bound[ok].max() == pytest.approx(eps)


@pytest.fixture(scope="module")
def holed(tmp_path_factory):
    return _holed(tmp_path_factory.mktemp("holed"), scattered=False)  # a lake of voids


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), level=st.integers(1, 3))
def test_coarse_level_is_within_its_bound(holed, seed, level):
    t, src = holed
    z, valid, tr = read_source(src)
    pts = _random_points(t, 500, np.random.default_rng(seed))
    got = height_at(t, pts, level=level)
    want = bilinear_reference(z, valid, tr, pts)
    assert np.array_equal(np.isnan(got.height), np.isnan(want))
    ok = ~np.isnan(want)
    assert (np.abs(got.height[ok] - want[ok]) <= got.bound[ok] + 1e-9).all()
    assert (got.level[ok] <= level).all() and (got.level[ok] == level).any()


@pytest.mark.fast
def test_coarse_level_reads_only_its_tiles(holed):
    t, _ = holed
    t.clear_cache()
    a, _, c, _, e, f = t.frame.transform[:6]
    pts = np.array([[c + a * 150.5, f + e * 20.5]])  # far from nodata
    top = t.grid.top_level
    got = height_at(t, pts, level=top)
    # the level's tile, and the tile whose δ gives the bound: a δ read is checked against
    # its own tile's heights (a swapped or edited-down δ is refused, tests/store/test_redteam)
    assert got.level.tolist() == [top] and got.stats["tiles_decoded"] == 2


@pytest.mark.fast
def test_outside_and_lonlat(holed):
    t, _ = holed
    a, _, c, _, e, f = t.frame.transform[:6]
    pts = np.array([[c + a * 10.2, f + e * 10.7], [c - 5 * a, f], [c, f - e * 1e6]])
    got = height_at(t, pts)
    assert np.isfinite(got.height[0]) and np.isnan(got.height[1:]).all()
    assert got.stats["outside"] == 2
    from pyproj import Transformer

    tr = Transformer.from_crs(t.frame.crs_wkt, "EPSG:4326", always_xy=True)
    ll = np.column_stack(tr.transform(pts[:1, 0], pts[:1, 1]))
    assert height_at(t, ll, crs="lonlat").height[0] == pytest.approx(got.height[0], abs=1e-6)


@pytest.mark.fast
def test_bad_points_and_crs_are_one_line_errors(holed):
    t, _ = holed
    from geoterrain.exceptions import UsageError

    for bad, kw in [([[1, 2, 3]], {}), ([[np.nan, 1]], {}), ([[1, 2]], {"crs": "EPSG:999999"}),
                    ([[1, 2]], {"level": 99})]:
        with pytest.raises(UsageError) as exc:
            height_at(t, bad, **kw)
        assert "\n" not in str(exc.value)


@pytest.mark.fast
@pytest.mark.parametrize("geo", [False, True])
def test_normal_slope_aspect_of_a_plane(tmp_path, geo):
    # z = 0.1 x (m): rises to the east, so the slope faces west (aspect 270°)
    H = W = 33
    if geo:
        kw = dict(crs="EPSG:4326", origin=(10.0, 45.0), spacing=1 / 3600)
        lat = 45.0 - (np.arange(H) + 0.5) / 3600
        lon = 10.0 + (np.arange(W) + 0.5) / 3600
        from pyproj import Geod

        _, _, d = Geod(ellps="WGS84").inv(np.full(W, 10.0), np.full(W, lat[16]), lon,
                                          np.full(W, lat[16]))
        x = np.broadcast_to(d, (H, W))
    else:
        kw = dict(spacing=10.0)
        x = np.broadcast_to(np.arange(W) * 10.0, (H, W))
    src = write_tif(tmp_path / "p.tif", 0.1 * x, **kw)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "p.geoterrain", tile_size=16))
    a, _, c, _, e, f = t.frame.transform[:6]
    pts = np.array([[c + a * 16.3, f + e * 16.6]])
    got = normal_at(t, pts)
    tol = 1e-3 if geo else 1e-9
    assert got.slope[0] == pytest.approx(np.degrees(np.arctan(0.1)), rel=tol)
    assert got.aspect[0] == pytest.approx(270.0, abs=0.1 if geo else 1e-9)
    assert np.allclose(got.normal[0], np.array([-0.1, 0, 1]) / np.sqrt(1.01), atol=tol)


@pytest.mark.fast
@pytest.mark.parametrize("n, said", [(1, "point 0 (5, 5) lies outside"),
                                     (2, "point 0 (5, 5) and 1 more lie outside"),
                                     (3, "point 0 (5, 5) and 2 more lie outside")])
def test_outside_error_agrees_in_number(holed, n, said):
    from geoterrain.analysis.points import outside_error

    t, _ = holed
    xy = np.full((n, 2), 5.0)
    msg = str(outside_error(t.frame, t.grid, xy, None, np.ones(n, bool)))
    assert said in msg and "\n" not in msg

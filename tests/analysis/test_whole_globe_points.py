"""Heights and slopes on a whole-globe grid: no edge at 180°.

A grid whose columns span 360° wraps (``Frame.columns_per_turn``): between its last column
and its first lies the half cell either side of 180°, and any longitude lies on it. The
oracle is a bilinear read of the same raster with its first column appended after the last
(an independent numpy reference), at the point's longitude taken into [−180°, 180°).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from pyproj import Geod

import geoterrain
from conftest import write_tif
from geoterrain.analysis import height_at, normal_at
from geoterrain.exceptions import InputError
from geoterrain.testing.analysisref import bilinear_reference

CELL = 2.0  # degrees: 90 × 180 cells, from −180° and 90°


def _world(lat, lon):
    # east-west slopes cross 180° (sin(lon / 2) jumps there: 1 at 180°, −1 at −180°)
    return (1500 * np.sin(lon / 2) * np.cos(lat) + 700 * np.cos(3 * lat)
            + 300 * np.cos(2 * lon)).astype(np.float32)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    d = tmp_path_factory.mktemp("wrapworld")
    lat = np.radians(90 - CELL / 2 - CELL * np.arange(int(180 / CELL)))[:, None]
    lon = np.radians(-180 + CELL / 2 + CELL * np.arange(int(360 / CELL)))[None, :]
    z = _world(lat, lon)
    tif = write_tif(d / "world.tif", z, crs="EPSG:4326", origin=(-180.0, 90.0),
                    spacing=CELL)
    store = geoterrain.preprocess(tif, d / "world.geoterrain")
    # the same globe one column short of a turn: it has edges
    part = geoterrain.preprocess(
        write_tif(d / "part.tif", z[:, :-1], crs="EPSG:4326", origin=(-180.0, 90.0),
                  spacing=CELL), d / "part.geoterrain")
    return d, store, part, z


def _oracle(z, lon, lat):
    """Bilinear on z with column 0 again after the last, longitudes into [−180°, 180°)."""
    zz = np.concatenate([z, z[:, :1]], axis=1)
    lon = np.mod(lon + 180.0, 360.0) - 180.0
    # the half cell west of the first column centre lies east of the appended column
    lon = np.where(lon < -180.0 + CELL / 2, lon + 360.0, lon)
    tr = (CELL, 0, -180.0, 0, -CELL, 90.0)
    return bilinear_reference(zz.astype(np.float64), np.ones(zz.shape, bool), tr,
                              np.column_stack([lon, lat]))


def test_heights_across_180_interpolate_the_last_and_first_columns(world):
    _, store, _, z = world
    rng = np.random.default_rng(5)
    # the strip either side of 180°, every latitude, and anywhere given past ±180°
    lon = np.r_[rng.uniform(180 - CELL / 2, 180, 300), rng.uniform(-180, -180 + CELL / 2, 300),
                rng.uniform(-540, 540, 400), [180.0, -180.0, 540.0]]
    lat = np.r_[rng.uniform(-90, 90, lon.size - 3), [0.0, 10.0, -45.0]]
    with geoterrain.open(store) as t:
        got = height_at(t, np.column_stack([lon, lat]))
        want = _oracle(z, lon, lat)
        assert np.isfinite(got.height).all()
        np.testing.assert_allclose(got.height, want, rtol=0, atol=1e-9)
        assert (got.bound == 0).all() and (got.level == 0).all()
        # a coarser level answers the strip at level 0, and the rest within its bound
        coarse = height_at(t, np.column_stack([lon, lat]), level=t.grid.top_level)
        assert (np.abs(coarse.height - want) <= coarse.bound + 1e-9).all()
        strip = (np.abs(np.mod(lon + 180.0, 360.0) - 180.0) > 180 - CELL / 2) | (
            np.mod(lon + 180.0, 360.0) < CELL / 2)
        assert (coarse.level[strip] == 0).all() and (coarse.bound[strip] == 0).all()
        # 180° and −180° are one meridian
        assert got.height[-3] == pytest.approx(float(height_at(t, (-180.0, 0.0)).height[0]))


def test_slopes_anywhere_on_the_globe_are_the_ground_s_from_true_north(world):
    """Slope and aspect against geodesic finite differences of the oracle's surface: on a
    whole globe, far from the scene plane's centre and across 180°, where that plane turns
    away from north (aspects were off by up to 160° when the gradient was taken on it)."""
    from pyproj import Geod

    _, store, _, z = world
    rng = np.random.default_rng(11)
    lon = np.r_[rng.uniform(-180, 180, 150), rng.uniform(180 - CELL / 2, 180, 50)]
    lat = rng.uniform(-70, 70, lon.size)
    # the point's own cell: fractional rows/columns 0.02 … 0.98, so the differences stay in it
    fj = np.mod(lon + 180.0, 360.0) / CELL - 0.5
    fi = (90.0 - lat) / CELL - 0.5
    keep = (np.abs(fj - np.round(fj)) > 0.02) & (np.abs(fi - np.round(fi)) > 0.02)
    lon, lat = lon[keep], lat[keep]
    g = Geod(ellps="WGS84")
    d = 0.01  # degrees
    ex = g.inv(lon - d, lat, lon + d, lat)[2]
    ny = g.inv(lon, lat - d, lon, lat + d)[2]
    gx = (_oracle(z, lon + d, lat) - _oracle(z, lon - d, lat)) / ex
    gy = (_oracle(z, lon, lat + d) - _oracle(z, lon, lat - d)) / ny
    want_slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    want_aspect = np.degrees(np.arctan2(-gx, -gy)) % 360.0
    with geoterrain.open(store) as t:
        got = normal_at(t, np.column_stack([lon, lat]))
    assert np.isfinite(got.slope).all()
    np.testing.assert_allclose(got.slope, want_slope, rtol=0.02, atol=1e-4)
    steep = want_slope > 0.005
    turn = np.abs((got.aspect - want_aspect + 180.0) % 360.0 - 180.0)
    assert steep.sum() > 100 and turn[steep].max() < 3.0, turn[steep].max()


def test_a_grid_short_of_a_turn_keeps_its_edges(world):
    _, _, part, _ = world
    with geoterrain.open(part) as t:
        got = height_at(t, np.array([[179.0, 0.0], [177.5, 0.0], [-181.0, 0.0]]))
    assert np.isnan(got.height[0]) and np.isfinite(got.height[1]) and np.isnan(got.height[2])


def test_query_answers_across_180_and_refuses_past_a_part_globe(world):
    from geoterrain.cli.main import cli

    _, store, part, z = world
    r = CliRunner()
    res = r.invoke(cli, ["-q", "query", str(store), "--at", "179.9,12.5", "--at", "185,12.5",
                         "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    want = _oracle(z, np.array([179.9, 185.0]), np.array([12.5, 12.5]))
    np.testing.assert_allclose([r["height_m"] for r in rows], want, atol=1e-6)
    res = r.invoke(cli, ["query", str(part), "--at", "185,12.5"])
    assert res.exit_code == 1 and "outside the data" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_a_profile_crosses_180_on_the_short_geodesic(world):
    _, store, part, z = world
    from geoterrain.analysis import profile

    with geoterrain.open(store) as t:
        a = profile(t, [(178.0, 10.0), (-178.0, 10.0)], spacing=20_000)
        b = profile(t, [(178.0, 10.0), (182.0, 10.0)], spacing=20_000)  # the same line
        geod_m = float(Geod(ellps="WGS84").inv(178.0, 10.0, -178.0, 10.0)[2])
        assert a.summary["length_m"] == pytest.approx(geod_m, rel=1e-9)
        assert geod_m < 500_000  # 4° of longitude, not 356°
        assert b.summary["length_m"] == pytest.approx(geod_m, rel=1e-9)
        np.testing.assert_allclose(b.height, a.height, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.height, _oracle(z, a.xy[:, 0], a.xy[:, 1]), rtol=0,
                                   atol=1e-9)
        # the samples cross: east of 178°, then west of −178°
        assert (np.abs(a.xy[:, 0]) >= 178.0 - 1e-9).all()
        assert (a.xy[:, 0] > 0).any() and (a.xy[:, 0] < 0).any()
    with geoterrain.open(part) as t, pytest.raises(InputError, match="outside"):
        profile(t, [(178.0, 10.0), (182.0, 10.0)], spacing=20_000)

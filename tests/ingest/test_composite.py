"""Sources of different resolutions and CRSs merged onto one grid (issue 45,
geoterrain.ingest.composite), on synthetic heights with a known formula.

A 1 m source inside a 30 m one: the 1 m samples are kept exactly where the 1 m source is
valid; its voids and the rest are the 30 m source warped by GDAL (bilinear), whose error
against the formula is within bilinear interpolation's own bound h²/8 (|f_xx| + |f_yy|)
inside the 30 m samples' hull; across the seam the merged surface steps by no more than
that error. The streaming preprocess writes the store the whole read writes.
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import from_origin

from geoterrain.cli.main import cli
from geoterrain.exceptions import UsageError
from geoterrain.ingest.composite import needs_composite, plan
from geoterrain.ingest.raster import read_raster
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.preprocessing.test_streaming import _assert_same_store

X0, Y0 = 500000.0, 5000000.0
A, LX, LY, SLOPE = 20.0, 150.0, 200.0, 0.01


def f(x, y):
    """Known heights (metres) at scene offsets x, y (metres east, north of X0, Y0)."""
    return 100 + A * np.sin(x / LX) * np.cos(y / LY) + SLOPE * x


# bilinear interpolation's error bound on a grid of spacing h: h²/8 (max|f_xx| + max|f_yy|)
def bilinear_bound(h):
    return h * h / 8 * (A / LX**2 + A / LY**2)


def _write(path, res, n, x0, y0, nodata=None, holes=None, dtype="float32", crs="EPSG:32633"):
    xs = x0 + (np.arange(n) + 0.5) * res
    ys = y0 - (np.arange(n) + 0.5) * res
    z = f(xs[None, :] - X0, ys[:, None] - Y0)
    z = np.round(z).astype(dtype) if dtype.startswith("int") else z.astype(dtype)
    if holes is not None:
        z[holes] = nodata
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype=dtype,
                       crs=crs, transform=from_origin(x0, y0, res, res), nodata=nodata) as ds:
        ds.write(z, 1)
    return str(path)


@pytest.fixture
def lidar_in_national(tmp_path):
    """A 30 m source, 16 × 16 samples, and a 1 m one of 100 × 100 inside it with a
    10 × 10 void (each with its own nodata)."""
    coarse = _write(tmp_path / "national_30m.tif", 30.0, 16, X0, Y0, nodata=-9999)
    fine = _write(tmp_path / "lidar_1m.tif", 1.0, 100, X0 + 180, Y0 - 180, nodata=-32768,
                  holes=(slice(40, 50), slice(40, 50)))
    return coarse, fine


def _scene(r):
    t = r.transform
    H, W = r.shape
    xs = t[2] + (np.arange(W) + 0.5) * t[0] - X0
    ys = t[5] + (np.arange(H) + 0.5) * t[4] - Y0
    return f(xs[None, :], ys[:, None])


@pytest.mark.fast
def test_a_1m_source_inside_a_30m_one_merges(lidar_in_national):
    coarse, fine = lidar_in_national
    layers, target = plan([coarse, fine])
    assert target.transform[0] == 1.0 and (target.width, target.height) == (480, 480)
    assert layers[0].offset == (180, 180)  # the finest first, on the target grid
    r = read_raster([coarse, fine])
    F = _scene(r)
    lidar = np.zeros(r.shape, bool)
    lidar[180:280, 180:280] = True
    lidar[220:230, 220:230] = False  # its void
    assert r.valid.all()  # the void and the rest filled from the 30 m source
    # the 1 m samples exactly
    assert np.array_equal(r.heights[lidar], F[lidar].astype(np.float32).astype(np.float64))
    # the 30 m source resampled: within bilinear's bound inside its samples' hull
    hull = np.zeros(r.shape, bool)
    hull[15:465, 15:465] = True
    err = np.abs(r.heights - F)[hull & ~lidar]
    assert err.max() <= bilinear_bound(30.0) + 1e-4
    # the seam: across the lidar's west edge and its void's edges the step is the true
    # slope's within the resampling's error (and float32 rounding)
    for rows, cols in ((np.s_[180:280], np.s_[178:182]), (np.s_[222:228], np.s_[218:222]),
                       (np.s_[222:228], np.s_[228:232])):
        step = np.diff(r.heights[rows, cols], axis=1) - np.diff(F[rows, cols], axis=1)
        assert np.abs(step).max() <= bilinear_bound(30.0) + 1e-4


@pytest.mark.fast
def test_priority_order_lets_the_first_source_win(lidar_in_national):
    coarse, fine = lidar_in_national
    r = read_raster([coarse, fine], priority="order")
    F = _scene(r)
    inside = np.s_[180:280, 180:280]
    # the 30 m source wins everywhere it is valid: its resampled heights, not the lidar's
    assert np.abs(r.heights[inside] - F[inside]).max() > 1e-3
    assert np.abs(r.heights[inside] - F[inside]).max() <= bilinear_bound(30.0) + 1e-4


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_a_merge_streams_to_the_whole_read_s_store(tmp_path, lidar_in_national):
    """The warped layer read a VRT block at a time: bands and the whole raster give the
    same bits, so the streamed store is the whole one's (bilinear and cubic)."""
    coarse, fine = lidar_in_national
    for rs in ("bilinear", "cubic"):
        a = preprocess([coarse, fine], tmp_path / f"a{rs}.gt", tile_size=32, resampling=rs)
        b = preprocess_streaming([coarse, fine], tmp_path / f"b{rs}.gt", tile_size=32, band=16,
                                 resampling=rs)
        _assert_same_store(a, b)


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_sources_in_two_crss_merge_onto_a_declared_grid(tmp_path):
    """A UTM source and a geographic one over the same ground, merged onto EPSG:4326 at a
    declared resolution (both warped): the same store whole and streamed, every sample
    valid, heights within the coarser source's resampling error of the formula."""
    utm = _write(tmp_path / "utm.tif", 20.0, 40, X0, Y0, nodata=-9999)
    with rasterio.open(utm) as ds:
        from rasterio.warp import transform_bounds

        w, s, e, n = transform_bounds(ds.crs, "EPSG:4326", *ds.bounds)
    deg = (e - w) / 30
    z = np.full((30, 30), 150.0, np.float32)
    with rasterio.open(tmp_path / "geo.tif", "w", driver="GTiff", width=30, height=30, count=1,
                       dtype="float32", crs="EPSG:4326", transform=from_origin(w, n, deg, deg),
                       nodata=-9999) as ds:
        ds.write(z, 1)
    kw = dict(crs="EPSG:4326", resolution=deg / 2, tile_size=16)
    a = preprocess([utm, str(tmp_path / "geo.tif")], tmp_path / "a.gt", **kw)
    b = preprocess_streaming([utm, str(tmp_path / "geo.tif")], tmp_path / "b.gt", band=8, **kw)
    _assert_same_store(a, b)
    r = read_raster([utm, str(tmp_path / "geo.tif")], crs="EPSG:4326", resolution=deg / 2)
    assert r.valid.mean() > 0.9


@pytest.mark.fast
def test_one_source_reprojected_by_crs_and_resolution(tmp_path):
    src = _write(tmp_path / "a.tif", 10.0, 30, X0, Y0)
    assert needs_composite([src], resolution=20.0) and not needs_composite([src])
    r = read_raster(src, resolution=20.0)
    assert r.shape == (15, 15) and r.transform[0] == 20.0


@pytest.mark.fast
def test_bad_merge_arguments_are_one_line_usage_errors(tmp_path, lidar_in_national):
    coarse, fine = lidar_in_national
    for kw, why in ((dict(resampling="lanczos9"), "resampling"), (dict(priority="x"), "priority"),
                    (dict(resolution=-1.0), "resolution"), (dict(crs="EPSG:0"), "CRS")):
        with pytest.raises(UsageError, match=why) as e:
            read_raster([coarse, fine], **kw)
        assert "\n" not in str(e.value)
    run = CliRunner().invoke(cli, ["preprocess", coarse, fine, "-o", str(tmp_path / "o.gt"),
                                   "--resampling", "lanczos9"])
    assert run.exit_code == 2 and "Traceback" not in run.output


def test_the_cli_merges_with_resolution_and_priority(tmp_path, lidar_in_national):
    coarse, fine = lidar_in_national
    run = CliRunner().invoke(cli, ["-q", "preprocess", fine, coarse, "-o",
                                   str(tmp_path / "m.gt"), "--resolution", "2",
                                   "--resampling", "cubic", "--priority", "order"])
    assert run.exit_code == 0, run.output
    import geoterrain

    with geoterrain.open(tmp_path / "m.gt") as t:
        assert (t.grid.rows, t.grid.cols) == (240, 240)

"""`export-raster --what hillshade|slope` against gdaldem itself (Debian's gdal-bin, `make
gdal`): the same DEM, sun, z-factor and scale; compared on the interior pixels (gdaldem
leaves the border as nodata without -compute_edges). Skipped when gdaldem is absent.

Cases: srtm1_japan as it is (geographic: gdaldem's convention -s 111120, which is this
export's default scale there) and srtm1_japan warped to UTM 54N (float32, bilinear), plus a
synthetic projected fBm for the multidirectional shading and the slope.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio

import geoterrain
from geoterrain.export.rasters import Relief, export_raster
from tests.conftest import real_dem

GDALDEM = shutil.which("gdaldem")
needs_gdaldem = pytest.mark.skipif(GDALDEM is None, reason="gdaldem not installed (make gdal)")


def gdaldem(*args) -> None:
    subprocess.run([GDALDEM, *map(str, args), "-q"], check=True, capture_output=True)


def _read(path):
    with rasterio.open(path) as r:
        return r.read(1), r.nodata


def _interior_agreement(ours_path, ref_path, tol: float) -> tuple[float, int]:
    """The share of interior pixels (both have data) within ``tol`` and their count."""
    a, na = _read(ours_path)
    b, nb = _read(ref_path)
    assert a.shape == b.shape
    ok = np.ones(a.shape, bool)
    ok[[0, -1], :] = ok[:, [0, -1]] = False
    for arr, nd in ((a, na), (b, nb)):
        ok &= np.isfinite(arr.astype(np.float64))
        if nd is not None and np.isfinite(nd):
            ok &= arr != nd
    diff = np.abs(a.astype(np.float64) - b.astype(np.float64))[ok]
    return float((diff <= tol).mean()), int(ok.sum())


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    src = real_dem("srtm1_japan.tif")
    d = tmp_path_factory.mktemp("gdaldem")
    t = geoterrain.open(geoterrain.preprocess(src, d / "japan.geoterrain"))
    yield t, src, d
    t.close()


@pytest.fixture(scope="module")
def japan_utm(tmp_path_factory):
    """srtm1_japan warped to UTM 54N at 30 m (float32, bilinear; nodata outside)."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    src = real_dem("srtm1_japan.tif")
    d = tmp_path_factory.mktemp("gdaldem_utm")
    out = d / "japan_utm.tif"
    with rasterio.open(src) as s:
        tr, w, h = calculate_default_transform(s.crs, "EPSG:32654", s.width, s.height,
                                               *s.bounds, resolution=30.0)
        z = np.full((h, w), -9999.0, np.float32)
        reproject(s.read(1).astype(np.float32), z, src_transform=s.transform, src_crs=s.crs,
                  dst_transform=tr, dst_crs="EPSG:32654", resampling=Resampling.bilinear,
                  src_nodata=None, dst_nodata=-9999.0)
        prof = dict(driver="GTiff", width=w, height=h, count=1, dtype="float32",
                    crs="EPSG:32654", transform=tr, nodata=-9999.0)
    with rasterio.open(out, "w", **prof) as dst:
        dst.write(z, 1)
    t = geoterrain.open(geoterrain.preprocess(out, d / "japan_utm.geoterrain"))
    yield t, out, d
    t.close()


@needs_gdaldem
@pytest.mark.parametrize("sun", [(315.0, 45.0), (200.0, 25.0)])
def test_hillshade_matches_gdaldem_geographic(japan, sun):
    t, src, d = japan
    ours, ref = d / f"ours_{sun[0]:g}.tif", d / f"ref_{sun[0]:g}.tif"
    export_raster(t, "hillshade", ours, relief=Relief(*sun), overwrite=True)
    # gdaldem's convention for a geographic DEM in metres
    gdaldem("hillshade", src, ref, "-az", sun[0], "-alt", sun[1], "-s", 111120)
    share, n = _interior_agreement(ours, ref, 1.0)
    print(f"hillshade: {100 * share:.3f} % of {n} interior pixels within 1 grey level")
    assert n > 700_000
    assert share >= 0.99, f"{100 * share:.3f} % within 1 grey level"


@needs_gdaldem
def test_hillshade_matches_gdaldem_utm(japan_utm):
    t, src, d = japan_utm
    ours, ref = d / "ours.tif", d / "ref.tif"
    export_raster(t, "hillshade", ours, relief=Relief(315.0, 45.0, z_factor=2.0))
    gdaldem("hillshade", src, ref, "-az", 315, "-alt", 45, "-z", 2)
    share, n = _interior_agreement(ours, ref, 1.0)
    print(f"hillshade: {100 * share:.3f} % of {n} interior pixels within 1 grey level")
    assert n > 500_000
    assert share >= 0.99, f"{100 * share:.3f} % within 1 grey level"


@needs_gdaldem
def test_multidirectional_and_slope_match_gdaldem(japan_utm):
    t, src, d = japan_utm
    export_raster(t, "hillshade", d / "m.tif", relief=Relief(altitude=40.0,
                                                             multidirectional=True))
    gdaldem("hillshade", src, d / "m_ref.tif", "-multidirectional", "-alt", 40)
    share, _ = _interior_agreement(d / "m.tif", d / "m_ref.tif", 1.0)
    assert share >= 0.99, f"multidirectional: {100 * share:.3f} % within 1 grey level"
    for units, flag in (("degrees", []), ("percent", ["-p"])):
        export_raster(t, "slope", d / f"s_{units}.tif", relief=Relief(slope_units=units))
        gdaldem("slope", src, d / f"s_{units}_ref.tif", *flag)
        share, _ = _interior_agreement(d / f"s_{units}.tif", d / f"s_{units}_ref.tif", 1e-3)
        assert share >= 0.999, f"slope in {units}: {100 * share:.3f} % within 0.001"


def test_error_raster_holds_no_inf(japan):
    """srtm1_japan's δ is unbounded at the vertices every mesh keeps (0.5 % of them): the
    error GeoTIFF has nodata there, never inf (a GIS stretch breaks on inf). Needs no
    gdaldem."""
    t, _, d = japan
    raw = t.gather(np.array([0, 0]), np.array([512, 883]), ("delta",))["delta"]
    assert np.isinf(raw).all()  # the case this test is about
    export_raster(t, "error", d / "e.tif", overwrite=True)
    with rasterio.open(d / "e.tif") as r:
        e = r.read(1)
        assert np.isnan(r.nodata)
    assert not np.isinf(e).any()
    assert np.isnan(e[0, [512, 883]]).all() and np.isfinite(e).mean() > 0.99

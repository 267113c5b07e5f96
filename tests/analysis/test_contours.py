"""contours against gdal_contour: the same closed and open lines per level, within half a
cell; coarser levels within their bound."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

import geoterrain
from conftest import real_dem, write_tif
from geoterrain.analysis import contours, write_contours
from geoterrain.exceptions import UsageError
from geoterrain.testing.analysisref import bilinear_reference, contour_comparison
from tests.analysis.stores import read_source, store_of

GDAL = shutil.which("gdal_contour")
needs_gdal = pytest.mark.skipif(GDAL is None, reason="gdal_contour absent (make gdal)")


def _gdal_lines(src, out, interval, extra=()):
    import shapely
    from pyogrio.raw import read

    subprocess.run([GDAL, "-q", "-i", repr(interval), "-a", "elev", *extra, str(src),
                    str(out)], check=True)
    meta, _, geom, fields = read(out)
    elev = fields[meta["fields"].tolist().index("elev")]
    return [shapely.get_coordinates(g) for g in shapely.from_wkb(geom)], elev


def _compare(c, lines, elev, cell):
    res = contour_comparison(c.lines, c.heights, lines, elev)
    for h, (ours, theirs, d) in res.items():
        assert ours == theirs, (h, ours, theirs)
        assert d <= 0.5 * cell, (h, d)
    return res


@needs_gdal
def test_gdal_contour_on_srtm1_japan(tmp_path_factory, tmp_path):
    src = real_dem("srtm1_japan.tif")
    t = store_of(tmp_path_factory, src)
    c = contours(t, 50.0)
    res = _compare(c, *_gdal_lines(src, tmp_path / "g.gpkg", 50.0), abs(t.frame.transform[0]))
    assert len(res) >= 30 and max(d for *_, d in res.values()) < 1e-6


@needs_gdal
@pytest.mark.fast
def test_gdal_contour_with_voids_and_an_offset(tmp_path):
    from geoterrain.ingest.synth import generate

    z = generate("fbm", 129, seed=5)[:100, :117].astype(np.float32) * 0.5
    z[30:41, 50:70] = -9999.0
    z[z.shape[0] // 2, 3] = -9999.0
    z[70, 80] = 400.0  # a sample on a level
    src = write_tif(tmp_path / "v.tif", z, nodata=-9999.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "v.geoterrain", tile_size=16))
    c = contours(t, 20.0, base=5.0)
    lines, elev = _gdal_lines(src, tmp_path / "g.gpkg", 20.0, ("-off", "5"))
    _compare(c, lines, elev, 10.0)
    assert c.stats["tiles_decoded"] > 0


@needs_gdal
@pytest.mark.slow
def test_gdal_contour_on_4097_fbm(tmp_path):
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "fbm.tif", generate("fbm", 4097, seed=7), spacing=10.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "fbm.geoterrain"))
    c = contours(t, 100.0)
    _compare(c, *_gdal_lines(src, tmp_path / "g.gpkg", 100.0), 10.0)


@pytest.fixture(scope="module")
def smooth(tmp_path_factory):
    """A 257² DEM (no padding, no nodata): every tile of every level has a bound."""
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("ct")
    src = write_tif(d / "s.tif", generate("fbm", 257, seed=8).astype(np.float32) * 0.2)
    return geoterrain.open(geoterrain.preprocess(src, d / "s.geoterrain", tile_size=32)), src


@pytest.mark.fast
@pytest.mark.parametrize("e", [7.0, 15.0])
def test_coarse_level_vertices_are_within_the_bound(smooth, e):
    t, src = smooth
    c = contours(t, 25.0, max_error=e)
    assert c.level > 0 and c.bound <= e and c.unbounded == 0
    z, valid, tr = read_source(src)
    pts = np.concatenate(c.lines)
    h = np.repeat(c.heights, [len(p) for p in c.lines])
    got = bilinear_reference(z, valid, tr, pts)
    # the raster's outermost half cell at level L is beyond its last samples: leave it out
    a, _, x0, _, ee, y0 = tr
    inner = ((pts[:, 0] - x0) / a > 0.5) & ((pts[:, 0] - x0) / a < z.shape[1] - 0.5) & \
        ((pts[:, 1] - y0) / ee > 0.5) & ((pts[:, 1] - y0) / ee < z.shape[0] - 0.5)
    assert np.abs(got - h)[inner].max() <= c.bound + 1e-9


@pytest.mark.fast
def test_tiles_without_a_level_are_not_decoded(smooth):
    t, _ = smooth
    t.clear_cache()
    lo = min(v["zmin"] for v in t.tile_info.values())
    c = contours(t, levels=[lo + 1.0])
    assert c.stats["tiles_skipped"] > 0 and len(c.lines) > 0
    assert c.stats["tiles_decoded"] < len(t.tile_info)


@pytest.mark.fast
@pytest.mark.parametrize("name", ["c.gpkg", "c.geojson"])
def test_write_contours(smooth, tmp_path, name):
    from pyogrio.raw import read

    t, _ = smooth
    c = contours(t, 50.0)
    p = write_contours(c, tmp_path / name, t.frame.crs_wkt)
    meta, _, geom, fields = read(p)
    assert len(geom) == len(c.lines) and meta["geometry_type"] == "LineString"
    assert np.array_equal(fields[0], c.heights)
    with pytest.raises(UsageError, match="exists"):
        write_contours(c, p, t.frame.crs_wkt)
    with pytest.raises(UsageError, match="gpkg"):
        write_contours(c, tmp_path / "c.shp", t.frame.crs_wkt)
    assert not list(tmp_path.glob(".*partial*"))


@pytest.mark.fast
def test_bad_intervals_are_one_line_errors(smooth):
    t, _ = smooth
    for kw in ({"interval": 0.0}, {"interval": -5.0}, {"interval": 1e-9},
               {"interval": 10.0, "max_error": -1.0}, {"levels": []}):
        with pytest.raises(UsageError) as info:
            contours(t, **kw)
        assert "\n" not in str(info.value)

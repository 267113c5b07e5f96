"""The flat scene refuses what it cannot flatten honestly (over ~1 000 km, or reaching a
pole), in one line naming the globe; ``preprocess`` still accepts such rasters."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from pyproj import CRS

from geoterrain.core.frame import Frame, check_flat
from geoterrain.exceptions import InputError
from tests.conftest import write_tif

WGS84 = CRS.from_epsg(4326).to_wkt()


@pytest.mark.parametrize("transform, rows, cols, why", [
    ((0.25, 0, -180, 0, -0.25, 90), 720, 1440, "north and south poles"),  # the whole globe
    ((0.1, 0, 0, 0, -0.1, 90), 100, 300, "north pole"),  # an Arctic cap
    ((0.1, 0, 0, 0, -0.1, -80), 100, 300, "south pole"),
    ((0.05, 0, -10, 0, -0.05, 60), 580, 1100, "km, over the 1,000 km"),  # a continent
    ((0.01, 0, 10, 0, -0.01, 46), 100, 1300, "km, over the 1,000 km"),  # 13° wide at 46°N
])
def test_too_wide_or_polar_geographic_frames_are_refused(transform, rows, cols, why):
    fr = Frame.from_raster(transform, WGS84, rows, cols)
    assert why in fr.flat_problem()
    with pytest.raises(InputError, match="on the globe"):
        check_flat(fr, "x.geoterrain")


@pytest.mark.parametrize("transform, rows, cols", [
    ((1 / 3600, 0, 139.1, 0, -1 / 3600, 35.5), 868, 884),  # srtm1_japan
    ((0.01, 0, 10, 0, -0.01, 46), 100, 1000),  # 10° wide at 46°N: 774 km
    ((0.01, 0, 10, 0, -0.01, 89.0), 100, 100),  # near the pole, not reaching it
])
def test_regional_geographic_frames_pass(transform, rows, cols):
    assert Frame.from_raster(transform, WGS84, rows, cols).flat_problem() is None


def test_projected_and_pixel_frames_pass():
    fr = Frame.from_raster((10.0, 0, 500000, 0, -10.0, 5e6), CRS.from_epsg(32633).to_wkt(),
                           100, 100)
    assert fr.flat_problem() is None and Frame.pixel(10, 10).flat_problem() is None


def test_a_whole_globe_raster_preprocesses_and_the_flat_render_refuses_it(tmp_path):
    from geoterrain.cli.main import cli

    lat = np.radians(89 - 2 * np.arange(90))[:, None]
    lon = np.radians(-179 + 2 * np.arange(180))[None, :]
    z = (2000 * np.sin(3 * lon) * np.cos(2 * lat) + 500 * np.cos(lat)).astype(np.float32)
    tif = write_tif(tmp_path / "world.tif", z, crs="EPSG:4326", origin=(-180.0, 90.0),
                    spacing=2.0)
    store = tmp_path / "world.geoterrain"
    r = CliRunner()
    res = r.invoke(cli, ["preprocess", str(tif), "-o", str(store)],
                   catch_exceptions=False)
    assert res.exit_code == 0, res.output
    for args in (["render", str(store), "-o", str(tmp_path / "w.png")],
                 ["mesh", str(store), "-o", str(tmp_path / "w.ply"), "--max-error", "10"],
                 ["export", str(store), "-o", str(tmp_path / "w.glb")]):
        res = r.invoke(cli, args, catch_exceptions=False)
        assert res.exit_code == 1, res.output
        err = res.stderr.strip().splitlines()
        assert len(err) == 1 and "render --globe" in err[0] and "poles" in err[0], res.stderr
        assert "Traceback" not in res.output
    assert not list(tmp_path.glob("w.*"))  # nothing half-written

"""Units: feet from the CRS, warnings that name the fix, web-map tiles at true size."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from geoterrain.core.frame import Frame
from geoterrain.exceptions import UsageError
from geoterrain.ingest.units import (
    crs_z_units,
    parse_tile,
    resolve_z_units,
    tile_from_path,
    tile_georeference,
)

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def test_feet_from_the_crs_and_warnings(caplog):
    assert crs_z_units("EPSG:3089") == ("us-ft", "horizontal")
    assert crs_z_units("EPSG:2227+6360") == ("us-ft", "vertical")  # CA zone 3 + NAVD88 ftUS
    assert crs_z_units("EPSG:4326") == (None, None)
    with caplog.at_level(logging.WARNING, "geoterrain"):
        assert resolve_z_units("auto", "EPSG:3089") == "us-ft"
        assert "--z-units m" in caplog.text
        caplog.clear()
        assert resolve_z_units("m", "EPSG:3089") == "m"
        assert "--z-units us-ft" in caplog.text
        caplog.clear()
        assert resolve_z_units("auto", "EPSG:32633") == "m"
        assert resolve_z_units("auto", None) == "m"
        assert caplog.text == ""
    with pytest.raises(UsageError):
        resolve_z_units("yards", None)


@pytest.mark.parametrize("z,x,y", [(12, 3626, 1617), (9, 100, 200), (14, 8000, 6000)])
def test_web_tile_has_true_ground_size(z, x, y):
    from pyproj import Geod

    transform, wkt = tile_georeference(z, x, y, 256, 256)
    f = Frame.from_raster(transform, wkt, 256, 256)
    X, Y = f.xy(np.array([127.5, 127.5, 0, 255]), np.array([0, 255, 127.5, 127.5]))
    # the ground distance across the tile's middle (pyproj's geodesic, independent maths)
    from pyproj import Transformer

    tr = Transformer.from_crs(wkt, "EPSG:4326", always_xy=True)
    a, c, e = transform[0], transform[2], transform[4]
    fy = transform[5] + e * 128
    lon0, lat0 = tr.transform(c + a * 0.5, fy)
    lon1, lat1 = tr.transform(c + a * 255.5, fy)
    ground = Geod(ellps="WGS84").inv(lon0, lat0, lon1, lat1)[2]
    assert abs((X[1] - X[0]) - ground) < 0.01 * ground
    # square pixels on the ground: north-south extent matches east-west
    assert abs((Y[2] - Y[3]) - (X[1] - X[0])) < 0.01 * ground


def test_tile_names():
    assert tile_from_path("a/12/3626/1617.png") == (12, 3626, 1617)
    assert tile_from_path("12_3626_1617.png") == (12, 3626, 1617)
    assert tile_from_path("fuji.png") is None
    assert parse_tile("3/1/2") == (3, 1, 2)
    for bad in ("3/8/1", "x/y/z", "1/2"):
        with pytest.raises(UsageError):
            parse_tile(bad)

"""profile: samples, ground distances (geodesic on geographic grids), heights, outputs."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import real_dem
from geoterrain.analysis import height_at, plot_profile, profile, write_profile_csv
from geoterrain.exceptions import InputError, UsageError
from tests.analysis.stores import store_of


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    return store_of(tmp_path_factory, real_dem("srtm1_japan.tif"))


@pytest.mark.fast
def test_geodesic_distances_and_heights(japan):
    from pyproj import Geod

    line = [(139.12, 35.30), (139.25, 35.45), (139.34, 35.35)]
    p = profile(japan, line, spacing=30.0)
    geod = Geod(ellps="WGS84")
    x, y = p.xy[:, 0], p.xy[:, 1]
    _, _, d = geod.inv(x[:-1], y[:-1], x[1:], y[1:])
    assert np.allclose(np.diff(p.distance), d, rtol=1e-12)
    assert np.diff(p.distance).max() <= 30.0 + 1e-6
    assert np.diff(p.distance)[np.diff(p.distance) < 29.0].size <= 2  # the segments' ends
    # the vertices are samples, and the length is the polyline's geodesic length
    assert np.allclose(p.xy[p.vertex], line)
    length = sum(geod.inv(*line[k], *line[k + 1])[2] for k in range(2))
    assert p.summary["length_m"] == pytest.approx(length, rel=1e-6)
    assert np.array_equal(p.height, height_at(japan, p.xy).height, equal_nan=True)
    assert p.summary["ascent"] > 0 and p.stats["tiles_decoded"] <= len(japan.tile_info)


@pytest.mark.fast
def test_lonlat_and_coarse_level(japan):
    a = profile(japan, [(139.15, 35.3), (139.3, 35.4)], spacing=100.0, crs="lonlat",
                level=2)
    b = profile(japan, [(139.15, 35.3), (139.3, 35.4)], spacing=100.0)
    assert np.allclose(a.distance, b.distance)
    ok = np.isfinite(b.height)
    assert (np.abs(a.height[ok] - b.height[ok]) <= a.bound[ok]).all()


@pytest.mark.fast
def test_outputs(japan, tmp_path):
    p = profile(japan, [(139.15, 35.3), (139.3, 35.4)], spacing=200.0)
    csv = write_profile_csv(p, tmp_path / "p.csv")
    rows = csv.read_text().splitlines()
    assert rows[0] == "distance_m,x,y,height_m,bound_m,level" and len(rows) == len(p.height) + 1
    got = np.array([float(r.split(",")[3]) for r in rows[1:]])
    assert np.allclose(got, p.height)
    png = plot_profile(p, tmp_path / "p.png", title="t")
    from PIL import Image

    assert Image.open(png).size == (1200, 500)
    with pytest.raises(UsageError, match="exists"):
        write_profile_csv(p, csv)


@pytest.mark.fast
def test_bad_lines_are_one_line_errors(japan):
    for line, kw, exc, word in [([(139.2, 35.3)], {}, UsageError, "two vertices"),
                                ([(139.2, 35.3), (139.2, 35.3)], {}, UsageError, "no length"),
                                ([(139.2, 35.3), (140.5, 35.3)], {}, InputError, "outside"),
                                ([(139.2, 35.3), (139.3, 35.3)], {"spacing": 0}, UsageError,
                                 "spacing")]:
        with pytest.raises(exc, match=word) as info:
            profile(japan, line, **kw)
        assert "\n" not in str(info.value)

"""`info`'s size report: bytes per component, and the DEFLATE + predictor GeoTIFF reference."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

import geoterrain
from geoterrain.preprocessing import preprocess
from geoterrain.storesize import component_bytes, size_report
from tests.conftest import write_tif


def _int_dem(tmp_path):
    rng = np.random.default_rng(5)
    z = np.cumsum(rng.integers(-3, 4, (90, 77)), axis=1) + 300
    z[:4, :9] = -32768
    return write_tif(tmp_path / "d.tif", z.astype(np.int16), nodata=-32768)


def test_components_add_up_to_the_file(tmp_path):
    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    with geoterrain.open(store) as t:
        c = component_bytes(t)
    assert sum(c.values()) == os.path.getsize(store)
    assert all(v > 0 for v in c.values()), c


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_reference_is_the_source_written_with_deflate_and_predictor(tmp_path):
    dem = _int_dem(tmp_path)
    store = preprocess(dem, tmp_path / "d.geoterrain")
    # the same heights written here independently: same bytes as the report's reference
    with rasterio.open(dem) as s:
        data = s.read(1)
    prof = dict(driver="GTiff", height=90, width=77, count=1, dtype="int16", nodata=-32768,
                compress="deflate", predictor=2)
    with rasterio.open(tmp_path / "ref.tif", "w", **prof) as d:
        d.write(data, 1)
    with geoterrain.open(store) as t:
        r = size_report(t)
    assert r["geotiff_dtype"] == "int16"
    assert r["geotiff_deflate_bytes"] == os.path.getsize(tmp_path / "ref.tif")
    assert r["ratio"] == r["store_bytes"] / r["geotiff_deflate_bytes"]


def test_info_prints_the_size_line(tmp_path):
    from geoterrain.cli.main import cli

    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    res = CliRunner().invoke(cli, ["info", str(store)])
    assert res.exit_code == 0, res.output
    line = next(ln for ln in res.output.splitlines() if ln.startswith("size "))
    assert "heights" in line and "normals" in line and "DEFLATE+predictor GeoTIFF" in line
    res = CliRunner().invoke(cli, ["info", str(store), "--json", "--no-reference"])
    i = json.loads(res.output)
    assert "ratio" not in i["size"] and sum(i["size"]["components"].values()) == i["size_bytes"]

"""The analysis commands: answers, files, and one line (exit 2 usage, 1 data) for bad
input: points outside the data, an empty polygon, a bad CRS, an observer in nodata."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from conftest import write_tif

pytestmark = pytest.mark.fast


def run(*args):
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def one_line(res, code):
    assert res.exit_code == code, res.output
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("Error:"), res.stderr
    assert "Traceback" not in res.output
    return err[0]


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("cmd")
    z = generate("fbm", 129, seed=11)[:120].astype(np.float32) * 0.3
    z[50:60, 40:55] = -9999.0
    src = write_tif(d / "d.tif", z, nodata=-9999.0)
    p = geoterrain.preprocess(src, d / "d.geoterrain", tile_size=32)
    t = geoterrain.open(p)
    a, _, c, _, e, f = t.frame.transform[:6]
    t.close()
    return p, (lambda col, row: f"{c + a * (col + 0.5)!r},{f + e * (row + 0.5)!r}")


def test_query_points(store, tmp_path):
    p, at = store
    res = run("query", p, "--at", at(10, 10), "--at", at(45, 55), "--slope")
    assert res.exit_code == 0, res.output
    lines = res.stdout.strip().splitlines()
    assert "height_m" in lines[0] and "slope_deg" in lines[0] and "nodata" in lines[2]
    csv = tmp_path / "pts.csv"
    csv.write_text("x,y\n" + at(3, 4) + "\n" + at(100, 30) + "\n")
    out = tmp_path / "h.csv"
    res = run("query", p, "--points", csv, "-o", out)
    assert res.exit_code == 0 and len(out.read_text().splitlines()) == 3
    assert "tiles decoded" in res.stderr


def test_query_polygon(store):
    p, at = store
    ring = [at(10, 10), at(80, 12), at(70, 90), at(10, 10)]
    wkt = "POLYGON ((" + ", ".join(r.replace(",", " ") for r in ring) + "))"
    res = run("query", p, "--polygon", wkt, "--base", "fit", "--json")
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    assert d["area_2d_m2"] > 0 and d["nodata_area_m2"] > 0
    assert d["net_m3"] == pytest.approx(d["cut_m3"] - d["fill_m3"])


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_profile_and_viewshed_and_contours(store, tmp_path):
    p, at = store
    line = f"LINESTRING ({at(5, 5).replace(',', ' ')}, {at(120, 100).replace(',', ' ')})"
    res = run("profile", p, "--line", line, "-o", tmp_path / "p.csv", "--plot",
              tmp_path / "p.png")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "p.png").stat().st_size > 10_000
    res = run("viewshed", p, "--observer", at(20, 20), "--radius", 500, "-o", tmp_path / "v.tif")
    assert res.exit_code == 0, res.output
    import rasterio

    with rasterio.open(tmp_path / "v.tif") as r:
        assert set(np.unique(r.read(1)).tolist()) <= {0, 1, 254, 255}
    res = run("contours", p, "--interval", 100, "-o", tmp_path / "c.gpkg")
    assert res.exit_code == 0 and "lines" in res.stderr


@pytest.mark.parametrize("args,code,word", [
    (["query", "{p}", "--at", "1,2"], 1, "outside the data"),
    (["query", "{p}", "--at", "1,2", "--crs", "EPSG:999999"], 2, "unknown CRS"),
    (["query", "{p}", "--at", "1,2", "--lonlat", "--crs", "EPSG:4326"], 2, "either"),
    (["query", "{p}", "--at", "abc"], 2, "X,Y"),
    (["query", "{p}"], 2, "nothing to ask"),
    (["query", "{p}", "--polygon", "POLYGON EMPTY"], 2, "empty"),
    (["query", "{p}", "--polygon", "POLYGON ((0 0, 1 1, 1 0, 0 1, 0 0))"], 2, "not valid"),
    (["query", "{p}", "--polygon", "POLYGON ((0 0, 1 0, 1 1, 0 0))"], 1, "outside"),
    (["profile", "{p}", "--line", "LINESTRING (0 0, 1 1)", "-o", "{tmp}/x.csv"], 1, "outside"),
    (["profile", "{p}", "--line", "POINT (0 0)", "-o", "{tmp}/x.csv"], 2, "LINESTRING"),
    (["profile", "{p}", "--line", "LINESTRING (0 0, 1 1)", "--crs", "nope", "-o",
      "{tmp}/x.csv"], 2, "unknown CRS"),
    (["viewshed", "{p}", "--observer", "{void}", "--radius", "100", "-o", "{tmp}/v.tif"], 1,
     "nodata"),
    (["viewshed", "{p}", "--observer", "0,0", "--radius", "100", "-o", "{tmp}/v.tif"], 1,
     "outside"),
    (["viewshed", "{p}", "--observer", "{ok}", "--radius", "-5", "-o", "{tmp}/v.tif"], 2,
     "radius"),
    (["viewshed", "{p}", "--observer", "{ok}", "--radius", "100", "--crs", "EPSG:0", "-o",
      "{tmp}/v.tif"], 2, "CRS"),
    (["contours", "{p}", "--interval", "0", "-o", "{tmp}/c.gpkg"], 2, "interval"),
    (["contours", "{p}", "-o", "{tmp}/c.gpkg"], 2, "--interval"),
    (["contours", "{p}", "--interval", "10", "-o", "{tmp}/c.shp"], 2, "gpkg"),
])
def test_bad_input_is_one_line(store, tmp_path, args, code, word):
    p, at = store
    args = [a.format(p=p, tmp=tmp_path, void=at(47, 55), ok=at(20, 20)) for a in args]
    assert word in one_line(run(*args), code)
    assert not list(tmp_path.glob("*")) or all(not f.name.startswith(".")
                                                for f in tmp_path.glob("*"))

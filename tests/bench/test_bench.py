"""The benchmark harness: `geoterrain bench` and geoterrain.bench.harness."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from geoterrain.bench import harness as bench
from geoterrain.bench.report import COLUMNS
from geoterrain.cli.main import cli
from geoterrain.exceptions import InputError, UsageError
from geoterrain.lod import STRATEGIES, strategy_info


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_cli_synthetic_csv_plot_table(tmp_path):
    out, png = tmp_path / "b.csv", tmp_path / "b.png"
    r = CliRunner().invoke(cli, ["-q", "bench", "--synthetic", "65", "--views", "4",
                                 "--pixel-error", "1,4", "-o", str(out), "--plot", str(png)])
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 4 * len(STRATEGIES) * 2
    assert set(rows[0]) == set(COLUMNS)
    for row in rows:
        assert (not strategy_info(row["strategy"]).bounded
                or float(row["err_max"]) <= float(row["tau"]) * (1 + 1e-9) + 1e-9)
        assert math.isfinite(float(row["select_ms"]))
        assert float(row["preprocess_s"]) > 0 and int(row["store_bytes"]) > 0
    assert png.stat().st_size > 10_000
    assert "| rtin | 1 |" in r.output


@pytest.mark.fast
def test_cli_store_and_path(tmp_path, fbm_tif):
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    cams = tmp_path / "cams.json"
    cams.write_text(json.dumps([{"look_from": [0, -2000, 1500], "look_at": [0, 0, 0]},
                                {"look_from": [500, 0, 300], "look_at": [0, 0, 0], "fov": 60}]))
    r = CliRunner().invoke(cli, ["-q", "bench", str(store), "--path", str(cams),
                                 "--pixel-error", "2", "--strategies", "rtin",
                                 "-o", str(tmp_path / "p.csv")])
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader((tmp_path / "p.csv").open()))
    assert [row["view"] for row in rows] == ["path", "path"]
    assert rows[0]["preprocess_s"] == ""  # a store is not preprocessed again
    assert {row["anti_aliasing"] for row in rows} == {""}  # nothing drawn


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_cli_render_csv_names_the_anti_aliasing(tmp_path, fbm_tif):
    """The CSV says how each frame's picture was anti-aliased (its render_ms depends on it)."""
    pytest.importorskip("geoterrain.rendering.scene")
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    for aa in ("fxaa", "msaa"):
        out = tmp_path / f"{aa}.csv"
        r = CliRunner().invoke(cli, ["-q", "bench", str(store), "--views", "2", "--render",
                                     "--anti-aliasing", aa, "--pixel-error", "2",
                                     "--strategies", "rtin", "-o", str(out)])
        assert r.exit_code == 0, r.output
        rows = list(csv.DictReader(out.open()))
        assert len(rows) == 2 and {row["anti_aliasing"] for row in rows} == {aa}
        assert all(float(row["render_ms"]) > 0 for row in rows)


@pytest.mark.fast
@pytest.mark.parametrize("args,code", [
    ([], 2),
    (["--synthetic", "65", "x.tif"], 2),
    (["--synthetic", "65", "--pixel-error", "0"], 2),
    (["--synthetic", "65", "--strategies", "nosuchstrategy"], 2),
    (["missing.tif"], 2),
    (["--synthetic", "65", "--plot", "b.jpg"], 2),
])
def test_cli_bad_input(tmp_path, args, code):
    r = CliRunner().invoke(cli, ["-q", "bench", *args])
    assert r.exit_code == code
    assert "Traceback" not in r.output


@pytest.mark.fast
def test_bad_cameras_json_is_input_error(tmp_path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps([{"look_from": [0, 0, 0], "look_at": [0, 0, 0]}]))
    with pytest.raises(InputError):
        bench.load_path(p)
    p.write_text("not json")
    with pytest.raises(InputError):
        bench.load_path(p)


@pytest.mark.fast
def test_flight_kinds_and_usage_error():
    v = bench.flight((-1, -1, 0), (1, 1, 0), n_views=8)
    assert [k for k, _ in v][:4] == list(bench.VIEW_KINDS)
    for _, view in v:
        assert np.isfinite(view.planes).all()
    with pytest.raises(UsageError):
        bench.flight((0, 0, 0), (1, 1, 1), n_views=0)


@pytest.mark.fast
def test_peers_match_rtin_static(tmp_path, fbm_tif):
    pytest.importorskip("pymartini")
    t = geoterrain.open(geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain"))
    rows, notes = bench.peers(t, [1.0, 4.0])
    by = {(r["method"], r["target_m"]): r for r in rows}
    for E in (1.0, 4.0):
        assert by[("rtin-static", E)]["err_max_m"] <= E * (1 + 1e-9) + 1e-9
        assert by[("rtin-static", E)]["uncovered"] == 0
        if ("pydelatin", E) in by:  # delatin's bound is a true maximum error too
            assert by[("pydelatin", E)]["err_max_m"] <= E + 1e-3 * E + 1e-4
        assert by[("pymartini", E)]["uncovered"] == 0


def test_run_with_render_times_frames(tmp_path, fbm_tif):
    pytest.importorskip("geoterrain.rendering.scene")
    t = geoterrain.open(geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain"))
    res = bench.run(t, n_views=2, taus=(2.0,), strategies=("rtin",), render=True)
    assert len(res.rows) == 2
    assert all(math.isfinite(r["render_ms"]) and r["render_ms"] > 0 for r in res.rows)

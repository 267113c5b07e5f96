"""Seed 000's experiments (``geoterrain bench --experiment``): every row has the thesis's
figures beside it, one anti-aliasing mode per run, the flight, and a small run end to end."""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner

from geoterrain.bench import experiments as ex
from geoterrain.bench.thesis000 import TABLES


def invoke(*args):
    # imported here, as tests/test_cli.py does (geoterrain.cli is mapped on install)
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, list(args))


@pytest.mark.fast
def test_every_row_quotes_the_thesis():
    for name, e in ex.EXPERIMENTS.items():
        rows = ex.configs(name)
        assert rows and {c.table for c in rows} <= set(e.tables)
        for c in rows:
            th = c.thesis()
            assert th is not None, (name, c)
            # the reference row of each group is part of the experiment
            assert any(r.table == c.table and r.setting == c.reference for r in rows)


@pytest.mark.fast
def test_the_quoted_tables_match_the_original_text():
    """Spot checks against the thesis's own lines (seed 000's original)."""
    assert TABLES["6-20"]["rows"][9] == ("Highland", "BF", (50, 120, 379, 33))
    assert TABLES["6-5"]["rows"][12] == ("Highland", "17", (122, 215, 579, 63))
    assert TABLES["6-13"]["rows"][7] == ("GTR", "32", (189, 273, 1843, 553))
    assert TABLES["6-3"]["rows"][0][2][2] is None  # Valley's missing fourth figure
    assert all(len(v) == 4 for t in TABLES.values() for _, _, v in t["rows"])


@pytest.mark.fast
def test_the_minute_flight_stays_above_the_terrain_and_loops():
    v = ex.minute_flight((0, 0, 0), (1000, 800, 300), 12)
    assert len(v) == 13 and v[0][0] == 0.0 and v[1][0] == 5.0 and v[-1][0] == 60.0
    eyes = np.array([w.eye for _, w in v])
    assert (eyes[:, 2] > 300).all()
    steps = np.linalg.norm(np.diff(eyes[1:], axis=0), axis=1)
    assert np.allclose(steps, steps[0])  # evenly over the minute
    assert np.linalg.norm(eyes[-1] - eyes[0]) < 1e-6 * 1000  # 60 s: back at the start


@pytest.mark.fast
def test_no_culling_view_keeps_everything():
    v = ex._NoCulling((0, 0, 100), (0, 1000, 0))
    assert v.planes.shape == (0, 4)
    lo, hi = np.array([[-1e6, -1e6, 0]]), np.array([[-1e6 + 1, -1e6 + 1, 1]])
    assert v.box_visibility(lo, hi)[0] == 2  # INSIDE: nothing is culled


def test_a_small_run_end_to_end(tmp_path):
    res = ex.run_experiment("spatial-coherence", terrains=("Valley",), frames=1,
                            work_dir=tmp_path, scale=8)
    assert res.anti_aliasing == "msaa" and len(res.rows) == 4
    by = {(r["table"], r["setting"]): r for r in res.rows}
    assert by[("6-15", "SkirtsOptimized")]["ratio"] == pytest.approx(1.0)
    assert all(r["fps"] > 0 and r["frames"] == 1 for r in res.rows)
    assert any("6-14" in n for n in res.notes)
    text = ex.format_result(res)
    assert "msaa" in text.splitlines()[0]
    p = ex.write_result_csv(res, tmp_path / "e.csv")
    assert p.read_text().splitlines()[0].startswith("table,group,setting")


@pytest.mark.fast
def test_cli_lists_and_refuses_clearly():
    r = invoke("bench", "--experiment", "list")
    assert r.exit_code == 0 and "algorithm (Tables 6-20)" in r.output
    r = invoke("bench", "--experiment", "algorithm", "--anti-aliasing", "auto")
    assert r.exit_code == 2 and "one --anti-aliasing mode" in r.output
    r = invoke("bench", "--experiment", "nope")
    assert r.exit_code == 2 and re.search("unknown experiment 'nope'", r.output)
    r = invoke("bench", "--experiment", "algorithm", "--terrains", "Moon")
    assert r.exit_code == 2 and "unknown terrain 'Moon'" in r.output


@pytest.mark.fast
def test_thesis_ratios_print_as_the_docs_divide():
    # Table 6-20, Highland on N2: GMM 195 / BF 120 = 1.625, which the docs write 1.63
    rows = [{"table": "6-20", "group": "Highland", "setting": s, "algorithm": s,
             "strategy": ex.ALGORITHMS[s], "terrain": "Highland", "fps": 1.0, "triangles": 1,
             "thesis": th, "reference": "BF"}
            for s, th in (("BF", (50, 120, 379, 33)), ("GMM", (53, 195, 409, 30)))]
    ex._ratios(rows)
    out = ex.format_result(ex.ExperimentResult("algorithm", rows, "msaa", 0.0, []))
    assert out.splitlines()[-1].endswith("0.91–1.63")

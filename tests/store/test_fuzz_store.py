"""The store mutation fuzzer (tests/store/storefuzz.py): clean errors or identical output only."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff

sys.path.insert(0, str(Path(__file__).parent))
from storefuzz import run_cases  # noqa: E402


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 65, seed=5))
    return geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16), d


def _check(res: dict) -> None:
    assert "worker_error" not in res, res.get("worker_error")
    assert not res["wrong"], f"silently wrong: {res['wrong'][:5]}"
    assert not res["internal"], f"internal errors: {res['internal'][:5]}"
    assert not res["hang"], f"hangs: {res['hang'][:5]}"
    assert not res["oom"], f"out of memory: {res['oom'][:5]}"
    assert res["peak_rss_kb"] < 2 * res["base_rss_kb"], res
    assert res["clean_error"] > 0 and res["identical"] >= 0


def test_fuzz_short(pristine):
    store, d = pristine
    res = run_cases(store, 300, seed=1, workdir=d)
    assert res.get("cases") == 300, res
    _check(res)


def test_fuzz_short_padded(tmp_path_factory):
    """The same on a DEM that leaves padding: its second δ (delta_edge blobs, some on
    unstored tiles, and their metadata list) is mutated too."""
    d = tmp_path_factory.mktemp("fuzzpad")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 65, seed=6)[:40, :50])
    store = geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=8)
    assert geoterrain.open(store).edge_max
    res = run_cases(store, 200, seed=3, workdir=d)
    assert res.get("cases") == 200, res
    _check(res)


@pytest.mark.slow
def test_fuzz_long(pristine):
    store, d = pristine
    res = run_cases(store, 10_000, seed=2, workdir=d)
    print({k: (v if not isinstance(v, list) else len(v)) for k, v in res.items()})
    assert res.get("cases") == 10_000, res
    _check(res)

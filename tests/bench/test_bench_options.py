"""Options of the benchmark scripts that a reader relies on, run on a small store:
``bench_render.py --pictures DIR`` writes pictures with ``--skip-bruteforce`` too, and
``bench_edit.py``'s warm-up edits by tiles, the timed edits' path."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import geoterrain

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture
def script(monkeypatch):
    """A benchmark script loaded as a module (its ``main`` not run)."""
    monkeypatch.syspath_prepend(str(BENCH))

    def load(stem: str):
        name = f"_bench_options_{stem}"
        spec = importlib.util.spec_from_file_location(name, BENCH / f"{stem}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        sys.modules.pop(name, None)
        return module

    return load


def test_bench_render_writes_the_strategies_pictures_without_bruteforce(tmp_path, fbm_tif,
                                                                          script):
    from PIL import Image

    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain", tile_size=16)
    pics = tmp_path / "pics"
    out = script("bench_render").main([str(store), "--views", "3", "--size", "96x64",
                                       "--brute-every", "2", "--skip-bruteforce",
                                       "--pictures", str(pics)])
    # the views bruteforce would have been drawn on (0 and 2), rtin's pictures only
    assert sorted(p.name for p in pics.iterdir()) == ["rtin_00.png", "rtin_02.png"]
    for p in pics.iterdir():
        img = np.asarray(Image.open(p))
        assert img.shape[:2] == (64, 96) and img.std() > 0  # a drawn terrain, not a blank
    assert [r["strategy"] for r in out["runs"]] == ["rtin"]
    assert out["runs"][0]["summary"]["psnr_to_bruteforce"] == []  # nothing to compare with
    assert "--skip-bruteforce" in script("bench_render").__doc__.split("--pictures DIR")[1]


def test_bench_edit_warms_the_by_tiles_path(tmp_path, script):
    """The parent's warm-up edit goes by tiles, as the timed children's edits do; an edit
    at the data's corner (the warm-up before) went to the whole grid on this store, so the
    first timed edit by tiles compiled its kernels."""
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.edit import Patch, edit_terrain

    dem = write_geotiff(tmp_path / "dem.tif", generate("fbm", 257, seed=0))
    store = str(geoterrain.preprocess(dem, tmp_path / "s.geoterrain"))
    before = Path(store).read_bytes()
    res = script("bench_edit").warm_up(store, str(tmp_path), 65)
    assert res.how == "tiles", res.why
    assert Path(store).read_bytes() == before  # a copy was edited, and removed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif", "s.geoterrain"]
    corner = tmp_path / "corner.geoterrain"
    corner.write_bytes(before)
    with geoterrain.open(corner) as t:  # the old warm-up's edit, for contrast
        old = edit_terrain(t, Patch(0, 0, np.full((65, 65), -20.0)), "add")
    assert old.how == "whole grid"

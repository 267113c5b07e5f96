"""The first run: the kernels not cached yet are found from the files alone, the command
line says so once with an estimate and a bar, and is silent when the cache is warm."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from geoterrain.core import warmup


@pytest.mark.fast
def test_cold_kernels_follow_the_cache_folder(tmp_path, monkeypatch):
    every = sum(len(warmup.kernels(f)) for f in warmup.PACKAGE.rglob("*.py")
                if "cache=True" in f.read_text())
    assert every > 100
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # an empty cache: every one cold
    cold = warmup.cold_kernels(["geoterrain"])
    assert len(cold) == every
    assert "geoterrain.rendering.tileshade._shade_tiles" in cold
    # an inlined helper has no cache of its own: never counted
    assert "geoterrain.rendering.tileshade._texel" not in cold
    assert warmup.estimate_seconds(every) >= 60


@pytest.mark.fast
def test_compile_watch_counts_numba_compilations():
    from numba import njit

    seen = []
    with warmup.CompileWatch(seen.append) as w:
        njit(lambda x: x + 1)(1)  # compiled now (not cached: a lambda)
    assert w.done >= 1 and seen[-1] == w.done


@pytest.mark.fast
def test_first_run_says_so_once(tmp_path, monkeypatch, fbm_tif):
    from geoterrain.cli.main import cli

    monkeypatch.setattr(warmup, "cold_kernels", lambda mods: ["geoterrain.x.a", "geoterrain.x.b"])
    res = CliRunner().invoke(cli, ["info", "--help"])
    assert "compiling" not in res.output  # --help compiles nothing
    res = CliRunner().invoke(cli, ["synth", "fbm", "--size", "33", "-o", str(tmp_path / "s.tif")])
    assert "compiling" not in res.stderr  # synth compiles nothing
    res = CliRunner().invoke(cli, ["preprocess", str(fbm_tif), "-o",
                                   str(tmp_path / "a.geoterrain")])
    assert res.exit_code == 0, res.output
    assert res.stderr.count("compiling kernels (first run only, about 2 s)") == 1
    res = CliRunner().invoke(cli, ["-q", "preprocess", str(fbm_tif), "-o",
                                   str(tmp_path / "b.geoterrain")])
    assert "compiling" not in res.stderr  # -q: quiet
    monkeypatch.setattr(warmup, "cold_kernels", lambda mods: [])
    res = CliRunner().invoke(cli, ["preprocess", str(fbm_tif), "-o",
                                   str(tmp_path / "c.geoterrain")])
    assert "compiling" not in res.stderr  # a warm cache: silent

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
    # kernels reported cold, but this run loads every one it uses from the cache: silent
    # (a render never compiles the other strategies' kernels; it must not say so each time)
    res = CliRunner().invoke(cli, ["preprocess", str(fbm_tif), "-o",
                                   str(tmp_path / "a.geoterrain")])
    assert res.exit_code == 0, res.output
    assert "compiling" not in res.stderr


@pytest.mark.fast
def test_the_notice_comes_with_a_real_compilation(capsys, monkeypatch):
    from numba import njit

    from geoterrain.cli.options import CompileBar, StageBar

    monkeypatch.setattr(warmup, "cold_kernels", lambda mods: ["geoterrain.x.a", "geoterrain.x.b"])
    stages = StageBar("preprocessing", quiet=False)
    with CompileBar("preprocess", quiet=False) as bar:
        assert CompileBar.active is None  # nothing compiled yet: nothing said
        njit(lambda x: x + 1)(1)  # compiled now (a lambda is never cached)
        assert CompileBar.active is bar and not bar.compiling()
        njit(lambda x: x + 2)(1)
        stages("write", 1, 2)  # the command's own work: the compile bar gives way
        assert CompileBar.active is None
    err = capsys.readouterr().err
    assert err.count("compiling kernels (first run only, about 1 s)") == 1
    with CompileBar("preprocess", quiet=True):
        njit(lambda x: x + 3)(1)
    assert "compiling" not in capsys.readouterr().err  # -q: quiet
    monkeypatch.setattr(warmup, "cold_kernels", lambda mods: [])
    with CompileBar("preprocess", quiet=False):
        njit(lambda x: x + 4)(1)
    assert "compiling" not in capsys.readouterr().err  # a warm cache: silent


def test_edit_has_a_compile_bar_over_its_kernels(tmp_path, fbm_tif, monkeypatch, capsys):
    """``geoterrain edit`` compiles kernels on an empty cache like the other commands: it
    has a compile bar (the notice on its first compilation), and its stage folders hold
    every compiled kernel's module an edit loads (by tiles, then over the whole grid)."""
    import subprocess
    import sys
    import textwrap

    from numba import njit

    import geoterrain
    from geoterrain.cli.compilebar import COMPILING, CompileBar

    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain", tile_size=16)
    code = textwrap.dedent(f"""
        import sys
        import numpy as np
        import geoterrain
        from geoterrain.preprocessing.edit import Patch, edit_terrain
        for how in ("tiles", "whole grid"):
            with geoterrain.open({str(store)!r}) as t:
                edit_terrain(t, Patch(40, 50, np.full((9, 9), -5.0)), "add", how=how)
        print(" ".join(m for m in sys.modules if m.startswith("geoterrain.")))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=tmp_path)
    loaded = out.stdout.split()
    compiled = [m for m in loaded if (f := warmup.PACKAGE.joinpath(
        *m.split(".")[1:]).with_suffix(".py")).is_file() and "cache=True" in f.read_text()]
    assert "geoterrain.preprocessing.edit.localbounds" in compiled
    assert [m for m in compiled if not m.startswith(COMPILING["edit"])] == []
    monkeypatch.setattr(warmup, "cold_kernels", lambda mods: ["geoterrain.x.a"])
    capsys.readouterr()
    with CompileBar("edit", quiet=False):
        njit(lambda x: x + 5)(1)  # compiled now (a lambda is never cached)
    assert "compiling kernels (first run only" in capsys.readouterr().err

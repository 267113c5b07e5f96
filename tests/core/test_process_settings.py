"""Process-wide settings the package makes: GNU OpenMP's wait policy, and numpy's
huge-page advice while a whole-grid preprocess runs (core/_fork.py, core/memory.py)."""

from __future__ import annotations

import gc
import json
import os
import platform
import subprocess
import sys
import threading

import numpy as np
import pytest

from geoterrain.core.memory import collector_paused, small_pages

_SET_HP = np._core.multiarray._set_madvise_hugepage


def _policy(env: dict) -> str:
    code = "import os, geoterrain; print(os.environ.get('OMP_WAIT_POLICY'))"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, check=True).stdout.strip()


@pytest.mark.fast
def test_omp_wait_policy_passive_unless_the_environment_sets_one():
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    assert _policy(env) == "PASSIVE"
    assert _policy({**env, "OMP_WAIT_POLICY": "ACTIVE"}) == "ACTIVE"


@pytest.mark.fast
def test_small_pages_nests_and_restores_numpys_setting():
    before = _SET_HP(True)  # numpy's setting now, then True
    try:
        with small_pages():
            assert _SET_HP(False) is False  # off inside
            with small_pages():
                assert _SET_HP(False) is False
            assert _SET_HP(False) is False  # the inner exit leaves it off
        assert _SET_HP(True) is True  # restored on the last exit
        seen = []

        def inside():
            with small_pages():
                seen.append(_SET_HP(False))
                gate.wait()

        gate = threading.Barrier(3)
        ts = [threading.Thread(target=inside) for _ in range(2)]
        for t in ts:
            t.start()
        gate.wait()
        for t in ts:
            t.join()
        assert seen == [False, False] and _SET_HP(True) is True  # the last to leave restores
    finally:
        _SET_HP(before)


@pytest.mark.fast
def test_collector_paused_nests_and_restores_the_collectors_state():
    was = gc.isenabled()
    try:
        gc.enable()
        with collector_paused():
            assert not gc.isenabled()
            with collector_paused():
                assert not gc.isenabled()
            assert not gc.isenabled()  # the inner exit leaves it paused
        assert gc.isenabled()  # the last exit enables it again
        gc.disable()  # paused by someone else before: left so
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
        gc.enable()
        with pytest.raises(RuntimeError), collector_paused():  # an error: restored too
            raise RuntimeError
        assert gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


@pytest.mark.fast
def test_a_whole_grid_preprocess_runs_no_garbage_collection(tmp_path):
    """The collector is paused over a whole-grid preprocess's stages (its full collections
    over the imports' objects cost 0.2 s of a 4097² one: docs/lab/preprocess.md), and
    enabled again after it."""
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.pipeline import preprocess

    src = write_geotiff(str(tmp_path / "dem.tif"), generate("fbm", 65, seed=2))
    seen, ticks = [], []

    def count(phase, info):
        if phase == "start" and ticks and ticks[-1][0] != "write":  # between the first
            seen.append(info["generation"])  # stage's end and the last's

    def tick(name, done, total):
        ticks.append((name, gc.isenabled()))

    was, threshold = gc.isenabled(), gc.get_threshold()
    gc.enable()
    gc.callbacks.append(count)
    try:
        gc.set_threshold(1)  # without the pause: a collection at almost every allocation
        preprocess(src, tmp_path / "dem.geoterrain", tile_size=16, progress=tick)
        assert gc.isenabled()
        gc.callbacks.remove(count)
        assert len(ticks) >= 5 and not any(on for _, on in ticks), ticks
        assert seen == []
    finally:
        gc.set_threshold(*threshold)
        if count in gc.callbacks:
            gc.callbacks.remove(count)
        (gc.enable if was else gc.disable)()


@pytest.mark.fast
@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's malloc_trim")
def test_release_free_heap_returns_the_free_pages_a_live_chunk_pins():
    """64 MB of 32 KiB arrays (on the heap: under glibc's mmap threshold) freed, each
    followed by a small array that stays: the free chunks sit below live ones, so glibc
    keeps them resident until release_free_heap hands their pages back (the streamed
    preprocess calls it after each pass)."""
    code = """
import json
import numpy as np
from geoterrain.core.memory import current_rss, release_free_heap
big, keep = [], []
for _ in range(2048):
    big.append(np.ones(1 << 12))
    keep.append(np.ones(16))
del big
before = current_rss()
ok = release_free_heap()
print(json.dumps([ok, before - current_rss()]))
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    ok, freed = json.loads(run.stdout.strip().splitlines()[-1])
    assert ok and freed >= 32 << 20  # at least half of the 64 MB freed

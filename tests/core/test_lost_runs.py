"""No lost runs: racing publishes, killed writers, signals (forked workers, no imports)."""

from __future__ import annotations

import multiprocessing as mp
import os
import random
import signal
import time

import pytest

import geoterrain
from geoterrain.exceptions import UsageError
from geoterrain.ingest.synth import generate, write_geotiff

# forkserver: a fork of the test process (numba and thread pools started) could deadlock
_ctx = mp.get_context("forkserver")
_ctx.set_forkserver_preload(["geoterrain.preprocessing.pipeline", "geoterrain.cli.main"])


def _preprocess(dem, dst, q, term=False):
    if term:
        from geoterrain.cli.main import _catch_signals

        _catch_signals()
    try:
        geoterrain.preprocess(dem, dst)
        q.put("ok")
    except UsageError as exc:
        q.put("exists" if "exists" in str(exc) else str(exc))
    except KeyboardInterrupt:
        q.put("interrupted")


def _timed_run(dem, dst) -> float:
    q = _ctx.Queue()
    p = _ctx.Process(target=_preprocess, args=(dem, dst, q))
    t0 = time.perf_counter()
    p.start()
    p.join(60)
    assert q.get(timeout=5) == "ok"
    return time.perf_counter() - t0


def _race(tmp_path, trials):
    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 65, seed=1))
    for k in range(trials):
        dst = tmp_path / f"s{k}.geoterrain"
        q = _ctx.Queue()
        ps = [_ctx.Process(target=_preprocess, args=(dem, dst, q)) for _ in range(2)]
        for p in ps:
            p.start()
        for p in ps:
            p.join(60)
        got = sorted(q.get(timeout=5) for _ in ps)
        assert got == ["exists", "ok"], (k, got)
        assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name]


def test_concurrent_preprocess_one_wins(tmp_path):
    _race(tmp_path, 8)


@pytest.mark.slow
def test_concurrent_preprocess_one_wins_50(tmp_path):
    _race(tmp_path, 50)


@pytest.mark.parametrize("sig,kills", [
    (signal.SIGKILL, 4), (signal.SIGTERM, 2), (signal.SIGHUP, 2),
    pytest.param(signal.SIGKILL, 20, marks=pytest.mark.slow, id="SIGKILL-20")])
def test_killed_runs_leave_no_partial(tmp_path, sig, kills):
    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=1))
    dst = tmp_path / "s.geoterrain"
    # a whole run, timed as the killed ones run: a forked worker (the faster of two, the
    # first one starting the fork server); an in-process run, with its first calls of
    # the compiled kernels, took longer than a worker's whole run
    full = min(_timed_run(dem, tmp_path / f"timing{k}.geoterrain") for k in range(2))
    rng = random.Random(int(sig))
    partial_seen, landed = False, 0
    for _ in range(kills):
        q = _ctx.Queue()
        p = _ctx.Process(target=_preprocess, args=(dem, dst, q, sig != signal.SIGKILL))
        p.start()
        time.sleep(rng.uniform(0.5, 1.0) * full)  # late: while the store is being written
        partial_seen |= any(".partial-" in f.name for f in tmp_path.iterdir())
        try:
            os.kill(p.pid, sig)
            landed += 1
        except ProcessLookupError:
            pass  # it finished (and was reaped) first
        p.join(30)
        if dst.exists():
            dst.unlink()  # it finished first; try again
    assert landed, "every run finished before its signal"
    if sig == signal.SIGKILL:
        geoterrain.preprocess(dem, tmp_path / "next.geoterrain")  # the next run cleans up
    left = [f.name for f in tmp_path.iterdir() if ".partial-" in f.name]
    assert not left, (left, partial_seen)

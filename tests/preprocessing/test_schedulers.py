"""Schedulers (geoterrain.preprocessing.schedulers) and the streaming preprocess on each.

The store must be the same on every scheduler (the passes are pure), and a task whose
worker process is killed must be run again, on a fresh pool (``processes``) or by dask
(``dask:local``, a real LocalCluster of 2 worker processes).
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from geoterrain.exceptions import UsageError
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.schedulers import parse_scheduler, run_tasks
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.preprocessing.test_streaming import _assert_same_store, _tif


def _die_once(marker: str, value: int) -> int:
    """Kill this worker process the first time (SIGKILL: no cleanup, no exception)."""
    if not os.path.exists(marker):
        with open(marker, "w"):
            pass
        os.kill(os.getpid(), signal.SIGKILL)
    return value * 2


@pytest.mark.fast
def test_scheduler_specs():
    assert parse_scheduler("threads:3") == ("threads", 3)
    for bad in ("", "threads", "threads:0", "processes:x", "dask", "dask:local", "gpu:2"):
        with pytest.raises(UsageError, match="sync, threads:N"):
            parse_scheduler(bad)


@pytest.mark.fast
@pytest.mark.parametrize("spec", ["sync", "threads:2", "processes:2"])
def test_results_come_back_in_order(spec):
    assert run_tasks(spec, [(pow, (2, k)) for k in range(6)]) == [1, 2, 4, 8, 16, 32]


@pytest.mark.parametrize("spec", ["processes:2", "dask:local:2"])
def test_a_killed_worker_s_task_is_run_again(tmp_path, spec):
    if spec.startswith("dask"):
        pytest.importorskip("distributed")
    marker = str(tmp_path / "died")
    out = run_tasks(spec, [(_die_once, (marker, 21)), (pow, (3, 2))])
    assert out == [42, 9]
    assert os.path.exists(marker)  # the first run did die


def _dem(tmp, seed, rows, cols, holes):
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1).astype(np.float32)
    z[rng.random(z.shape) < holes] = -9999
    return _tif(tmp / "dem.tif", z, -9999)


@pytest.fixture(scope="module")
def dask_address():
    """The address of a real LocalCluster of 2 one-thread worker processes, started by
    the first example that asks (one takes about 3 s to start) and shared by the rest."""
    started = []

    def address() -> str:
        if not started:
            distributed = pytest.importorskip("distributed")
            started.append(distributed.LocalCluster(n_workers=2, threads_per_worker=1,
                                                    processes=True, dashboard_address=None))
        return started[0].scheduler_address

    yield address
    for cluster in started:
        cluster.close()


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(9, 120), cols=st.integers(9, 120),
       holes=st.sampled_from([0.0, 0.1]),
       spec=st.sampled_from(["sync", "threads:2", "processes:2", "dask"]),
       band=st.sampled_from([2, 4, 16, 64]))
@example(seed=3, rows=40, cols=33, holes=0.1, spec="dask", band=4)
@example(seed=4, rows=70, cols=21, holes=0.0, spec="processes:2", band=2)
def test_the_store_is_the_same_on_every_scheduler(tmp_path_factory, dask_address, seed, rows,
                                                  cols, holes, spec, band):
    """Bytes equal the whole-grid store's for every band size on every scheduler
    (``dask``: the shared LocalCluster, through ``dask:ADDRESS``)."""
    tmp = tmp_path_factory.mktemp("sch")
    src = _dem(tmp, seed, rows, cols, holes)
    a = preprocess(src, tmp / "a.gt", tile_size=16)
    spec = f"dask:{dask_address()}" if spec == "dask" else spec
    b = preprocess_streaming(src, tmp / "b.gt", tile_size=16, band=band, scheduler=spec)
    _assert_same_store(a, b)


def test_the_store_is_the_same_on_a_dask_local_cluster(tmp_path):
    """``dask:local:2`` starts its own LocalCluster of 2 worker processes."""
    pytest.importorskip("distributed")
    src = _dem(tmp_path, 7, 100, 90, 0.05)
    a = preprocess(src, tmp_path / "a.gt", tile_size=16)
    b = preprocess_streaming(src, tmp_path / "b.gt", tile_size=16, band=8,
                             scheduler="dask:local:2")
    _assert_same_store(a, b)


@pytest.mark.parametrize("spec", ["processes:2", "dask:local:2"])
def test_geographic_and_mosaic_input_give_the_same_store_on_every_scheduler(tmp_path, spec):
    """Issue 45: a geographic mosaic of four tiles (its x, y pass first, then the metric
    bounds) streams to the whole-grid store on worker processes and on a dask
    LocalCluster, as on ``sync``."""
    if spec.startswith("dask"):
        pytest.importorskip("distributed")
    from tests.ingest.test_mosaic import split
    from tests.preprocessing.test_streaming_inputs import _geo_tif, _relief

    z = _relief(6, 70, 80, holes=0.05)
    merged = _geo_tif(tmp_path / "m.tif", z, 179.7, 61.0, 0.01, nodata=-9999)
    tiles = [str(p) for p in split(merged, tmp_path / "tiles")]
    a = preprocess(tiles, tmp_path / "a.gt", tile_size=16,
                   root_grid=False)  # streamed: square for now
    for sched in ("sync", spec):
        b = preprocess_streaming(tiles, tmp_path / f"{sched[:4]}.gt", tile_size=16, band=8,
                                 scheduler=sched)
        _assert_same_store(a, b)


@pytest.mark.slow  # heavy (10-36 s): the full tier runs it, CI skips it
def test_no_dask_scheduler_at_an_address_is_a_usage_error(tmp_path):
    pytest.importorskip("distributed")
    with pytest.raises(UsageError, match="no dask scheduler"):
        run_tasks("dask:tcp://127.0.0.1:9", [(pow, (2, 2))])


def test_a_killed_streaming_run_leaves_no_store_and_the_next_run_cleans_up(tmp_path):
    """SIGKILL of the driver mid-run: no store at the destination (its scratch folder and
    partial store are named .NAME.*partial-PID), and the next run in that folder removes
    them and writes the store."""
    import subprocess
    import sys
    import time

    import geoterrain

    src = _dem(tmp_path, 3, 600, 500, 0.02)
    out = tmp_path / "out"
    out.mkdir()
    dst = out / "s.gt"
    code = ("from geoterrain.preprocessing.streaming import preprocess_streaming; "
            f"preprocess_streaming({src!r}, {str(dst)!r}, band=4)")
    p = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.monotonic() + 120
    while not list(out.glob(".*.scratch.partial-*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    p.kill()
    p.wait()
    assert not dst.exists()
    left = [x.name for x in out.iterdir()]
    assert left and all(".partial-" in n for n in left), left
    preprocess_streaming(src, dst, band=64)
    assert [x.name for x in out.iterdir()] == ["s.gt"]
    assert geoterrain.open(dst).tile(0, 0, 0).heights.shape == (65, 65)


def _killed_after_first_pass(src, dst, band, eps=None, first="bounds"):
    # a streaming run into dst, SIGKILLed once its first pass is recorded
    import subprocess
    import sys
    import time

    code = ("from geoterrain.preprocessing.streaming import preprocess_streaming; "
            f"preprocess_streaming({src!r}, {str(dst)!r}, band={band}, codec_error={eps})")
    p = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.monotonic() + 180
    while not list(dst.parent.glob(f".{dst.name}.scratch.partial-*/done-{first}")) \
            and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    p.kill()
    p.wait()
    assert not dst.exists(), "the run ended before it could be killed"


def test_resume_after_a_killed_driver_reuses_its_passes(tmp_path, caplog):
    """SIGKILL of the driver once its first pass is recorded; `resume` takes up that
    scratch folder, reuses the recorded pass, and writes the uninterrupted run's store.
    A run with another setting does not take it up."""
    import logging

    src = _dem(tmp_path, 5, 600, 500, 0.02)
    ref = preprocess(src, tmp_path / "ref.gt")
    out = tmp_path / "out"
    out.mkdir()
    dst = out / "s.gt"
    _killed_after_first_pass(src, dst, 4)
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        preprocess_streaming(src, dst, band=4, resume=True)
    assert "resuming a killed run; passes done: bounds" in caplog.text
    _assert_same_store(ref, dst)
    assert [x.name for x in out.iterdir()] == ["s.gt"]
    caplog.clear()
    dst.unlink()
    _killed_after_first_pass(src, dst, 4)
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        preprocess_streaming(src, dst, band=8, resume=True)  # another job: a fresh run
    assert "resuming" not in caplog.text
    _assert_same_store(ref, dst)
    assert [x.name for x in out.iterdir()] == ["s.gt"]


def test_a_lossy_run_resumes_from_its_decoded_heights(tmp_path, caplog):
    """With ε the height pass runs first and leaves the decoded heights in the scratch
    folder: a driver killed after it resumes from them (the other passes read them) to
    the uninterrupted run's store."""
    import logging

    src = _dem(tmp_path, 5, 600, 500, 0.02)
    ref = preprocess(src, tmp_path / "ref.gt", codec_error=1.0)
    out = tmp_path / "out"
    out.mkdir()
    dst = out / "s.gt"
    _killed_after_first_pass(src, dst, 4, eps=1.0, first="heights")
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        preprocess_streaming(src, dst, band=4, codec_error=1.0, resume=True)
    assert "resuming a killed run; passes done: heights" in caplog.text
    _assert_same_store(ref, dst)
    assert [x.name for x in out.iterdir()] == ["s.gt"]


@pytest.mark.parametrize("args, says", [(["--memory-limit", "12Q"], "--memory-limit"),
                                        (["--memory-limit", "1K"], "64M"),
                                        (["--scheduler", "gpu:2"], "--scheduler")])
def test_bad_streaming_options_are_one_line_usage_errors(tmp_path, args, says):
    from click.testing import CliRunner

    from geoterrain.cli.main import cli

    src = _dem(tmp_path, 1, 20, 20, 0.0)
    run = CliRunner().invoke(cli, ["preprocess", src, "-o", str(tmp_path / "s.gt"), *args])
    assert run.exit_code == 2, run.output
    err = [ln for ln in run.output.splitlines() if ln.startswith("Error")]
    assert len(err) == 1 and says in err[0] and "Traceback" not in run.output
    assert not (tmp_path / "s.gt").exists()

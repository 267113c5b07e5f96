"""geoterrain in worker processes: multiprocessing pools of every start method and
ProcessPoolExecutor, after the parent ran parallel kernels (GNU OpenMP aborted forked
children at their first parallel launch: "Terminating: fork() called from a process
already using GNU OpenMP"). Every parallel kernel is a ParallelKernel whose serial twin
a fork() child runs (geoterrain/core/threads.py)."""

from __future__ import annotations

import hashlib
import importlib
import multiprocessing as mp
import pkgutil
import shutil
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from numba.core.registry import CPUDispatcher

import geoterrain
import geoterrain.core.threads as threads
from geoterrain.core.threads import ParallelKernel
from geoterrain.ingest.synth import generate, write_geotiff
from tests.conftest import in_fork


def _digest(p) -> str:
    return hashlib.sha256(open(p, "rb").read()).hexdigest()


@pytest.fixture(scope="module")
def dems(tmp_path_factory):
    """Three DEMs, and the stores this (parent) process writes of them: the parent has run
    every preprocess kernel, on threads, before any worker starts. One DEM has several
    compressed blocks, which GDAL decodes on a pool of threads (a fork() child must not
    wait for the parent's)."""
    d = tmp_path_factory.mktemp("fork")
    out = []
    with pytest.MonkeyPatch.context() as mp_:  # small work would run the serial twins
        mp_.setattr(threads, "PARALLEL_MIN_SAMPLES", 0)
        for i in range(3):
            src = write_geotiff(d / f"d{i}.tif", generate("fbm", (97, 300, 129)[i],
                                                          seed=20 + i))
            ref = geoterrain.preprocess(src, d / f"ref{i}.geoterrain")
            out.append((src, _digest(ref)))
    return out


def _copies(dems, folder):
    folder.mkdir()
    return [shutil.copyfile(src, folder / src.name) for src, _ in dems]


@pytest.mark.parametrize("method", ["fork", "forkserver", "spawn"])
def test_pool_map_of_preprocess(dems, tmp_path, method):
    """Pool(2).map(geoterrain.preprocess, DEMs): every map returns, with the stores the
    parent writes (byte-identical: stores are reproducible)."""
    srcs = _copies(dems, tmp_path / method)
    with mp.get_context(method).Pool(2) as pool:
        stores = pool.map_async(geoterrain.preprocess, srcs).get(timeout=240)
    assert [_digest(p) for p in stores] == [ref for _, ref in dems]


@pytest.mark.parametrize("method", ["fork", "spawn"])
def test_process_pool_executor(dems, tmp_path, method):
    srcs = _copies(dems, tmp_path / method)
    with ProcessPoolExecutor(2, mp_context=mp.get_context(method)) as ex:
        stores = list(ex.map(geoterrain.preprocess, srcs, timeout=240))
    assert [_digest(p) for p in stores] == [ref for _, ref in dems]


def test_fxaa_in_a_forked_child_after_the_parent_ran_it():
    """A forked worker after a render with --anti-aliasing fxaa (a parallel kernel)."""
    from geoterrain.rendering.antialias import fxaa

    rng = np.random.default_rng(3)
    img = (rng.random((90, 120, 3)) * 255).astype(np.uint8)
    depth = rng.random((90, 120)).astype(np.float32)
    want = fxaa(img, depth).tobytes()
    got, status = in_fork(lambda: fxaa(img, depth).tobytes() == want)
    assert (got, status) == (b"same", 0)


def test_every_parallel_kernel_has_a_serial_twin():
    """A prange kernel compiled with parallel=True is reached only through a
    ParallelKernel (a bare one would abort a forked worker again)."""
    wrapped, bare = set(), {}
    for m in pkgutil.walk_packages(geoterrain.__path__, "geoterrain."):
        for name, v in vars(importlib.import_module(m.name)).items():
            if isinstance(v, ParallelKernel):
                wrapped.add(id(v.parallel))
                assert not v.serial.targetoptions.get("parallel")
            elif isinstance(v, CPUDispatcher) and v.targetoptions.get("parallel"):
                bare[f"{m.name}.{name}"] = id(v)
    assert len(wrapped) >= 20
    assert not {k for k, i in bare.items() if i not in wrapped}

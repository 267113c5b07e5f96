"""serial_kernels (geoterrain/core/threads.py): inside it a ParallelKernel runs its serial
twin, on this thread only; it nests, and the way out restores the choice."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from geoterrain.core.threads import ParallelKernel, serial_kernels


class _Spy(ParallelKernel):
    """A ParallelKernel whose two versions only say which one ran."""

    def __init__(self):  # no compilation: the choice is what is tested
        self.parallel = lambda: "parallel"
        self.serial = lambda: "serial"


@pytest.mark.fast
def test_serial_kernels_chooses_the_twin_nests_and_restores():
    k = _Spy()
    assert k() == "parallel"
    with serial_kernels():
        assert k() == "serial"
        with serial_kernels(False):  # a large piece inside: every core again
            assert k() == "parallel"
        assert k() == "serial"
        seen = []
        th = threading.Thread(target=lambda: seen.append(k()))
        th.start()
        th.join()
        assert seen == ["parallel"]  # another thread keeps its own choice
    assert k() == "parallel"
    with pytest.raises(RuntimeError), serial_kernels():
        raise RuntimeError
    assert k() == "parallel"


@pytest.mark.fast
def test_serial_and_parallel_normals_agree():
    from geoterrain.bounds.normals import normal_map

    rng = np.random.default_rng(0)
    j, i = np.meshgrid(np.arange(40.0), np.arange(33.0))
    z = rng.normal(size=i.shape)
    v = rng.random(i.shape) > 0.1
    par = normal_map(j, -i, z, v)
    with serial_kernels():
        ser = normal_map(j, -i, z, v)
    assert np.array_equal(par, ser)


def _spy_on_parallel(monkeypatch) -> list[str]:
    """Every ParallelKernel of the package records its name when its threaded version
    runs (and then runs its serial twin, the same arithmetic)."""
    import importlib
    import pkgutil

    import geoterrain

    ran: list[str] = []
    for m in pkgutil.walk_packages(geoterrain.__path__, "geoterrain."):
        if ".serve" in m.name or ".bench" in m.name:
            continue
        for name, v in vars(importlib.import_module(m.name)).items():
            if isinstance(v, ParallelKernel):
                def spy(*a, _n=f"{m.name}.{name}", _s=v.serial):
                    ran.append(_n)
                    return _s(*a)
                monkeypatch.setattr(v, "parallel", spy)
    return ran


@pytest.mark.fast
@pytest.mark.parametrize("threshold", [None, 0])
def test_small_work_runs_only_the_serial_twins(tmp_path, monkeypatch, threshold):
    """A small DEM's preprocess and static mesh (below PARALLEL_MIN_SAMPLES) run no
    threaded kernel, so a first run on it compiles only the twins; with the threshold at
    0 the same work runs threaded ones (the spy sees them)."""
    import geoterrain
    import geoterrain.core.threads as threads
    from geoterrain.ingest.synth import generate, write_geotiff

    if threshold is not None:
        monkeypatch.setattr(threads, "PARALLEL_MIN_SAMPLES", threshold)
    ran = _spy_on_parallel(monkeypatch)
    src = write_geotiff(tmp_path / "d.tif", generate("fbm", 129, seed=4))
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "d.geoterrain"))
    assert len(geoterrain.lod.static(t, 1.0).mesh.faces)
    if threshold is None:
        assert ran == []
    else:  # the preprocess's and the mesh's threaded kernels
        assert {"_raw_delta_nb", "_tile_boxes_nb", "_normals_nb", "_level_payloads",
                "_find_active", "_emit_leaves"} <= {n.rsplit(".", 1)[1] for n in ran}


@pytest.mark.parametrize("threshold", [None, 0])
def test_a_small_stores_render_runs_only_the_serial_twins(tmp_path, monkeypatch, threshold):
    """A render of a store below PARALLEL_MIN_SAMPLES runs no threaded kernel (its first
    run compiles the twins only: issue 51's first run); with the threshold at 0 the
    same frame runs threaded ones, and both give the same pixels."""
    import geoterrain
    import geoterrain.core.threads as threads
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.rendering.cameras import default_view
    from geoterrain.rendering.scene import render_array

    src = write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=4))
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "d.geoterrain"))
    view = default_view(t, (320, 240))
    want, _ = render_array(t, view)
    if threshold is not None:
        monkeypatch.setattr(threads, "PARALLEL_MIN_SAMPLES", threshold)
    ran = _spy_on_parallel(monkeypatch)
    img, _ = render_array(geoterrain.open(tmp_path / "d.geoterrain"), view)
    assert np.array_equal(img, want)
    if threshold is None:
        assert ran == []
    else:  # the tiles' normal codes and their texels, threaded
        assert {"_derived_codes_nb", "_shade_tiles"} & {n.rsplit(".", 1)[1] for n in ran}

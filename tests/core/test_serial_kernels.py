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

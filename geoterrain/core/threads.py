"""How many cores the compiled (numba ``prange``) kernels use for a piece of work.

Measured on this 2-core machine (``vertex_errors``, ms, 2 threads / 1 thread): quiet,
threads win at every size (65²: 0.08 / 0.10, 1025²: 20 / 33, 2049²: 92 / 153); with
another process busy on one core they lose, most on small grids where each parallel
region is short and its barrier waits for a descheduled thread (65²: 0.42 / 0.08,
1025²: 80 / 34, 2049²: 222 / 159). Small pieces of work (a quantized-mesh tile, a small
DEM: below ``PARALLEL_MIN_SAMPLES``, about 724²) run on one thread, where threads gain
little and can lose 5×; larger ones on every core, which wins 1.6× on an idle machine
and loses 1.4–2.4× on one with a core taken.
"""

from __future__ import annotations

import types
from collections.abc import Iterator
from contextlib import contextmanager

import numba
from numba import njit

from geoterrain.core._fork import FORKED

__all__ = ["PARALLEL_MIN_SAMPLES", "cores_for", "forked", "serial_twin"]

PARALLEL_MIN_SAMPLES = 1 << 19  # about 724²: below it, one thread

# numba's GNU OpenMP layer aborts a process forked from one that ran a parallel region,
# at the child's first parallel launch; the package registers the fork hook on import
# (geoterrain/core/_fork.py), before any such region can run, whatever a child imports.


def forked() -> bool:
    """Whether this process is a fork() child (then parallel kernels must not launch).

    Examples
    --------
    >>> forked()
    False
    """
    return FORKED[0]


def serial_twin(kernel):
    """``kernel`` (a compiled kernel or its Python function) compiled again without
    threads, its ``prange`` loops run as ``range`` (the same arithmetic), with its own
    cache entry: what a fork() child runs, and one small piece of work on the calling
    thread.

    Examples
    --------
    >>> import numpy as np
    >>> from geoterrain.bounds.normals import _valid_finite_nb
    >>> twin = serial_twin(_valid_finite_nb)
    >>> twin.py_func.__name__, twin(*[np.zeros((1, 2))] * 3, np.ones((1, 2), bool)).tolist()
    ('_valid_finite_nb_serial', [[True, True]])
    """
    f = getattr(kernel, "py_func", kernel)
    twin = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial",
                              f.__defaults__, f.__closure__)
    twin.__qualname__ = f.__qualname__ + "_serial"  # its own cache entry
    return njit(cache=True, nogil=True)(twin)


@contextmanager
def cores_for(samples: int) -> Iterator[None]:
    """Run the compiled kernels called inside on one thread when ``samples`` is below
    :data:`PARALLEL_MIN_SAMPLES`, else on numba's threads (the setting is per thread,
    restored on exit; results never depend on it).

    Examples
    --------
    >>> with cores_for(100):
    ...     numba.get_num_threads()
    1
    """
    if samples >= PARALLEL_MIN_SAMPLES:
        yield
        return
    n = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(n)

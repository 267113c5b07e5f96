"""How many cores the compiled (numba ``prange``) kernels use for a piece of work, and
which kernels a fork() child runs.

Fork safety: numba runs ``prange`` loops on GNU OpenMP here, which aborts a process forked
from one that ran a parallel region ("Terminating: fork() called from a process already
using GNU OpenMP") at the child's first parallel launch: a ``multiprocessing`` pool of the
default fork start method died after any preprocess in its parent. Every parallel kernel
is a :class:`ParallelKernel` (:func:`parallel_kernel`): a fork() child runs its serial
twin, the same arithmetic on the calling thread, and never launches a parallel region.
numba's other layers were measured against it (benchmarks/bench_threading.py,
docs/lab/threading.md): ``workqueue`` is fork-safe but aborts when two threads launch
kernels at once (the interactive viewer selects on a worker thread while the main thread
shades), and ``tbb`` from the PyPI wheel is not found by numba in a virtual environment
without ``LD_LIBRARY_PATH``. GNU OpenMP and twins cost the parent nothing.

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

import functools
import threading
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numba
from numba import njit

from geoterrain.core._fork import FORKED

__all__ = ["PARALLEL_MIN_SAMPLES", "ParallelKernel", "cores_for", "forked", "parallel_kernel",
           "serial_for", "serial_kernels", "serial_now",
           "serial_twin"]

PARALLEL_MIN_SAMPLES = 1 << 19  # about 724²: below it, one thread

_HERE = threading.local()  # .serial: this thread runs the serial twins (serial_kernels)

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


def serial_now() -> bool:
    """Whether a :class:`ParallelKernel` called now runs its serial twin: in a fork()
    child, inside :func:`serial_kernels`, and for small work (:func:`cores_for`).

    Examples
    --------
    >>> with cores_for(100):
    ...     inside = serial_now()
    >>> serial_now(), inside
    (False, True)
    """
    return FORKED[0] or getattr(_HERE, "serial", False)


def serial_for(samples: int) -> bool:
    """Whether work of ``samples`` samples runs the serial twins: :func:`serial_now`, or
    fewer than :data:`PARALLEL_MIN_SAMPLES` (as :func:`cores_for`).

    Examples
    --------
    >>> serial_for(100), serial_for(PARALLEL_MIN_SAMPLES)
    (True, False)
    """
    return serial_now() or samples < PARALLEL_MIN_SAMPLES


def serial_twin(kernel):
    """``kernel`` (a compiled kernel or its Python function) compiled again without
    threads, its ``prange`` loops run as ``range`` (the same arithmetic), with its own
    cache entry: what a fork() child runs, and one small piece of work on the calling
    thread.

    Examples
    --------
    >>> import numpy as np
    >>> from geoterrain.bounds.normals.maps import _valid_finite_nb
    >>> twin = serial_twin(_valid_finite_nb)
    >>> twin.py_func.__name__, twin(*[np.zeros((1, 2))] * 3, np.ones((1, 2), bool)).tolist()
    ('_valid_finite_nb_serial', [[True, True]])
    """
    if isinstance(kernel, ParallelKernel):
        return kernel.serial
    f = getattr(kernel, "py_func", kernel)
    twin = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial",
                              f.__defaults__, f.__closure__)
    twin.__qualname__ = f.__qualname__ + "_serial"  # its own cache entry
    return njit(cache=True, nogil=True)(twin)


class ParallelKernel:
    """A compiled kernel whose ``prange`` loops run on numba's threads (``.parallel``), and
    its serial twin (``.serial``, :func:`serial_twin`): calling it runs the twin in a
    fork() child, where a parallel launch would abort the process, else the parallel one.
    The choice costs a Python call (well under a microsecond). Call it from Python only: a
    compiled caller calls ``.parallel`` or ``.serial`` itself.

    Examples
    --------
    >>> import numpy as np
    >>> from numba import prange
    >>> @parallel_kernel(cache=False)
    ... def double(a):
    ...     for i in prange(a.size):
    ...         a[i] *= 2
    >>> a = np.arange(3.0); double(a); a.tolist(), double.serial.py_func.__name__
    ([0.0, 2.0, 4.0], 'double_serial')
    """

    def __init__(self, f: Callable, **options):
        self.py_func = f
        self.parallel = njit(parallel=True, **options)(f)
        self.serial = _twin(f, options)
        functools.update_wrapper(self, f)

    def __call__(self, *args):
        return (self.serial if serial_now() else self.parallel)(*args)


def parallel_kernel(**options) -> Callable[[Callable], ParallelKernel]:
    """``@parallel_kernel(cache=True, nogil=True)`` in place of ``@njit(parallel=True,
    ...)``: a :class:`ParallelKernel` (every ``prange`` kernel of geoterrain is one;
    tests/test_kernel_arity.py checks)."""
    return lambda f: ParallelKernel(f, **options)


def _twin(f: Callable, options: dict):
    twin = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial",
                              f.__defaults__, f.__closure__)
    twin.__qualname__ = f.__qualname__ + "_serial"  # its own cache entry
    return njit(**options)(twin)


@contextmanager
def serial_kernels(serial: bool = True) -> Iterator[None]:
    """Run every :class:`ParallelKernel` called inside on the calling thread (its serial
    twin): for work made of many small pieces, such as an edit of a few tiles, where each
    parallel region is short and, on a busy machine, waits at its barrier for a
    descheduled thread; the parallel kernels are then not loaded at all. ``serial``
    False: the parallel ones again (a large piece inside). Per thread, nestable,
    restored on exit; results never depend on it.

    Examples
    --------
    >>> import numpy as np
    >>> from geoterrain.bounds.normals import normal_map
    >>> with serial_kernels():
    ...     normal_map(*np.meshgrid(np.arange(3.0), np.arange(3.0)), np.zeros((3, 3))).shape
    (3, 3, 3)
    """
    old = getattr(_HERE, "serial", False)
    _HERE.serial = serial
    try:
        yield
    finally:
        _HERE.serial = old


@contextmanager
def cores_for(samples: int) -> Iterator[None]:
    """Run the compiled kernels called inside on one thread when ``samples`` is below
    :data:`PARALLEL_MIN_SAMPLES`, else on numba's threads (the setting is per thread,
    restored on exit; results never depend on it). On one thread a :class:`ParallelKernel`
    runs its serial twin (:func:`serial_kernels`): the same arithmetic, and a small DEM's
    first run compiles only the twins, in a third to a half of the parallel kernels' compile
    time.

    Examples
    --------
    >>> with cores_for(100):
    ...     numba.get_num_threads()
    1
    """
    if samples >= PARALLEL_MIN_SAMPLES or serial_now():
        # large work; or every ParallelKernel runs its serial twin already (an edit, a
        # fork() child): numba's threads are not asked for, so not started (the first
        # ask loads its threading layer and starts its pool: 3-4 ms of CPU, 3-21 ms of
        # wall time at load 11, and multiprocessing imported)
        yield
        return
    n = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with serial_kernels():
            yield
    finally:
        numba.set_num_threads(n)

"""Every compiled kernel takes at most 12 arguments (issue 43): a kernel with more takes
bundles (named tuples of the arrays and scalars that belong together) instead."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from numba.core.registry import CPUDispatcher

import geoterrain
from geoterrain.core.threads import ParallelKernel

MAX_ARGS = 12


def _kernels() -> dict[str, int]:
    """Every numba dispatcher a geoterrain module holds (its globals, or a dict of them:
    the serial twins), with its argument count."""
    found = {}

    def add(v):
        if isinstance(v, ParallelKernel):  # its parallel kernel and its serial twin
            add(v.parallel)
            add(v.serial)
        if isinstance(v, CPUDispatcher):
            f = v.py_func
            found[f"{f.__module__}.{f.__qualname__}"] = len(inspect.signature(f).parameters)

    for m in pkgutil.walk_packages(geoterrain.__path__, "geoterrain."):
        for v in vars(importlib.import_module(m.name)).values():
            add(v)
            if isinstance(v, dict):
                for w in list(v.values()):
                    add(w)
    return found


def test_no_kernel_takes_more_than_twelve_arguments():
    found = _kernels()
    assert len(found) > 100  # the scan sees the kernels
    wide = {k: n for k, n in found.items() if n > MAX_ARGS}
    assert not wide, f"kernels with more than {MAX_ARGS} arguments: {wide}"

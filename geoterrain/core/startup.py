"""A command's start: what numba's and VTK's imports cost that a command-line process
need not pay (issue 51, a quick first run; docs/lab/chunked-info-first-run.md).

:func:`install` is called by the command line (``geoterrain.cli.main``) before it runs a
command; it imports nothing of numba or VTK. Each change waits for the library's module
to be imported (a finder on ``sys.meta_path`` that wraps that one module's loader), and
is skipped where the library is not the code it was written for. The library API
(``import geoterrain``) leaves numba and VTK as they are.

- **numba's context refresh on a cached kernel.** numba's ``Cache.load_overload`` calls
  ``target_context.refresh()`` before it reads a kernel from its cache: that imports and
  installs every implementation numba holds (``numba.cpython.*``, ``numba.np.linalg``,
  the random generators, the typed containers, …) and fills the typing context with
  their templates, about 0.1 s of CPU in a fresh process, though a cached kernel is
  machine code that needs none of them. Here the load starts numba's runtime (NRT: a
  cached kernel may allocate; ``rtsys.initialize`` is the part of the refresh a load
  uses) and reads the kernel as numba does. A kernel the cache does not hold is compiled
  as before: numba's compiler refreshes both contexts itself (``compile_extra``, and each
  typing template's lookup) before it types or lowers anything.
- **numba's implementation modules under a cached kernel's environments.** A cached
  kernel pickles the environments of the numba functions it calls (``np.empty``'s,
  ``np.cumsum``'s, …), and numba rebuilds each by importing its module for its globals:
  ``numba.np.arrayobj``, ``arraymath``, ``numba.cpython.unicode``, 60–85 ms of CPU at the
  first load. Only object mode reads an environment's globals (``pylowering``), and
  numba's own functions are nopython code: a numba module not imported yet stands in as
  an empty module of its name (:class:`_EnvironmentImports`); the environment keeps its
  constants and pickles as before.
- **VTK's module lookup.** VTK's import hook (``vtkmodules.find_lib_path``, recent VTK)
  globs the package folder, about 540 files, twice for each of the ~50 extension modules
  a render loads (``.pyd``, then ``.so``): 30–50 ms of CPU. Here the folder is listed once
  and the same rule applied to the list, in the same order.
- **coverage.py and pyyaml under numba.** ``numba.misc.coverage_support`` imports
  ``coverage`` when it is installed (a test or development environment), 40–60 ms, to
  report compiled lines to a running ``coverage.Coverage``. A measured process imports
  coverage before it runs the command (``coverage run``, pytest-cov,
  ``COVERAGE_PROCESS_START``); where it is not imported yet, none runs, so numba's support
  is imported without it. ``numba.core.config`` imports ``yaml`` (20 ms) to read a
  ``.numba_config.yaml`` in the working folder: where there is none, without it (a file
  made there later, while the command runs, would be warned about and not read).

Examples
--------
>>> import subprocess, sys
>>> code = ("import sys; from geoterrain.core import startup; startup.install(); "
...         "import numba.core.caching as c; print(c.Cache.load_overload.__module__)")
>>> subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip()
'geoterrain.core.startup'
>>> from geoterrain.core import startup
>>> startup.lib_path_rule("vtkCommonCore", ["vtkCommonCore.pyi",
...     "vtkCommonCore.cpython-311-x86_64-linux-gnu.so", "vtkCommonCoreX.so"])
['vtkCommonCore.pyi', 'vtkCommonCore.cpython-311-x86_64-linux-gnu.so']
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
import types
from collections.abc import Callable, Iterable
from pathlib import Path

_installed = False


# --- numba: a cached kernel loaded without the context refresh ---

def _load_overload(self, sig, target_context):
    """numba's ``Cache.load_overload`` without ``target_context.refresh()``: numba's
    runtime started, then the cached kernel read as numba reads it (None where the cache
    does not hold it, or where numba swallows an I/O error)."""
    from numba.core.runtime import rtsys

    rtsys.initialize(target_context)
    with self._guard_against_spurious_io_errors():
        return self._load_overload(sig, target_context)


class _EnvironmentImports:
    """What ``numba.core.environment`` sees as ``importlib`` (its ``_rebuild_env``, which
    unpickles a cached kernel's environments, imports each one's module for its globals):
    a module imported already as it is; one of numba's own modules not imported yet as an
    empty module of that name, not imported. An environment's globals are read by object
    mode alone (``pylowering``); numba's implementations are compiled in nopython mode,
    so nothing reads them, and the environment pickles as before (its module's name)."""

    @staticmethod
    def import_module(name: str, package: str | None = None):
        mod = sys.modules.get(name)
        if mod is not None:
            return mod
        if name.startswith("numba."):
            return types.ModuleType(name)
        return importlib.import_module(name, package)


def _patch_numba_environment(environment) -> None:
    if getattr(environment, "importlib", None) is not importlib or not callable(
            getattr(environment, "_rebuild_env", None)):
        return  # another numba than this was written for: leave it
    environment.importlib = _EnvironmentImports


def _patch_numba_caching(caching) -> None:
    cache = getattr(caching, "Cache", None)
    if cache is None or not all(hasattr(cache, a) for a in (
            "load_overload", "_load_overload", "_guard_against_spurious_io_errors")):
        return  # another numba than this was written for: leave it
    cache.load_overload = _load_overload


# --- VTK: its extension modules found from one listing of the folder ---

def lib_path_rule(name: str, names: Iterable[str]) -> list[str]:
    """The entries of a folder's listing that VTK's ``find_lib_path`` considers for the
    module ``name``: its glob ``f"{name}[.-]*"``, in the listing's order.

    >>> lib_path_rule("vtkIOXML", ["vtkIOXMLParser.so", "vtkIOXML.so", "vtkIOXML-9.4.so"])
    ['vtkIOXML.so', 'vtkIOXML-9.4.so']
    """
    n = len(name)
    return [f for f in names if len(f) > n and f.startswith(name) and f[n] in ".-"]


def _patch_vtkmodules(vtkmodules) -> None:
    exts = getattr(vtkmodules, "LIB_EXTS", None)
    if not callable(getattr(vtkmodules, "find_lib_path", None)) or not exts:
        return  # an older VTK (no import hook) or another one
    listings: dict[str, list[str]] = {}

    def find_lib_path(paths, vtk_module_name):
        # VTK's own loop (extension outer, folder inner), the glob read from a listing
        for ext in exts:
            for base in paths:
                names = listings.get(base)
                if names is None:
                    try:
                        names = listings[base] = os.listdir(base)
                    except OSError:
                        names = listings[base] = []
                for f in lib_path_rule(vtk_module_name, names):
                    resolved = Path(base, f).resolve()
                    if resolved.is_file() and ext in resolved.suffixes:
                        return str(resolved)
        return None

    vtkmodules.find_lib_path = find_lib_path


# --- numba's optional imports where nothing would use them ---

def _without(name: str, exec_module: Callable[[object], None], module) -> None:
    """Runs ``module`` with ``import name`` failing (as if not installed), unless ``name``
    is imported already; ``name`` stays importable afterwards."""
    if name in sys.modules:
        exec_module(module)
        return
    sys.modules[name] = None  # `import name` raises ImportError
    try:
        exec_module(module)
    finally:
        if sys.modules.get(name, 0) is None:
            del sys.modules[name]


def _without_coverage(exec_module: Callable[[object], None], module) -> None:
    # imported already: maybe running (coverage run, pytest-cov), and numba reports to it
    _without("coverage", exec_module, module)


def _without_yaml(exec_module: Callable[[object], None], module) -> None:
    # numba reads pyyaml's module for a .numba_config.yaml in the working folder only
    if os.path.isfile(".numba_config.yaml"):
        exec_module(module)
    else:
        _without("yaml", exec_module, module)


_AFTER = {"numba.core.caching": _patch_numba_caching,
          "numba.core.environment": _patch_numba_environment,
          "vtkmodules": _patch_vtkmodules}
_AROUND = {"numba.misc.coverage_support": _without_coverage,
           "numba.core.config": _without_yaml}


class _Loader:
    """Runs a module as its own loader does, with the change for it (a loader by its
    methods: importlib.abc is not imported, 15 ms that ``info`` need not pay)."""

    def __init__(self, inner, name: str):
        self.inner, self.name = inner, name

    def create_module(self, spec):
        return self.inner.create_module(spec)

    def exec_module(self, module) -> None:
        if self.name in _AROUND:
            _AROUND[self.name](self.inner.exec_module, module)
        else:
            self.inner.exec_module(module)
            _AFTER[self.name](module)


class _Hook:
    """Waits for the modules :func:`install` changes; leaves ``sys.meta_path`` when all
    were imported."""

    def __init__(self, names: set[str]):
        self.waiting = names

    def find_spec(self, fullname, path, target=None):
        if fullname not in self.waiting:
            return None
        self.waiting.discard(fullname)
        if not self.waiting:
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)  # the other finders (this one: None now)
        if spec is not None and hasattr(spec.loader, "exec_module"):
            spec.loader = _Loader(spec.loader, fullname)
        return spec


def install() -> None:
    """In this process, from now on: cached numba kernels load without numba's context
    refresh or the numba modules their environments name, VTK finds its modules from one
    listing of its folder, and numba imports neither coverage.py unless it is imported
    already nor pyyaml unless the working folder holds a ``.numba_config.yaml``. Imports
    nothing of numba or VTK; a module imported already is changed at once (numba's config
    and coverage support stay as imported)."""
    global _installed
    if _installed:
        return
    _installed = True
    waiting = set()
    for name, patch in _AFTER.items():
        mod = sys.modules.get(name)
        if mod is not None:
            patch(mod)
        else:
            waiting.add(name)
    waiting |= {name for name in _AROUND if name not in sys.modules}
    if waiting:
        sys.meta_path.insert(0, _Hook(waiting))

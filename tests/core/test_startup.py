"""A command's start (geoterrain/core/startup.py): a cached kernel loads without numba's
context refresh and without importing the numba modules its environments name, and
computes what it computed before, a kernel compiled afterwards in the same process still
compiles, VTK's modules are found where VTK's own lookup finds them,
and numba's coverage support imports coverage.py only where it is imported already.

Each process here is fresh (``startup.install`` changes numba and VTK for the rest of a
process; the test process is left as it is)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import types
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core import startup

_KERNELS = '''
import numpy as np
from numba import njit

@njit(cache=True)
def grow(a):  # an allocation (numba's runtime) and numba's own array functions
    out = np.empty_like(a)
    for i in range(a.size):
        out[i] = a[i] * 2.0 + 1.0
    return np.cumsum(out)
'''

_RUN = '''
import json, sys
import numpy as np
sys.path.insert(0, {folder!r})
if {install}:
    from geoterrain.core import startup
    startup.install()
import numba.core.base as B
calls = []
_refresh = B.BaseContext.refresh
def refresh(self):
    calls.append(1)
    return _refresh(self)
B.BaseContext.refresh = refresh
import cached
a = np.linspace(-3.0, 5.0, 11)
got = cached.grow(a)
loaded = sum(cached.grow.stats.cache_hits.values())
refreshed = len(calls)
arrayobj = "numba.np.arrayobj" in sys.modules  # np.empty_like's module (its environment)
from numba import njit
@njit
def later(n):  # compiled after the cached load: needs the implementations refreshed now
    return np.arange(n).sum()
print(json.dumps(dict(got=got.tolist(), want=np.cumsum(a * 2.0 + 1.0).tolist(),
                      loaded=loaded, refreshed_by_load=refreshed, arrayobj=arrayobj,
                      later=later(4) if {install} else None)))
'''


def _run(folder, install: bool) -> dict:
    out = subprocess.run([sys.executable, "-c", _RUN.format(folder=str(folder),
                                                            install=install)],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.splitlines()[-1])


@pytest.mark.fast
def test_a_cached_kernel_loads_without_the_refresh_and_computes_the_same(tmp_path,
                                                                         monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "cached.py").write_text(_KERNELS)
    first = _run(tmp_path, install=True)  # compiled (the compiler refreshes) and cached
    assert first["loaded"] == 0 and first["refreshed_by_load"] > 0
    plain = _run(tmp_path, install=False)  # numba's own load: refreshes
    assert plain["loaded"] == 1 and plain["refreshed_by_load"] > 0
    fast = _run(tmp_path, install=True)
    assert fast["loaded"] == 1 and fast["refreshed_by_load"] == 0
    assert plain["arrayobj"] and not fast["arrayobj"]  # environments rebuilt, not imported
    for r in (first, plain, fast):
        assert r["got"] == r["want"]
    assert first["later"] == fast["later"] == 6
    assert fast["got"] == plain["got"]


def _fake_vtkmodules():
    vtkmodules = pytest.importorskip("vtkmodules")
    if not callable(getattr(vtkmodules, "find_lib_path", None)):
        pytest.skip("a VTK without its module lookup hook (an older one)")
    ns = types.SimpleNamespace(LIB_EXTS=vtkmodules.LIB_EXTS,
                               find_lib_path=vtkmodules.find_lib_path)
    startup._patch_vtkmodules(ns)  # a stand-in: VTK itself is left as it is
    return vtkmodules, ns


@pytest.mark.fast
def test_vtks_modules_are_found_where_vtk_finds_them():
    vtkmodules, ns = _fake_vtkmodules()
    assert ns.find_lib_path is not vtkmodules.find_lib_path
    paths = list(vtkmodules.__path__)
    names = sorted({f.name.split(".")[0] for p in paths for f in Path(p).iterdir()
                    if f.name.startswith("vtk")})
    assert len(names) > 50
    for name in names + ["vtkNoSuchModule", "vtkIOXML", "vtkIOXMLParser"]:
        assert ns.find_lib_path(paths, name) == vtkmodules.find_lib_path(paths, name), name


_NAME = st.text("vtkIOXMLParse.-_so", min_size=1, max_size=12).filter(
    lambda s: s not in (".", ".."))


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(name=_NAME, names=st.sets(_NAME, max_size=10))
def test_the_lookup_rule_is_vtks_glob(tmp_path_factory, name, names):
    """On a real folder: the names VTK's ``Path.glob(f"{name}[.-]*")`` yields, in the
    folder's own order."""
    d = tmp_path_factory.mktemp("glob")
    for f in names:
        (d / f).write_bytes(b"")
    listing = os.listdir(d)
    assert startup.lib_path_rule(name, listing) == [
        p.name for p in Path(d).glob(f"{name}[.-]*")]


_OPTIONAL = '''
import sys
print("coverage" in sys.modules)  # a measured test run starts coverage in each process
if {first}:
    import coverage, yaml
from geoterrain.core import startup
startup.install()
import numba, numba.misc.coverage_support as c, numba.core.config as config
print(c.coverage_available, "coverage" in sys.modules, config._HAVE_YAML, "yaml" in sys.modules)
import coverage, yaml  # still importable afterwards
print(coverage.__name__, yaml.__name__, config.BOUNDSCHECK)
'''


@pytest.mark.fast
@pytest.mark.parametrize("first, config_file", [(False, False), (True, False), (False, True)],
                         ids=["not-imported", "imported-first", "numba-config-file"])
def test_numba_imports_coverage_and_yaml_only_where_they_are_used(tmp_path, first,
                                                                  config_file):
    """numba imports coverage.py only where it is imported already (it may be running),
    and pyyaml where it is imported already or the working folder holds a
    .numba_config.yaml, which numba still reads."""
    pytest.importorskip("coverage")
    pytest.importorskip("yaml")
    if config_file:
        (tmp_path / ".numba_config.yaml").write_text("boundscheck: 1\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_BOUNDSCHECK"}
    out = subprocess.run([sys.executable, "-c", _OPTIONAL.format(first=first)], env=env,
                         cwd=tmp_path, capture_output=True, text=True,
                         check=True).stdout.split("\n")
    cov = first or out[0] == "True"
    yml = first or config_file
    assert out[1] == f"{cov} {cov} {yml} {yml}"
    assert out[2] == f"coverage yaml {1 if config_file else None}"

"""Every benchmark script still imports against the library it measures.

The scripts in ``benchmarks/`` are not run by the suite (they are timed by hand, on a
quiet machine). This loads each one as a module, which runs its imports and
definitions but not its ``main`` (each has a ``__main__`` guard): a script that names
something the library no longer has fails here, not on the day it is needed. An
optional third-party package that is not installed (the ``bench`` extra: pymartini,
pysz, ...) skips that script.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

SCRIPTS = sorted((Path(__file__).resolve().parents[2] / "benchmarks").glob("bench_*.py"))


def test_there_are_benchmark_scripts():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.stem)
def test_a_benchmark_script_imports(path, monkeypatch):
    monkeypatch.syspath_prepend(str(path.parent))
    name = f"_bench_script_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] not in ("geoterrain", "cli"):
            pytest.skip(f"{path.name} needs {exc.name} (not installed)")
        raise
    finally:
        sys.modules.pop(name, None)
    assert callable(getattr(module, "main", None)), f"{path.name} has no main()"

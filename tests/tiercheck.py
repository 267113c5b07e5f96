"""A pytest plugin that fails the run unless it exercised every module of geoterrain.

``make test-fast-coverage`` runs the fast tier with it (``--tiercheck``, which the root
conftest.py turns into this plugin): every module
under ``geoterrain/`` and ``cli/`` must have run at least one line inside one of its
functions (traced by coverage.py, started here), or have had one of its numba kernels
called (a compiled kernel's lines are never traced; a kernel that was called holds a
compiled signature); a module that defines no function needs only to be imported. The
run then fails with the list of the modules that were not, so that a new module comes
with a fast test (or a doctest: doctests belong to the fast tier).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# package folder → its module name prefix (pyproject's package-dir: cli/ is geoterrain.cli)
PACKAGES = {ROOT / "geoterrain": "geoterrain", ROOT / "cli": "geoterrain.cli"}

_cov = None
_missing: list[str] | None = None


def project_modules() -> dict[str, Path]:
    """Every module of the package, by name → its file."""
    out = {}
    for folder, prefix in PACKAGES.items():
        for f in sorted(folder.rglob("*.py")):
            parts = f.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join((prefix, *parts))] = f
    return out


def function_lines(path: Path) -> set[int]:
    """The lines of the statements inside the functions a file defines (docstrings out)."""
    lines: set[int] = set()

    def body(nodes):
        for i, n in enumerate(nodes):
            if (i == 0 and isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)
                    and isinstance(n.value.value, str)):
                continue  # a docstring: never an executed line
            for sub in ast.walk(n):
                if isinstance(sub, ast.stmt):
                    lines.add(sub.lineno)

    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            body(node.body)
    return lines


def called_kernels(module) -> bool:
    """Whether one of ``module``'s numba kernels was compiled or loaded (i.e. called)."""
    try:
        from numba.core.dispatcher import Dispatcher
    except ImportError:
        return False
    if module is None:
        return False
    name = module.__name__
    return any(isinstance(v, Dispatcher) and v.py_func.__module__ == name and v.signatures
               for v in list(vars(module).values()))


def unexercised(executed: dict[str, set[int]]) -> list[str]:
    """The modules that ran none of their functions' lines nor kernels (and, for a module
    without functions, that were never imported), given the executed lines by file."""
    out = []
    for name, path in project_modules().items():
        ran = executed.get(str(path), set())
        fn = function_lines(path)
        if fn & ran or called_kernels(sys.modules.get(name)):
            continue
        if not fn and (ran or name in sys.modules):
            continue
        out.append(name)
    return out


def pytest_configure(config):
    global _cov
    try:
        import coverage
    except ImportError:
        raise pytest.UsageError("--tiercheck needs coverage.py (in the test extra: "
                                "pip install -e '.[test]')") from None

    _cov = coverage.Coverage(source=[str(p) for p in PACKAGES], data_file=None,
                             branch=False, config_file=False)
    _cov.start()


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session, exitstatus):
    global _missing
    if _cov is None:
        return
    _cov.stop()
    data = _cov.get_data()
    _missing = unexercised({f: set(data.lines(f) or ()) for f in data.measured_files()})
    if _missing and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter):
    if _missing is None:
        return
    n = len(project_modules())
    if _missing:
        terminalreporter.write_line(
            f"tiercheck: {len(_missing)} of {n} modules not exercised by this run (give "
            f"each a fast test or a doctest): {', '.join(_missing)}", red=True)
    else:
        terminalreporter.write_line(f"tiercheck: all {n} modules exercised", green=True)

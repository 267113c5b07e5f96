"""The fast tier's promise that every module is exercised, and the check behind it.

``make test-fast`` runs the tests marked ``fast`` and every doctest; ``make
test-fast-coverage`` runs the same with ``--tiercheck`` (tests/tiercheck.py), which fails
unless each module under geoterrain/ and cli/ ran one of its functions. Here: every
module imports, and the check names the modules that ran nothing.
"""

from __future__ import annotations

import importlib

import pytest
import tiercheck

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def test_every_module_imports():
    mods = tiercheck.project_modules()
    assert {"geoterrain", "geoterrain.terrain", "geoterrain.store.size", "geoterrain.cli",
            "geoterrain.cli.main", "geoterrain.preprocessing.bands.delta"} <= set(mods)
    for name, path in mods.items():
        assert importlib.import_module(name).__file__ == str(path)


def test_function_lines_are_the_statements_inside_functions(tmp_path):
    src = tmp_path / "m.py"
    src.write_text('"""A module."""\n'        # 1
                   "X = 1\n"                  # 2
                   "\n"                       # 3
                   "def f(a):\n"              # 4
                   '    """f."""\n'           # 5
                   "    return a + 1\n"       # 6
                   "\n"                       # 7
                   "class C:\n"               # 8
                   "    def m(self):\n"       # 9
                   "        if self:\n"       # 10
                   "            return 2\n")  # 11
    assert tiercheck.function_lines(src) == {6, 10, 11}


def test_a_module_that_ran_none_of_its_functions_is_named():
    path = tiercheck.project_modules()["geoterrain.store.size"]
    body = tiercheck.function_lines(path)
    defs = {i + 1 for i, ln in enumerate(path.read_text().splitlines())
            if ln.startswith("def ")}
    assert body and defs and not body & defs
    # nothing ran: size.py (functions, no kernels) and the CLI's modules are named
    missing = tiercheck.unexercised({})
    assert {"geoterrain.store.size", "geoterrain.cli.info"} <= set(missing)
    # its import alone (the def lines) is not enough; one line inside a function is
    assert "geoterrain.store.size" in tiercheck.unexercised({str(path): defs})
    assert "geoterrain.store.size" not in tiercheck.unexercised({str(path): {min(body)}})

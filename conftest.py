"""Doctest names: ``t`` is a small preprocessed terrain, as in the docstrings' examples.

Doctests belong to the fast tier (``make test-fast``, marker ``fast``): each module's
examples are its cheapest check. ``--tiercheck`` (``make test-fast-coverage``) fails the
run unless it exercised every module (tests/tiercheck.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# numba's cache does not tell bounds-checked code from plain code: a run with
# NUMBA_BOUNDSCHECK=1 (make test-boundscheck) keeps its compiled kernels apart, so neither
# run loads the other's
if os.environ.get("NUMBA_BOUNDSCHECK") == "1" and not os.environ.get("NUMBA_CACHE_DIR"):
    os.environ["NUMBA_CACHE_DIR"] = str(Path(__file__).parent / ".numba-boundscheck")


def pytest_addoption(parser):
    parser.addoption("--tiercheck", action="store_true",
                     help="fail unless the run exercised every module of geoterrain "
                          "(traced with coverage.py; see tests/tiercheck.py)")


def pytest_configure(config):
    if config.getoption("--tiercheck"):
        import tiercheck

        config.pluginmanager.register(tiercheck, "tiercheck")


@pytest.hookimpl(tryfirst=True)  # before -m deselects by marker
def pytest_collection_modifyitems(items):
    for item in items:
        if type(item).__name__ == "DoctestItem":
            item.add_marker(pytest.mark.fast)


@pytest.fixture(scope="session")
def _doctest_terrain(tmp_path_factory):
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    d = tmp_path_factory.mktemp("doctest")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 129, seed=3))
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32))
    yield t
    t.close()


@pytest.fixture(autouse=True)
def _doctest_names(request):
    if type(request.node).__name__ == "DoctestItem":
        ns = request.getfixturevalue("doctest_namespace")
        ns["t"] = request.getfixturevalue("_doctest_terrain")
        ns["View"] = __import__("geoterrain.core.view", fromlist=["View"]).View

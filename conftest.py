"""Doctest names: ``t`` is a small preprocessed terrain, as in the docstrings' examples."""

from __future__ import annotations

import pytest


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

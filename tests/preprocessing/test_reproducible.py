"""The same input and options write the same bytes: users and caches compare store hashes."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

import geoterrain
from geoterrain.ingest.synth import generate
from tests.conftest import write_tif


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.fast
@pytest.mark.parametrize("case", ["lossless", "lossy", "geographic", "streamed"])
def test_two_runs_write_the_same_bytes(tmp_path, case):
    z = generate("fbm", 70, seed=4).astype(np.float32)[:, :61]
    kw: dict = {"tile_size": 16}
    if case == "geographic":
        src = write_tif(tmp_path / "d.tif", z, crs="EPSG:4326", origin=(10.0, 61.0),
                        spacing=0.01)
    else:
        src = write_tif(tmp_path / "d.tif", z)
    if case == "lossy":
        kw["codec_error"] = 0.5
    if case == "streamed":
        kw["memory_limit"] = 1  # below any whole grid: read a window at a time
    times: dict = {}
    a = geoterrain.preprocess(src, tmp_path / "a.geoterrain", timings=times, **kw)
    b = geoterrain.preprocess(src, tmp_path / "b.geoterrain", **kw)
    assert _digest(a) == _digest(b)
    assert times and all(v >= 0 for v in times.values()) and "write" in times
    with geoterrain.open(a) as t:
        assert "preprocess_seconds" not in t.meta
        assert t.info()["modified"].startswith("20")

"""Shared fixtures: real DEMs from ../shared/dems (skipped when absent) and synthetic ones.

The real-DEM folder defaults to ``../shared/dems`` next to the project root; the
environment variable ``GEOTERRAIN_TEST_DEMS`` points the tests at another folder
(give a missing one, e.g. ``GEOTERRAIN_TEST_DEMS=/nonexistent``, to check that the
suite still runs, on synthetic terrains, on a machine without the real DEMs).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parents[1]
DEMS = Path(os.environ.get("GEOTERRAIN_TEST_DEMS") or ROOT / ".." / "shared" / "dems").resolve()
REAL_DEMS = ["srtm3_pysheds.tif", "srtm1_japan.tif", "roi_epsg3089.tif",
             "fuji_terrain_rgb.png", "st_helens_terrain_rgb.png", "terrarium.png"]

# CI: a fixed example sequence (a red CI must be reproducible); here: new examples each run
settings.register_profile("ci", max_examples=30, deadline=None, derandomize=True)
settings.register_profile("dev", max_examples=60, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture(autouse=True)
def _no_compile_notice(request, monkeypatch):
    """A command's first run says "compiling kernels" on stderr when numba's cache is cold
    (which depends on what ran before); tests that read a command's stderr see it only
    where they test it (tests/core/test_warmup.py)."""
    if request.module.__name__.rsplit(".", 1)[-1] != "test_warmup":
        from geoterrain.core import warmup

        monkeypatch.setattr(warmup, "cold_kernels", lambda modules: [])


@pytest.fixture
def parallel_always(monkeypatch):
    """Every parallel kernel on numba's threads, small work included (small work runs the
    serial twins otherwise: geoterrain/core/threads.py): a test of a fork() child needs
    a parent that has launched parallel regions."""
    import geoterrain.core.threads as threads

    monkeypatch.setattr(threads, "PARALLEL_MIN_SAMPLES", 0)


def has_real_dem(name: str) -> bool:
    """Whether a real DEM is available (for fixtures that add cases rather than skip)."""
    return (DEMS / name).is_file()


def real_dem(name: str) -> Path:
    """Path of a real DEM, or skip the test when the shared folder is absent."""
    p = DEMS / name
    if not p.is_file():
        pytest.skip(f"real DEM {name} not available ({DEMS} absent)")
    return p


@pytest.fixture(params=REAL_DEMS)
def real_dem_path(request) -> Path:
    return real_dem(request.param)


def in_fork(check) -> tuple[bytes, int]:
    """Run ``check()`` (→ bool) in a child made by fork() and return what it reported
    (b"same" or b"different"; nothing if it died) and its wait status. The child never
    returns into pytest."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.write(w, b"same" if check() else b"different")
        finally:
            os._exit(0)
    os.close(w)
    got = os.read(r, 64)
    os.close(r)
    _, status = os.waitpid(pid, 0)
    return got, status


def write_tif(path, z, crs="EPSG:32633", origin=(500000.0, 5000000.0), spacing=10.0,
              nodata=None, dtype=None) -> Path:
    """Write a north-up GeoTIFF of any dtype (for ingest tests)."""
    import rasterio
    from rasterio.transform import from_origin

    z = np.asarray(z)
    dtype = dtype or z.dtype
    prof = dict(driver="GTiff", height=z.shape[0], width=z.shape[1], count=1, dtype=dtype,
                crs=crs, transform=from_origin(origin[0], origin[1], spacing, spacing))
    if nodata is not None:
        prof["nodata"] = nodata
    with rasterio.open(path, "w", **prof) as dst:
        dst.write(z.astype(dtype), 1)
    return Path(path)


@pytest.fixture
def fbm_tif(tmp_path) -> Path:
    from geoterrain.ingest.synth import generate, write_geotiff

    return write_geotiff(tmp_path / "fbm.tif", generate("fbm", 129, seed=3))


def store_pair(tmp_path, z, option: str, nodata=None, tile_size=16, codec_error=None,
               pre=None, **kw):
    """The same DEM (written by :func:`write_tif` with ``kw``) preprocessed with the
    boolean preprocess ``option`` off, then on: two open terrains."""
    import geoterrain

    src = write_tif(tmp_path / "d.tif", z, nodata=nodata, **kw)
    out = []
    for on in (False, True):
        p = geoterrain.preprocess(src, tmp_path / f"d{int(on)}.geoterrain", tile_size=tile_size,
                                  codec_error=codec_error, **{option: on}, **(pre or {}))
        out.append(geoterrain.open(p))
    return out

"""Grid shapes and extents a compiled kernel could mis-index: every one preprocesses, meshes
and selects (or is refused in one line), and no kernel reads or writes outside its arrays.

Run with numba's bounds checks on, in a cache of their own (``make test-boundscheck``:
``NUMBA_BOUNDSCHECK=1``, ``-m 'fast or boundscheck'``): an index outside an array is then
an IndexError instead of a crash or silently wrong memory. Without them the sweep still
catches crashes, and the folded-triangle case below checks the fix directly.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.view import View
from geoterrain.exceptions import GeoterrainError
from tests.conftest import write_tif

pytestmark = pytest.mark.boundscheck
# a few cases in the default suite; the bounds-checked run (make test-boundscheck) sweeps more
EXAMPLES = 60 if os.environ.get("NUMBA_BOUNDSCHECK") == "1" else 6

# sides just below, at and above powers of two, 1 and 2 (a line of samples)
SIDES = sorted({1, 2, 3, *(2**k + d for k in range(2, 7) for d in (-1, 0, 1))})
# (lon0, lat0, degrees east, degrees south) of the whole raster; None: projected / pixel
EXTENTS = {
    "projected": None,
    "pixel": None,
    "global": (-180.0, 90.0, 360.0, 180.0),
    "north_pole": (-180.0, 90.0, 360.0, 12.0),
    "south_pole": (0.0, -75.0, 90.0, 15.0),
    "antimeridian": (170.0, 10.0, 20.0, 8.0),
    "small": (10.0, 61.0, 0.2, 0.1),
}


def _write(tmp_path, rows, cols, extent, heights, seed):
    rng = np.random.default_rng(seed)
    z = (np.full((rows, cols), 250.0) if heights == "flat"
         else rng.uniform(-50, 3000, (rows, cols)))
    if heights == "holes":
        z[rng.random((rows, cols)) < 0.2] = np.nan
    z = z.astype(np.float32)
    ext = EXTENTS[extent]
    if extent == "projected":
        return write_tif(tmp_path / "d.tif", z, spacing=30.0), {}
    if extent == "pixel":
        return write_tif(tmp_path / "d.tif", z, crs=None), {"pixel_size": 5.0}
    lon0, lat0, dx, dy = ext
    import rasterio
    from rasterio.transform import from_origin

    path = tmp_path / "d.tif"
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1,
                       dtype="float32", crs="EPSG:4326", nodata=None,
                       transform=from_origin(lon0, lat0, dx / cols, dy / rows)) as d:
        d.write(z, 1)
    return path, {}


def _exercise(store) -> None:
    """Everything a reader does with a store, on every strategy's kernels once."""
    with geoterrain.open(store) as t:
        for e in (0.0, 5.0):
            t.static_selection(e)
        X, Y, Z = t.scene_xyz()
        ok = np.isfinite(Z)
        c = np.array([X[ok].mean(), Y[ok].mean(), Z[ok].mean()])
        span = max(float(np.ptp(X[ok])), float(np.ptp(Y[ok])), 1.0)
        view = View(tuple(c + np.array([0.3, -1.0, 0.6]) * span), tuple(c), size=(96, 64))
        for strategy in ("rtin", "chunked", "geomipmap", "cdlod"):
            t.select(view, 2.0, strategy)


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(rows=st.sampled_from(SIDES), cols=st.sampled_from(SIDES),
       extent=st.sampled_from(sorted(EXTENTS)), heights=st.sampled_from(["flat", "rough", "holes"]),
       tile=st.sampled_from([2, 4, 16, 64]), seed=st.integers(0, 2**16))
@example(rows=17, cols=33, extent="global", heights="rough", tile=16, seed=1)
@example(rows=1, cols=65, extent="projected", heights="rough", tile=4, seed=2)
@example(rows=65, cols=1, extent="north_pole", heights="flat", tile=4, seed=3)
def test_every_shape_and_extent(tmp_path_factory, rows, cols, extent, heights, tile, seed):
    d = tmp_path_factory.mktemp("sweep")
    src, kw = _write(d, rows, cols, extent, heights, seed)
    try:
        store = geoterrain.preprocess(src, d / "s.geoterrain", tile_size=tile, **kw)
    except GeoterrainError as exc:  # refused: in one line
        assert "\n" not in str(exc) and str(exc)
        return
    _exercise(store)


def test_a_folded_triangle_searches_the_whole_grid():
    """A triangle folded almost flat in metres (a padded global grid's corners beyond a
    pole) has its search margin disp / spacing past 2^63: converting that to an integer was
    undefined (a crash of the 540 × 1080 global grid); it is capped at the grid's side."""
    from geoterrain.bounds.curvature import MetricGrid, _tri_term

    N = 5
    rows, cols = np.indices((N, N)).astype(float)
    X, Y = 1e6 * cols, -1e6 * rows
    X[4, 4], Y[4, 4] = 1e6 * 4 + 1e-9, -1e6 * 4  # (0,0), (4,4), (4,0): almost collinear
    X[4, 0], Y[4, 0] = 2e6, -2e6 + 1e-13
    X[2, 2], Y[2, 2] = 7e6, 9e6  # a sample far from where its indices put it
    g = MetricGrid(X, Y, np.zeros((N, N)), np.ones((N, N), np.bool_), 0.01, N, N)
    m = _tri_term(g, 2, 2, 0, 0, 4, 4, 4, 0, True)[3]
    assert m == N + 2


@pytest.mark.slow
@pytest.mark.parametrize("heights", ["flat", "rough"])
def test_global_grid_540_by_1080(tmp_path, heights):
    """The issue's case: 1/3° cells over −180…180° × −90…90° died with a segfault."""
    src, _ = _write(tmp_path, 540, 1080, "global", heights, 0)
    store = geoterrain.preprocess(src, tmp_path / "g.geoterrain")
    with geoterrain.open(store) as t:
        sel = t.static_selection(100.0)
        assert sel.stats["triangles"] > 0
        assert math.isfinite(t.info()["vertex_error_max"])

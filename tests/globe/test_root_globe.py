"""A root-grid store on the globe (issue 45): sampled through its grid like a square store.

The same projected raster preprocessed as its 2 × 1 (and 1 × 2) root grid and as the
square: the globe's layer heights at random points over both roots, every level, and the
payloads of the nodes over the store are the square's within the two stores' error
bounds (both lossless here: equal), and `render --globe` draws it. The truth for the
heights is the raster itself, bilinear by numpy (no globe code).
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from pyproj import Transformer

import geoterrain
from geoterrain.globe import Globe
from geoterrain.globe.layers import StoreLayer
from geoterrain.globe.payload import make_payload
from tests.conftest import write_tif

#: (CRS, origin, spacing) of the projected and the geographic rasters
FRAMES = {"utm": ("EPSG:32633", (500000.0, 5000000.0), 30.0),
          "geo": ("EPSG:4326", (138.5, 35.5), 1 / 1200)}


def _raster(rows, cols, seed=0):
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 6, (rows, cols)).cumsum(0).cumsum(1) / 10 + 900.0
    z = np.rint(z)
    z[rows // 3:rows // 3 + 4, cols // 2 - 9:cols // 2 - 3] = np.nan  # a void
    return z


@pytest.fixture(scope="module", params=[(65, 129, "utm"), (129, 65, "utm"), (65, 129, "geo")],
                ids=["2x1", "1x2", "2x1-geographic"])
def pair(request, tmp_path_factory):
    """(raster, root-grid store, square store, frame) of one raster, 16-sample tiles."""
    rows, cols, frame = request.param
    crs, origin, spacing = FRAMES[frame]
    d = tmp_path_factory.mktemp("rootglobe")
    z = _raster(rows, cols)
    src = write_tif(d / "z.tif", np.where(np.isnan(z), -9999, z).astype(np.int16), crs=crs,
                    origin=origin, spacing=spacing, nodata=-9999)
    roots = geoterrain.preprocess(src, d / "roots.geoterrain", tile_size=16, root_grid=True)
    square = geoterrain.preprocess(src, d / "square.geoterrain", tile_size=16, root_grid=False)
    with geoterrain.open(roots) as t, geoterrain.open(square) as s:
        assert not t.grid.square and s.grid.square
        assert t.grid.roots == ((2, 1) if cols > rows else (1, 2))
    return z, roots, square, frame


def _lonlat(i, j, frame):
    """WGS 84 lon, lat of fractional level-0 (row, column) (pixel centres at integers)."""
    crs, origin, spacing = FRAMES[frame]
    x = origin[0] + (j + 0.5) * spacing
    y = origin[1] - (i + 0.5) * spacing
    return Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)


def _bilinear(z, i, j, S):
    """Level-S bilinear heights of the raster at level-0 (row, column), NaN where one of
    the four samples is missing (the truth: numpy on the raster)."""
    r0, c0 = np.floor(i / S).astype(int), np.floor(j / S).astype(int)
    fr, fc = i / S - r0, j / S - c0
    sub = z[::S, ::S]
    r1, c1 = np.minimum(r0 + 1, sub.shape[0] - 1), np.minimum(c0 + 1, sub.shape[1] - 1)
    h = (1 - fr) * ((1 - fc) * sub[r0, c0] + fc * sub[r0, c1]) + \
        fr * ((1 - fc) * sub[r1, c0] + fc * sub[r1, c1])
    return h


@pytest.mark.fast
def test_layer_heights_are_the_square_stores_and_the_rasters(pair):
    z, roots, square, frame = pair
    rows, cols = z.shape
    rng = np.random.default_rng(1)
    with geoterrain.open(roots) as t, geoterrain.open(square) as s:
        a, b = StoreLayer(t), StoreLayer(s)
        assert a.spacing == b.spacing
        for level in range(t.grid.top_level + 1):
            S = 1 << level
            i = rng.uniform(0, (rows - 1) // S * S, 3000)
            j = rng.uniform(0, (cols - 1) // S * S, 3000)
            lon, lat = _lonlat(i, j, frame)
            ha, hb = a.heights(lon, lat, level), b.heights(lon, lat, level)
            # both lossless: the same samples, so the same heights, NaN at the same points
            assert np.array_equal(ha, hb, equal_nan=True), level
            want = _bilinear(z, i, j, S)
            ok = np.isfinite(want)
            assert np.array_equal(np.isfinite(ha), ok), level
            assert np.allclose(ha[ok], want[ok], atol=1e-6), level
            far = j > 64 if cols > rows else i > 64  # points in the second root
            assert np.isfinite(ha[far]).sum() > 100
        assert np.array_equal(a.covers(lon, lat), b.covers(lon, lat))
        assert np.array_equal(a.weight(lon, lat), b.weight(lon, lat))


@pytest.mark.slow  # two globes' error tables: about 20 s
def test_globe_payloads_are_the_square_stores(pair):
    _, roots, square, _ = pair
    ga = Globe([roots], node_cells=8, sync=True, feather=2.0)
    gb = Globe([square], node_cells=8, sync=True, feather=2.0)
    try:
        assert ga.table.nodes.keys() == gb.table.nodes.keys()
        deep = [k for k in ga.table.nodes if k[1] >= ga.max_depth - 1]
        assert len(deep) > 4
        for key in deep:
            pa = make_payload(ga.surface, key, normals=False)
            pb = make_payload(gb.surface, key, normals=False)
            assert np.array_equal(pa.elevation, pb.elevation), key
            assert np.array_equal(pa.r, pb.r), key
            assert ga.table.nodes[key].e == gb.table.nodes[key].e
        assert any(np.ptp(make_payload(ga.surface, k, normals=False).elevation) > 1.0
                   for k in deep)  # the store's heights, not the ellipsoid's zero
    finally:
        ga.close()
        gb.close()


@pytest.mark.slow  # about 6 s a store
def test_render_globe_draws_a_root_grid_store(pair, tmp_path):
    from geoterrain.cli.main import cli

    _, roots, _, _ = pair
    out = tmp_path / "g.png"
    res = CliRunner().invoke(cli, ["-q", "render", "--globe", str(roots), "-o", str(out),
                                   "--size", "96x72"])
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 0

"""DEMs whose longitudes run past ±180° (a Pacific grid, or one given in 0…360°): web
tiles and quantized-mesh tiles hold their data on both sides of the antimeridian.

The references are independent of the tilers: a grid shifted by a whole turn (360°) must
give the same tiles byte for byte, and a tile's heights are compared with a bilinear
interpolation of the source GeoTIFF read by rasterio, the pixel's longitude taken to the
grid's own turn.
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from pyproj import Transformer

import geoterrain
from geoterrain.ingest.synth import generate
from tests.conftest import write_tif

pytestmark = pytest.mark.fast


def _store(tmp_path, name, west, z=None):
    z = (generate("fbm", 129, seed=2) * 0.05).astype(np.float32) if z is None else z
    dem = write_tif(tmp_path / f"{name}.tif", z, crs="EPSG:4326", origin=(west, -16.0),
                    spacing=1 / 1200, nodata=-9999)
    return dem, geoterrain.preprocess(dem, tmp_path / f"{name}.geoterrain", tile_size=32)


def test_web_tiles_across_the_antimeridian_hold_the_dem(tmp_path):
    from geoterrain.export.webtiles import HALF, TILE, WebTiler, merc_tile_bounds

    dem, store = _store(tmp_path, "pacific", 179.95)
    with rasterio.open(dem) as src:
        h, inv = src.read(1).astype(np.float64), ~src.transform
    to_geo = Transformer.from_crs("EPSG:3857", "EPSG:4326", always_xy=True)
    with geoterrain.open(store) as t:
        tiler = WebTiler(t)
        z = tiler.max_zoom
        xs, ys = tiler.tile_range(z)
        assert 0 in xs and (1 << z) - 1 in xs and len(xs) == 2
        w, s, e, n = tiler.bounds
        assert -180 <= w <= e <= 180 and s < n
        checked = 0
        for x in xs:
            for y in ys:
                got = tiler.heights(z, x, y, corner=True)
                mw, _, _, mn = merc_tile_bounds(z, x, y)
                res = 2 * HALF / (TILE << z)
                k = np.arange(TILE)
                mx, my = np.meshgrid(mw + k * res, mn - k * res)
                lon, lat = (np.asarray(a) for a in to_geo.transform(mx, my))
                lon = 179.0 + np.mod(lon - 179.0, 360.0)  # the grid's turn
                col, row = inv @ (lon, lat)
                fi, fj = np.asarray(row) - 0.5, np.asarray(col) - 0.5
                ok = (fi >= 0) & (fi <= h.shape[0] - 1) & (fj >= 0) & (fj <= h.shape[1] - 1)
                i0 = np.clip(np.floor(fi[ok]).astype(int), 0, h.shape[0] - 2)
                j0 = np.clip(np.floor(fj[ok]).astype(int), 0, h.shape[1] - 2)
                a, b = fi[ok] - i0, fj[ok] - j0
                ref = ((h[i0, j0] * (1 - b) + h[i0, j0 + 1] * b) * (1 - a)
                       + (h[i0 + 1, j0] * (1 - b) + h[i0 + 1, j0 + 1] * b) * a)
                np.testing.assert_allclose(got[ok], ref, atol=0.01)
                checked += int(ok.sum())
        assert checked > 10000


@pytest.mark.parametrize("west", [-175.0, -180.05])
def test_a_grid_a_whole_turn_east_gives_the_same_tiles(tmp_path, west):
    """The same heights given with longitudes 360° further east (0…360° data) give
    byte-identical web tiles, and the same quantized-mesh tiles (the same vertices and
    triangles; a height may round to the next of its tile's 32 767 steps, and a tie flip
    a quad's diagonal: the interpolation's arithmetic runs on other longitudes)."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.webtiles import WebTiler, encode_image

    _, a = _store(tmp_path, "a", west)
    _, b = _store(tmp_path, "b", west + 360.0)
    with geoterrain.open(a) as ta, geoterrain.open(b) as tb:
        wa, wb = WebTiler(ta), WebTiler(tb)
        assert wa.bounds == pytest.approx(wb.bounds)
        for z in (wa.max_zoom - 2, wa.max_zoom):
            xa, ya = wa.tile_range(z)
            assert list(xa) == list(wb.tile_range(z)[0]) and ya == wb.tile_range(z)[1]
            for x in xa:
                for y in ya:
                    assert encode_image(wa.dem_tile("terrain-rgb", z, x, y)) == \
                        encode_image(wb.dem_tile("terrain-rgb", z, x, y)), (z, x, y)
        write_tileset(ta, tmp_path / "qa", max_error=2.0)
        write_tileset(tb, tmp_path / "qb", max_error=2.0)
    qmt = pytest.importorskip("quantized_mesh_tile")
    from geoterrain.export.qmeshformat import tile_rect

    files = sorted(p.relative_to(tmp_path / "qa") for p in (tmp_path / "qa").glob("*/*/*.terrain"))
    assert files == sorted(p.relative_to(tmp_path / "qb")
                           for p in (tmp_path / "qb").glob("*/*/*.terrain")) and len(files) > 5
    for rel in files:
        z, x, y = int(rel.parts[0]), int(rel.parts[1]), int(rel.stem)
        w, s, e, n = tile_rect(z, x, y)
        got = []
        for root in ("qa", "qb"):
            t = qmt.TerrainTile(west=w, south=s, east=e, north=n)
            t.fromFile(str(tmp_path / root / rel), hasLighting=True, hasWatermask=True,
                       gzipped=True)
            v = np.array(t.getVerticesCoordinates())
            order = np.lexsort((v[:, 1], v[:, 0]))
            got.append((v[order], len(t.indices),
                        (t.header["maximumHeight"] - t.header["minimumHeight"]) / 32767))
        (va, na, step), (vb, nb, _) = got
        assert na == nb, rel  # the same triangles (a tie may flip a quad's diagonal)
        np.testing.assert_allclose(va[:, :2], vb[:, :2], atol=1e-9, err_msg=str(rel))
        assert np.abs(va[:, 2] - vb[:, 2]).max() <= step + 1e-6, rel

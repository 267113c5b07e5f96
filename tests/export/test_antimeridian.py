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


# ------------------------------------------------------------------ whole-globe grids
def _globe(tmp_path, cols=180):
    """A whole-globe grid (its columns span exactly 360°, cell edges at ±180°): column 0
    follows the last one across the antimeridian, half a cell either side of it."""
    rows = cols // 2
    g = generate("fbm", 513 if cols > 257 else 257, seed=4)[:rows, :cols]
    z = (np.pad(g, ((0, 0), (0, cols - g.shape[1])), mode="reflect") * 0.5).astype(np.float32)
    dem = write_tif(tmp_path / "globe.tif", z, crs="EPSG:4326", origin=(-180.0, 90.0),
                    spacing=360.0 / cols, nodata=-9999)
    return dem, geoterrain.preprocess(dem, tmp_path / "globe.geoterrain", tile_size=32)


def _periodic_bilinear(h: np.ndarray, inv, lon, lat) -> tuple[np.ndarray, np.ndarray]:
    """The GeoTIFF's bilinear at lon/lat, its columns wrapping (column W is column 0), and
    where it is defined (between the first and last rows' centres)."""
    col, row = inv @ (np.mod(lon + 180.0, 360.0) - 180.0, lat)
    fi, fj = np.asarray(row) - 0.5, np.mod(np.asarray(col) - 0.5, h.shape[1])
    ok = (fi >= 0) & (fi <= h.shape[0] - 1)
    i0 = np.clip(np.floor(fi).astype(int), 0, h.shape[0] - 2)
    j0 = np.floor(fj).astype(int)
    a, b = fi - i0, fj - j0
    j1 = (j0 + 1) % h.shape[1]
    ref = ((h[i0, j0] * (1 - b) + h[i0, j1] * b) * (1 - a)
           + (h[i0 + 1, j0] * (1 - b) + h[i0 + 1, j1] * b) * a)
    return ref, ok


def test_web_tiles_of_a_whole_globe_grid_have_no_seam_at_the_antimeridian(tmp_path):
    """Every pixel between the first and last rows is a height: at the zoom that reads
    level 0 it is the GeoTIFF's bilinear with its columns wrapping; at coarser zooms
    (levels whose lattice does not divide the turn) no pixel is missing either."""
    from geoterrain.export.webtiles import HALF, TILE, WebTiler, merc_tile_bounds

    dem, store = _globe(tmp_path, cols=515)  # odd: level 1's lattice does not divide the turn
    with rasterio.open(dem) as src:
        h, inv = src.read(1).astype(np.float64), ~src.transform
    to_geo = Transformer.from_crs("EPSG:3857", "EPSG:4326", always_xy=True)
    with geoterrain.open(store) as t:
        tiler = WebTiler(t)
        assert tiler.bounds[0] == -180.0 and tiler.bounds[2] == 180.0
        zs = list(range(tiler.max_zoom + 1))
        levels = [tiler.level_for(z) for z in zs]
        assert 0 in levels and any(515 % (1 << L) for L in levels), levels
        for z in zs:
            xs, ys = tiler.tile_range(z)
            assert list(xs) == list(range(1 << z))
            for x in (xs[0], xs[-1]):  # the tiles either side of the antimeridian
                for y in ys:
                    got = tiler.heights(z, x, y, corner=True).ravel()
                    mw, _, _, mn = merc_tile_bounds(z, x, y)
                    res = 2 * HALF / (TILE << z)
                    k = np.arange(TILE)
                    mx, my = np.meshgrid(mw + k * res, mn - k * res)
                    lon, lat = (np.asarray(a).ravel() for a in to_geo.transform(mx, my))
                    ref, ok = _periodic_bilinear(h, inv, lon, lat)
                    assert np.isfinite(got[ok]).all(), (z, x, y)
                    if tiler.level_for(z) == 0:
                        np.testing.assert_allclose(got[ok], ref[ok], atol=0.01)


def test_quantized_mesh_tiles_of_a_whole_globe_grid_cover_the_antimeridian(tmp_path):
    """Between the last column's centre and the first's (across 180°) the finest tiles
    have triangles, and the samples of the columns either side lie within the declared
    error: written (rtin and tin) and served (each tile built from the level-0 tiles
    under it, across both ends of the grid)."""
    import gzip
    import json

    import matplotlib.tri as mtri

    qmt = pytest.importorskip("quantized_mesh_tile")
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.qmeshformat import tile_rect
    from geoterrain.export.qmeshtiles import QuantizedMeshTiles

    dem, store = _globe(tmp_path)  # 2° cells, 17² lattices: the finest tiles are zoom 3
    with rasterio.open(dem) as src:
        h, transform = src.read(1).astype(np.float64), src.transform
    rng = np.random.default_rng(5)
    lat = rng.uniform(-88.0, 88.0, 400)  # within one cell of 180° (the centres at ±179°)
    lon = np.where(rng.random(400) < 0.5, rng.uniform(179.0, 180.0, 400),
                   rng.uniform(-180.0, -179.0, 400))
    rows, cols = np.meshgrid(np.arange(h.shape[0]), [0, 1, h.shape[1] - 2, h.shape[1] - 1],
                             indexing="ij")
    slon, slat = (np.asarray(a) for a in rasterio.transform.xy(transform, rows.ravel(),
                                                               cols.ravel()))
    sh = h[rows.ravel(), cols.ravel()]

    def check(folder, zmax, declared):
        covered = np.zeros(len(lon), bool)
        for p in folder.glob(f"{zmax}/*/*.terrain"):
            x, y = int(p.parent.name), int(p.stem)
            w, s, e, n = tile_rect(zmax, x, y)
            tile = qmt.TerrainTile(west=w, south=s, east=e, north=n)
            tile.fromFile(str(p), hasLighting=True, hasWatermask=True, gzipped=True)
            v = np.array(tile.getVerticesCoordinates(), np.float64)
            interp = mtri.LinearTriInterpolator(mtri.Triangulation(
                v[:, 0], v[:, 1], np.array(tile.indices).reshape(-1, 3)), v[:, 2])
            lon_t = w + np.mod(lon - w, 360.0)  # the tile's turn
            inside = (lon_t <= e) & (lat >= s) & (lat <= n)
            surf = np.ma.filled(interp(lon_t[inside], lat[inside]), np.nan)
            covered[np.flatnonzero(inside)[np.isfinite(surf)]] = True
            lon_t = w + np.mod(slon - w, 360.0)
            inside = (lon_t <= e) & (slat >= s) & (slat <= n)
            surf = np.ma.filled(interp(lon_t[inside], slat[inside]), np.nan)
            err = np.abs(surf - sh[inside])
            assert np.nanmax(err, initial=0.0) <= declared[f"{zmax}/{x}/{y}"] + 1e-3, p
        assert covered.all(), folder  # no hole along the antimeridian

    for mesher in ("rtin", "tin"):
        out, served = tmp_path / f"tiles_{mesher}", tmp_path / f"served_{mesher}"
        with geoterrain.open(store) as t:
            write_tileset(t, out, max_error=2.0, mesher=mesher, lattice=17)
            declared = json.loads((out / "geoterrain.json").read_text())["declared_error"]
            zmax = max(int(p.name) for p in out.iterdir() if p.name.isdigit())
            q = QuantizedMeshTiles(t, mesher=mesher, lattice=17)
            assert zmax >= 2
            check(out, zmax, declared)
            for x, y in q.level_tiles(zmax):
                if x not in (0, (2 << zmax) - 1):  # the columns either side of 180°
                    continue
                data, declared[f"{zmax}/{x}/{y}"], _ = q.tile(zmax, x, y)
                (served / str(zmax) / str(x)).mkdir(parents=True, exist_ok=True)
                (served / str(zmax) / str(x) / f"{y}.terrain").write_bytes(gzip.compress(data))
            check(served, zmax, declared)

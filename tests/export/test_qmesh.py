"""Cesium quantized-mesh tile sets, read back with an independent decoder.

quantized-mesh-tile decodes every tile; the tests then check, against the source
DEM read with rasterio: heights within each tile's declared error, edge vertices
shared exactly by neighbouring tiles, no vertex next to a nodata sample, and a
layer.json that lists exactly the tiles written.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.tri as mtri
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.export.qmeshformat import tile_rect
from tests.conftest import real_dem, write_tif

qmt = pytest.importorskip("quantized_mesh_tile")


def _read_tileset(out: Path, dem: Path):
    tiles = {}
    for p in sorted(out.glob("*/*/*.terrain")):
        z_, x, y = int(p.parent.parent.name), int(p.parent.name), int(p.stem)
        w, s, e, n = tile_rect(z_, x, y)
        t = qmt.TerrainTile(west=w, south=s, east=e, north=n)
        t.fromFile(str(p), hasLighting=True, hasWatermask=True, gzipped=True)
        tiles[(z_, x, y)] = t
    with rasterio.open(dem) as src:
        h = src.read(1, masked=True)
        transform = src.transform
    return out, tiles, h, transform


def _japan(tmp_path_factory, mesher: str):
    from geoterrain.export.qmesh import write_tileset

    dem = real_dem("srtm1_japan.tif")
    d = tmp_path_factory.mktemp(f"qmesh_japan_{mesher}")
    with geoterrain.open(geoterrain.preprocess(dem, d / "j.geoterrain")) as t:
        write_tileset(t, d / "tiles", mesher=mesher)
    return _read_tileset(d / "tiles", dem)


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    """srtm1_japan (slow: about 90 s to tile, more to decode in pure Python)."""
    return _japan(tmp_path_factory, "rtin")


@pytest.fixture(scope="module")
def japan_tin(tmp_path_factory):
    """srtm1_japan on TIN tiles (slow)."""
    return _japan(tmp_path_factory, "tin")


SETS = ["tileset", "tileset_tin", "roots", "roots_tin",
        pytest.param("japan", marks=pytest.mark.slow),
        pytest.param("japan_tin", marks=pytest.mark.slow)]


@pytest.fixture(scope="module")
def tileset(tmp_path_factory):
    return _synthetic_tileset(tmp_path_factory, "rtin")


@pytest.fixture(scope="module")
def tileset_tin(tmp_path_factory):
    """The same DEM on TIN tiles (tiles --mesher tin)."""
    return _synthetic_tileset(tmp_path_factory, "tin")


def _synthetic_tileset(tmp_path_factory, mesher: str):
    from geoterrain.cli.main import cli
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp(f"qmesh_{mesher}")
    # gentle relief (so not every border sample is needed by its own error), straddling
    # tile boundaries of levels 10 and 11 in both directions
    z = generate("fbm", 129, seed=4).astype(np.float32) * 0.05
    z[10:40, 70:110] = -9999  # a nodata hole inside the DEM
    z[:, :6] = -9999  # and a nodata margin
    dem = write_tif(d / "geo.tif", z, crs="EPSG:4326", origin=(138.45, 35.55),
                    spacing=1 / 1200, nodata=-9999)
    store = geoterrain.preprocess(dem, tile_size=32)
    out = d / "tiles"
    res = CliRunner().invoke(cli, ["-q", "tiles", str(store), "-o", str(out),
                                   "--format", "quantized-mesh", "--max-error", "2",
                                   "--mesher", mesher], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return _read_tileset(out, dem)


@pytest.fixture(scope="module")
def roots(tmp_path_factory):
    """A wide geographic DEM on its 2 × 1 root grid (the default layout; issue 45)."""
    return _roots_tileset(tmp_path_factory, "rtin")


@pytest.fixture(scope="module")
def roots_tin(tmp_path_factory):
    return _roots_tileset(tmp_path_factory, "tin")


def _roots_tileset(tmp_path_factory, mesher: str):
    """65 × 193 samples of 3″ in EPSG:4326 (a void inside, a nodata margin on the east),
    across a tile boundary of levels 10 and 11 both ways; 32-sample store tiles: 2 × 1
    root tiles over a 65 × 193 lattice (the square would be 257²)."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp(f"qmesh_roots_{mesher}")
    z = generate("fbm", (65, 193), seed=6).astype(np.float32) * 0.05
    z[20:35, 120:150] = -9999
    z[:, -5:] = -9999
    # the level-10 (and 11) tile edges at 138.515625° E and 35.5078125° N cross it
    dem = write_tif(d / "wide.tif", z, crs="EPSG:4326", origin=(138.435625, 35.5328125),
                    spacing=1 / 1200, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, tile_size=32)) as t:
        assert (t.frame.kind, t.grid.layout, t.grid.roots) == ("geographic", "roots", (2, 1))
        write_tileset(t, d / "tiles", max_error=2.0, mesher=mesher)
    return _read_tileset(d / "tiles", dem)


@pytest.fixture(scope="module")
def steep(tmp_path_factory):
    """Rough relief at 1" (0–200 m over 2 km): the resampling error is a large share of
    the fine levels' geometric error, so the per-tile threshold has to leave room for it."""
    return _steep(tmp_path_factory, "rtin")


@pytest.fixture(scope="module")
def steep_tin(tmp_path_factory):
    return _steep(tmp_path_factory, "tin")


def _steep(tmp_path_factory, mesher: str):
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp(f"qmesh_steep_{mesher}")
    z = generate("fbm", 65, seed=9).astype(np.float32) * 0.1
    dem = write_tif(d / "steep.tif", z, crs="EPSG:4326", origin=(138.71, 35.37),
                    spacing=1 / 3600, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, tile_size=32)) as t:
        write_tileset(t, d / "tiles", max_error=2.0, mesher=mesher)
    return _read_tileset(d / "tiles", dem)


def _coords(t):
    v = np.array(t.getVerticesCoordinates(), np.float64)
    return v[:, 0], v[:, 1], v[:, 2]


@pytest.mark.fast
@pytest.mark.parametrize("which", SETS)
def test_every_tile_decodes_with_its_extensions(which, request):
    tileset = request.getfixturevalue(which)
    out, tiles, _, _ = tileset
    layer = json.loads((out / "layer.json").read_text())
    assert layer["format"] == "quantized-mesh-1.0" and layer["scheme"] == "tms"
    assert set(layer["extensions"]) == {"octvertexnormals", "watermask"}
    listed = {(z, x, y) for z, rects in enumerate(layer["available"]) for r in rects
              for x in range(r["startX"], r["endX"] + 1) for y in range(r["startY"], r["endY"] + 1)}
    assert listed == set(tiles)
    assert {(0, 0, 0), (0, 1, 0)} <= set(tiles)
    assert layer["maxzoom"] == max(z for z, _, _ in tiles)
    for t in tiles.values():
        lon, lat, hgt = _coords(t)
        assert len(t.indices) % 3 == 0 and len(t.indices) > 0
        assert len(t.vLight) == len(lon)  # one oct-encoded normal per vertex
        assert np.allclose(np.linalg.norm(np.array(t.vLight), axis=1), 1, atol=0.02)
        assert len(t.watermask) == 1


@pytest.mark.fast
@pytest.mark.parametrize("which", [*SETS, "steep", "steep_tin"])
def test_heights_within_the_declared_error_of_the_dem(which, request):
    tileset = request.getfixturevalue(which)
    out, tiles, h, transform = tileset
    declared = json.loads((out / "geoterrain.json").read_text())["declared_error"]
    rows, cols = np.mgrid[0:h.shape[0], 0:h.shape[1]]
    slon, slat = rasterio.transform.xy(transform, rows.ravel(), cols.ravel())
    slon, slat = np.asarray(slon), np.asarray(slat)
    dem = h.filled(np.nan).ravel()
    checked = 0
    for (z, x, y), t in tiles.items():
        lon, lat, hgt = _coords(t)
        w, s, e, n = tile_rect(z, x, y)
        inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n) & np.isfinite(dem)
        if not inside.any():
            continue
        tri = mtri.Triangulation(lon, lat, np.array(t.indices).reshape(-1, 3))
        surf = np.ma.filled(mtri.LinearTriInterpolator(tri, hgt)(slon[inside], slat[inside]),
                            np.nan)
        diff = np.abs(surf - dem[inside])
        diff = diff[np.isfinite(diff)]
        checked += len(diff)
        assert diff.max(initial=0) <= declared[f"{z}/{x}/{y}"] + 1e-3, (z, x, y)
    assert checked > 10000


@pytest.mark.fast
@pytest.mark.parametrize("which", [*SETS, "steep", "steep_tin"])
def test_declared_errors_fit_cesiums_level_error(which, request):
    """Below max zoom each tile's declared error (an a-priori bound: resampling error +
    largest left-out δ + quantisation) is ≤ Cesium's levelMaximumGeometricError."""
    from geoterrain.export.qmeshformat import cesium_level_error

    out, tiles, _, _ = request.getfixturevalue(which)
    info = json.loads((out / "geoterrain.json").read_text())
    zmax = info["max_zoom"]
    below = [(k, v) for k, v in info["declared_error"].items() if int(k.split("/")[0]) < zmax]
    assert len(below) > 5
    for k, v in below:
        assert v <= cesium_level_error(int(k.split("/")[0])) + 1e-4, k
    assert info["over_level_error"] == sum(
        v > info["levels"][k.split("/")[0]]["level_error"] + 1e-4
        for k, v in info["declared_error"].items())


@pytest.mark.fast
@pytest.mark.parametrize("which", SETS)
def test_neighbours_share_their_edge_vertices_exactly(which, request):
    tileset = request.getfixturevalue(which)
    _, tiles, _, _ = tileset
    pairs = set()
    for (z, x, y), t in tiles.items():
        for (dx, dy), mine, theirs in (((1, 0), "eastI", "westI"), ((0, 1), "northI", "southI")):
            o = tiles.get((z, x + dx, y + dy))
            if o is None:
                continue
            a = np.array(_coords(t)).T[getattr(t, mine)]
            b = np.array(_coords(o)).T[getattr(o, theirs)]
            a, b = a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]
            assert a.shape == b.shape and len(a) > 0, (z, x, y, dx, dy)
            assert np.array_equal(a[:, 2], b[:, 2])  # identical heights
            along = 1 if dx else 0  # latitude along an east edge, longitude along a north one
            assert np.allclose(a[:, along], b[:, along], rtol=0, atol=1e-9)
            pairs.add((z, dx))
    assert {(10, 1), (10, 0), (11, 1), (11, 0)} <= pairs  # east and north edges, two levels


@pytest.mark.fast
@pytest.mark.parametrize("which", SETS)
def test_no_vertex_at_a_nodata_sample(which, request):
    tileset = request.getfixturevalue(which)
    _, tiles, h, transform = tileset
    bad = np.ma.getmaskarray(h)
    inv = ~transform
    for (z, _, _), t in tiles.items():
        if z < 8:  # the flat placeholder tiles of the coarsest levels lie outside the grid
            continue
        lon, lat, _ = _coords(t)
        c = inv.a * lon + inv.b * lat + inv.c - 0.5  # sample (pixel-centre) coordinates
        r = inv.d * lon + inv.e * lat + inv.f - 0.5
        assert (r > -1e-6).all() and (c > -1e-6).all()
        assert (r < h.shape[0] - 1 + 1e-6).all() and (c < h.shape[1] - 1 + 1e-6).all()
        r0, c0 = np.floor(r + 1e-9).astype(int), np.floor(c + 1e-9).astype(int)
        for dr in (0, 1):
            for dc in (0, 1):
                rr = np.minimum(r0 + dr, h.shape[0] - 1)
                cc = np.minimum(c0 + dc, h.shape[1] - 1)
                near = (np.abs(r - rr) < 1) & (np.abs(c - cc) < 1)
                assert not bad[rr[near], cc[near]].any()


@pytest.mark.fast
def test_an_unknown_tile_mesher_is_refused_before_anything_is_written(tileset, tmp_path):
    from geoterrain.cli.main import cli
    from geoterrain.exceptions import UsageError
    from geoterrain.export.qmesh import write_tileset

    out, _, _, _ = tileset
    store = next(out.parent.glob("*.geoterrain"))
    res = CliRunner().invoke(cli, ["tiles", str(store), "-o", str(tmp_path / "a"),
                                   "--mesher", "delatin"])
    assert res.exit_code == 2 and "delatin" in res.stderr
    with geoterrain.open(store) as t, pytest.raises(UsageError, match="unknown tile mesher"):
        write_tileset(t, tmp_path / "b", mesher="delatin")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.fast
@pytest.mark.parametrize("mesher", ["rtin", "tin"])
def test_a_projected_dem_tiles_at_every_level(tmp_path, mesher):
    """roi_epsg3089 (Kentucky, feet): the coarse tiles reach past the projection's domain
    (pyproj gives inf there); every level is written and every tile decodes."""
    from geoterrain.export.qmesh import write_tileset

    dem = real_dem("roi_epsg3089.tif")
    with geoterrain.open(geoterrain.preprocess(dem, tmp_path / "r.geoterrain")) as t:
        stats = write_tileset(t, tmp_path / "tiles", mesher=mesher)
    _, tiles, _, _ = _read_tileset(tmp_path / "tiles", dem)
    assert len(tiles) == stats["tiles"] and stats["max_zoom"] == 15
    assert {z for z, _, _ in tiles} == set(range(16))
    assert all(len(t.indices) >= 3 for t in tiles.values())


@pytest.mark.fast
def test_tiles_refuses_to_overwrite_a_layer(tileset):
    from geoterrain.cli.main import cli

    out, _, _, _ = tileset
    store = next(out.parent.glob("*.geoterrain"))
    res = CliRunner().invoke(cli, ["tiles", str(store), "-o", str(out)])
    assert res.exit_code == 2 and "exists" in res.stderr


def test_geoid_gives_ellipsoidal_heights_within_the_declared_error(tmp_path):
    """--geoid egm96: decoded heights are the DEM's + the EGM96 undulation N (pyproj here,
    straight from the grid), within each tile's declared error; without the grid, a
    one-line error."""
    from pyproj import Transformer

    from geoterrain.cli.main import cli
    from geoterrain.exceptions import UsageError
    from geoterrain.export.qmeshdem import geoid_transformer
    from geoterrain.ingest.synth import generate

    z = generate("fbm", 65, seed=2).astype(np.float32) * 0.1
    dem = write_tif(tmp_path / "g.tif", z, crs="EPSG:4326", origin=(138.71, 35.37),
                    spacing=1 / 3600, nodata=-9999)
    store = geoterrain.preprocess(dem, tile_size=32)
    try:
        geoid_transformer()
    except UsageError as exc:
        res = CliRunner().invoke(cli, ["tiles", str(store), "-o", str(tmp_path / "t"),
                                       "--geoid", "egm96"])
        assert res.exit_code == 2 and "proj-data" in res.stderr
        pytest.skip(f"no EGM96 grid: {exc}")
    res = CliRunner().invoke(cli, ["-q", "tiles", str(store), "-o", str(tmp_path / "t"),
                                   "--geoid", "egm96"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    out, tiles, h, transform = _read_tileset(tmp_path / "t", dem)
    info = json.loads((out / "geoterrain.json").read_text())
    assert info["heights"].startswith("WGS 84 ellipsoidal")
    rows, cols = np.mgrid[0:h.shape[0], 0:h.shape[1]]
    slon, slat = (np.asarray(a) for a in rasterio.transform.xy(transform, rows.ravel(),
                                                                   cols.ravel()))
    tr = Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True)
    ell = np.asarray(tr.transform(slon, slat, h.filled(np.nan).ravel())[2])
    assert 35 < np.nanmean(ell - h.filled(np.nan).ravel()) < 45  # N ≈ +40 m at Fuji
    zmax = info["max_zoom"]
    t = tiles[max(k for k in tiles if k[0] == zmax)]
    lon, lat, hgt = _coords(t)
    w, s, e, n = tile_rect(*max(k for k in tiles if k[0] == zmax))
    inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n)
    surf = mtri.LinearTriInterpolator(mtri.Triangulation(lon, lat, np.array(t.indices)
                                                         .reshape(-1, 3)), hgt)
    diff = np.abs(np.ma.filled(surf(slon[inside], slat[inside]), np.nan) - ell[inside])
    key = "/".join(map(str, max(k for k in tiles if k[0] == zmax)))
    assert np.nanmax(diff) <= info["declared_error"][key] + 1e-3
    assert np.isfinite(diff).sum() > 100


def test_rough_levels_are_rebuilt_on_a_finer_lattice(tmp_path):
    """Where the resampling error leaves no room under the level error, the whole level is
    rebuilt on a 257² lattice: its tiles still hold their declared bound at every DEM
    sample and still share edge vertices; tiles over the level error are counted."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.ingest.synth import generate

    z = generate("fbm", 65, seed=9).astype(np.float32)  # 0–2000 m over 2 km
    dem = write_tif(tmp_path / "rough.tif", z, crs="EPSG:4326", origin=(138.71, 35.37),
                    spacing=1 / 3600, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, tile_size=32)) as t:
        write_tileset(t, tmp_path / "tiles", max_error=2.0, mesher="rtin")
    out, tiles, h, transform = _read_tileset(tmp_path / "tiles", dem)
    info = json.loads((out / "geoterrain.json").read_text())
    fine = [int(z) for z, v in info["levels"].items() if v["lattice"] == 257]
    assert fine and max(fine) < info["max_zoom"]
    rows, cols = np.mgrid[0:h.shape[0], 0:h.shape[1]]
    slon, slat = (np.asarray(a) for a in rasterio.transform.xy(transform, rows.ravel(),
                                                                   cols.ravel()))
    dem_h = h.filled(np.nan).ravel()
    checked = 0
    for (zz, x, y), tile in tiles.items():
        if zz not in fine:
            continue
        lon, lat, hgt = _coords(tile)
        w, s, e, n = tile_rect(zz, x, y)
        step = np.diff(np.unique(lon)).min() / (e - w)  # 1/256 on a 257² lattice
        assert abs(step * 256 - 1) < 0.01, (zz, step)
        checked += 1
        inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n)
        tri = mtri.Triangulation(lon, lat, np.array(tile.indices).reshape(-1, 3))
        surf = np.ma.filled(mtri.LinearTriInterpolator(tri, hgt)(slon[inside], slat[inside]),
                            np.nan)
        diff = np.abs(surf - dem_h[inside])
        assert np.nanmax(diff) <= info["declared_error"][f"{zz}/{x}/{y}"] + 1e-3
        o = tiles.get((zz, x + 1, y))
        if o is not None:
            a = np.array(_coords(tile)).T[tile.eastI]
            b = np.array(_coords(o)).T[o.westI]
            assert np.array_equal(np.sort(a[:, 2]), np.sort(b[:, 2]))
    assert checked >= len(fine)
    over = sum(v > info["levels"][k.split("/")[0]]["level_error"] + 1e-4
               for k, v in info["declared_error"].items())
    assert info["over_level_error"] == over


def test_max_zoom_is_capped_by_what_the_data_fills(tmp_path, caplog, monkeypatch):
    """tiles --max-zoom 22 on 1″ SRTM: capped one level past the DEM's resolution, and
    said, within a second (before any height is decoded)."""

    import geoterrain.export.qmesh as Q

    store = geoterrain.preprocess(real_dem("srtm1_japan.tif"), tmp_path / "j.geoterrain")

    class Stop(Exception):
        pass

    def stop(*a, **k):
        raise Stop

    monkeypatch.setattr(Q, "GeoDem", stop)  # the heights: where the work begins
    with geoterrain.open(store) as t:  # (uncapped, zoom 22's tiles would never end)
        with pytest.raises(Stop):
            Q.write_tileset(t, tmp_path / "tiles", max_zoom=22)
        fill = Q.max_zoom_for(Q.pixel_degrees(t), 129)
    assert fill == 13
    assert f"capped at {fill + 1}" in caplog.text


@pytest.mark.fast
def test_served_levels_list_the_written_tiles_when_the_dem_edge_is_a_tile_edge(tmp_path):
    """The DEM's west edge on a tile boundary at level 9: the tile west of it holds only a
    line of samples along its east edge, no triangle. The writer leaves it out (a flat tile
    there would list other vertices than its neighbour along their edge), and so does the
    server, which finds each tile's lattice validity without building it."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.qmeshtiles import QuantizedMeshTiles
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", (24, 24), seed=0) * 0.02).astype(np.float32)
    dem = write_tif(tmp_path / "d.tif", z, crs="EPSG:4326",
                    origin=(138.515625 - 1 / 512, 35.5078125), spacing=1 / 1200, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, tmp_path / "d.geoterrain",
                                               tile_size=32)) as t:
        write_tileset(t, tmp_path / "t", min_zoom=9, mesher="rtin")
        q = QuantizedMeshTiles(t, mesher="rtin")
        written = {(int(p.parent.parent.name), int(p.parent.name), int(p.stem))
                   for p in (tmp_path / "t").glob("*/*/*.terrain")}
        assert {9, 10, 11} <= {k[0] for k in written} and (9, 906, 356) in written
        assert (9, 905, 356) not in written
        for zz in range(9, q.max_zoom + 1):
            assert {(x, y) for x, y in q.level_tiles(zz)} == {k[1:] for k in written
                                                              if k[0] == zz}, zz


@pytest.mark.fast
@pytest.mark.parametrize("mesher", ["rtin", "tin"])
def test_a_grid_past_the_antimeridian_wraps_onto_the_western_tiles(tmp_path, mesher):
    """A geographic grid whose longitudes run past 180° (179.95°…180.06°, as a Pacific
    DEM in 0…360° comes): the tiles west of the antimeridian hold its east end, every
    valid sample lies within its tile's declared error, the served set is the written
    one, no numpy warning reaches the user, and the layer's bounds cross (west > east)."""
    import warnings

    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.qmeshtiles import QuantizedMeshTiles
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", 129, seed=2) * 0.05).astype(np.float32)
    dem = write_tif(tmp_path / "pacific.tif", z, crs="EPSG:4326", origin=(179.95, -16.0),
                    spacing=1 / 1200, nodata=-9999)
    out = tmp_path / "tiles"
    with geoterrain.open(geoterrain.preprocess(dem, tmp_path / "p.geoterrain",
                                               tile_size=32)) as t:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            write_tileset(t, out, max_error=2.0, mesher=mesher)
        q = QuantizedMeshTiles(t, mesher=mesher)
        written = {(int(p.parent.parent.name), int(p.parent.name), int(p.stem))
                   for p in out.glob("*/*/*.terrain")}
        for zz in range(q.max_zoom + 1):
            assert set(q.level_tiles(zz)) == {k[1:] for k in written if k[0] == zz}, zz
    zmax = max(k[0] for k in written)
    east = {x for zz, x, _ in written if zz == zmax and x >= 1 << zmax}
    west = {x for zz, x, _ in written if zz == zmax and x < 1 << zmax}
    assert east and west and 0 in west and (2 << zmax) - 1 in east  # both sides of 180°
    layer = json.loads((out / "layer.json").read_text())
    w, s, e, n = layer["bounds"]
    assert 179.9 < w < 180 and -180 < e < -179.9 and s < n
    _, tiles, h, transform = _read_tileset(out, dem)
    declared = json.loads((out / "geoterrain.json").read_text())["declared_error"]
    rows, cols = np.mgrid[0:h.shape[0], 0:h.shape[1]]
    slon, slat = (np.asarray(a) for a in rasterio.transform.xy(transform, rows.ravel(),
                                                               cols.ravel()))
    heights = h.filled(np.nan).ravel()
    covered = np.zeros(len(heights), bool)
    for (zz, x, y), tile in tiles.items():
        if zz != zmax:
            continue
        lon, lat, hgt = _coords(tile)
        tw, ts, te, tn = tile_rect(zz, x, y)
        lon_t = tw + np.mod(slon - tw, 360.0)  # the sample's longitude in the tile's turn
        inside = (lon_t <= te) & (slat >= ts) & (slat <= tn) & np.isfinite(heights)
        tri = mtri.Triangulation(lon, lat, np.array(tile.indices).reshape(-1, 3))
        surf = np.ma.filled(mtri.LinearTriInterpolator(tri, hgt)(lon_t[inside], slat[inside]),
                            np.nan)
        ok = np.isfinite(surf)
        assert np.abs(surf[ok] - heights[inside][ok]).max() <= declared[f"{zz}/{x}/{y}"] + 1e-3
        covered[np.flatnonzero(inside)[ok]] = True
    inner = np.zeros(h.shape, bool)
    inner[1:-1, 1:-1] = True  # the outer ring lies on the meshes' hull: not interpolated
    inner = inner.ravel() & np.isfinite(heights)
    assert covered[inner].all()  # no sample is left out, east of 180° as west of it
    assert (inner & (slon > 180.0)).sum() > 5000


@settings(max_examples=200, deadline=None)
@given(M=st.sampled_from([3, 5, 9, 17]), seed=st.integers(0, 2**31),
       share=st.floats(0.05, 1.0), thr=st.sampled_from([0.0, 0.2, 5.0, 1e9]))
def test_the_lattice_triangle_rule_is_the_rtin_cut(M, seed, share, thr):
    """lattice_has_triangle (what the server lists rtin tiles by) is exactly whether
    select_tile's cut keeps a face of three valid corners, at any threshold: a cut
    triangle over valid and invalid samples is always split (δ = +inf)."""
    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.export.qmesh import lattice_has_triangle
    from geoterrain.lod.kernels import close_upward, extract

    rng = np.random.default_rng(seed)
    valid = rng.random((M, M)) < share
    h = np.where(valid, rng.normal(size=(M, M)).cumsum(0) * 3.0, 0.0)
    active = vertex_errors(h, valid) > thr
    active[0, :] = active[-1, :] = active[:, 0] = active[:, -1] = True
    close_upward(active)
    faces, fidx = extract(active, np.zeros_like(active), np.full(M * M, -1, np.int32))
    kept = valid.ravel()[fidx][faces].all(1)
    assert bool(lattice_has_triangle(valid)) == bool(kept.any())


@pytest.mark.fast
def test_the_servers_validity_is_the_writers(tmp_path):
    """What the server finds each lattice's validity from: the level-0 mask built from the
    tile table (decoding only tiles with nodata) is the store's own, and
    GeoDem.valid_at is where GeoDem.bilinear gives a height, at random lon/lat around a
    DEM with a void, a nodata margin and its edges."""
    from geoterrain.export.qmeshdem import GeoDem
    from geoterrain.export.qmeshtiles import QuantizedMeshTiles
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", (40, 50), seed=2) * 0.05).astype(np.float32)
    z[5:15, 20:30] = -9999
    z[:, :3] = -9999
    dem = write_tif(tmp_path / "m.tif", z, crs="EPSG:4326", origin=(138.45, 35.55),
                    spacing=1 / 1200, nodata=-9999)
    with geoterrain.open(geoterrain.preprocess(dem, tmp_path / "m.geoterrain",
                                               tile_size=16)) as t:
        q = QuantizedMeshTiles(t, mesher="rtin")
        _, v = t.level_heights(0)
        assert np.array_equal(q.mask.valid, v[:40, :50])
        full = GeoDem(t)
        w, s, e, n = full.extent()
        rng = np.random.default_rng(0)
        lon = rng.uniform(w - 0.01, e + 0.01, 20000)
        lat = rng.uniform(s - 0.01, n + 0.01, 20000)
        # on sample rows and columns too (the edges' == tests)
        i, j = rng.integers(-1, 41, 2000), rng.integers(-1, 51, 2000)
        lon2, lat2 = full.lonlat(i.astype(float), j.astype(float))
        lon, lat = np.concatenate([lon, lon2]), np.concatenate([lat, lat2])
        got = q.mask.valid_at(lon, lat)
        assert np.array_equal(got, np.isfinite(full.bilinear(lon, lat)))
        assert 0 < got.mean() < 1

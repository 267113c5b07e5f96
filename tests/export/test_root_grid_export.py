"""Exports of a store of rectangular root tiles (issue 45, ``preprocess --root-grid``):
glTF, OBJ, PLY and STL of the static mesh and of a view, the static mesh streamed to
disk, and the GeoTIFF products, read back with independent readers (trimesh, rasterio)
and checked against the input raster."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import xy as raster_xy

import geoterrain
from geoterrain.export.formats import export_mesh
from geoterrain.export.meshdata import mesh_arrays
from geoterrain.export.rasters import PRODUCTS, export_raster, product
from geoterrain.ingest.synth import generate, write_geotiff

trimesh = pytest.importorskip("trimesh")
pytestmark = pytest.mark.fast


def run(*args):
    from tests.rendering.test_render import _cli

    return CliRunner().invoke(_cli(), [str(a) for a in args])


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 129 × 513 fBm (UTM, 10 m; a void of nodata) on the square and on 2 × 1 roots."""
    d = tmp_path_factory.mktemp("rootexport")
    z = generate("fbm", 513, seed=5, relief=600.0)[:129, :513].astype(np.float32)
    z[40:52, 300:330] = -9999.0
    dem = write_geotiff(d / "wide.tif", z, crs="EPSG:32633", origin=(500000.0, 5000000.0),
                        spacing=10.0, nodata=-9999.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32,
                                               root_grid=False))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert rt.grid.roots == (2, 1) and sq.grid.square
    with rasterio.open(dem) as src:
        h = src.read(1, masked=True)
    return sq, rt, dem, np.ma.filled(h.astype(np.float64), np.nan)


def _on_samples(ij: np.ndarray) -> np.ndarray:
    return (ij == np.rint(ij)).all(1)


def _heights_are_the_dems(dem_h, ij, z):
    """Vertices on samples have the raster's heights there (and every one is valid)."""
    on = _on_samples(ij)
    assert on.all()  # clipped to the data, but a bintree edge crosses a grid line at a sample
    i, j = ij[:, 0].astype(int), ij[:, 1].astype(int)
    want = dem_h[i, j]
    assert np.isfinite(want).all()
    np.testing.assert_allclose(z, want, atol=1e-3)


@pytest.mark.parametrize("ext", [".ply", ".obj", ".stl"])
def test_the_streamed_static_mesh_is_the_in_memory_one(pair, tmp_path, ext):
    """write_static_mesh on a root grid: the in-memory static mesh's triangles (as sets
    of source-grid samples), its positions, and the count estimated beforehand bounds it."""
    from geoterrain.export.meshstream import estimated_triangles, write_static_mesh

    _, rt, _, dem_h = pair
    e = 2.0
    sel = rt.static_selection(e)
    st = write_static_mesh(rt, e, tmp_path / f"s{ext}")
    m = trimesh.load(tmp_path / f"s{ext}", process=False)
    assert st["triangles"] == len(m.faces) == sel.stats["triangles"] > 0
    assert estimated_triangles(rt, e) >= st["triangles"]
    pts = np.asarray(sel.mesh.points)
    ij = np.asarray(sel.ij)

    def triangles(P, F):
        """The faces as sorted triples of corners rounded to 1 cm (float32 files)."""
        c = np.round(np.asarray(P, np.float64)[np.asarray(F)] * 100).astype(np.int64)
        c = np.sort(c.view([("x", "i8"), ("y", "i8"), ("z", "i8")])[..., 0], axis=1)
        return np.sort(c.view(np.int64).reshape(len(F), 9).view("V72")[:, 0])

    assert (triangles(m.vertices, m.faces) == triangles(pts, sel.surface_faces())).all()
    _heights_are_the_dems(dem_h, ij, pts[:, 2] / rt.frame.z_scale / rt.frame.z_to_m)


def test_mesh_command_streams_a_root_grid(pair, tmp_path):
    _, rt, _, _ = pair
    out = tmp_path / "m.ply"
    res = run("-q", "mesh", rt.path, "-o", out, "--max-error", "2", "--json")
    assert res.exit_code == 0, res.output
    assert '"streamed": true' in res.output
    assert len(trimesh.load(out, process=False).faces) == \
        rt.static_selection(2.0).stats["triangles"]


def test_gltf_obj_ply_and_stl_of_a_root_grid(pair, tmp_path):
    """Each format read back: every vertex at its sample's source-CRS position with the
    DEM's height (PLY in source coordinates), the texture the data's rectangle, the
    solid watertight."""
    _, rt, dem, dem_h = pair
    sel = rt.static_selection(2.0)
    m = mesh_arrays(rt, sel)
    _heights_are_the_dems(dem_h, m.ij, m.elevation)
    out = export_mesh(rt, sel, tmp_path / "t.glb")
    (g,) = trimesh.load(out).geometry.values()
    assert len(g.vertices) == len(m.xyz) and len(g.faces) == len(m.faces)
    assert g.visual.material.baseColorTexture.size == (rt.grid.cols, rt.grid.rows)
    assert np.allclose(np.asarray(g.vertices)[:, 1], m.xyz[:, 2], atol=1e-3)  # Y up
    out = export_mesh(rt, sel, tmp_path / "t.obj")
    o = trimesh.load(out, process=False)
    assert np.allclose(o.vertices, m.xyz, atol=1e-3)
    uv = np.asarray(o.visual.uv)
    assert uv.shape == (len(m.xyz), 2) and (uv >= 0).all() and (uv <= 1).all()
    # the texture coordinates put each vertex on its texel: u along the columns
    np.testing.assert_allclose(uv[:, 0], (m.ij[:, 1] + 0.5) / rt.grid.cols, atol=1e-6)
    out = export_mesh(rt, sel, tmp_path / "c.ply", crs_coords=True)
    raw = trimesh.load(out, process=False).metadata["_ply_raw"]["vertex"]["data"]
    with rasterio.open(dem) as src:
        ex, ey = raster_xy(src.transform, m.ij[:, 0].astype(int), m.ij[:, 1].astype(int))
    assert np.allclose(raw["x"], ex) and np.allclose(raw["y"], ey)
    np.testing.assert_allclose(raw["z"], dem_h[m.ij[:, 0].astype(int),
                                                m.ij[:, 1].astype(int)], atol=1e-3)
    s = trimesh.load(export_mesh(rt, rt.static_selection(3.0), tmp_path / "t.stl",
                                 print_size=120.0, base_height=4.0))
    assert s.is_watertight and s.is_winding_consistent and s.volume > 0
    assert max(s.extents[:2]) == pytest.approx(120.0, rel=1e-5)


def test_a_view_exported_from_a_root_grid(pair, tmp_path):
    _, rt, _, dem_h = pair
    out = tmp_path / "v.glb"
    res = run("-q", "export", rt.path, "-o", out, "--look-from", "1500,-1500,1200",
              "--look-at", "1500,0,300", "--preview", tmp_path / "p.png")
    assert res.exit_code == 0, res.output
    (g,) = trimesh.load(out).geometry.values()
    assert len(g.faces) > 0 and (tmp_path / "p.png").stat().st_size > 1000
    # the view's vertices lie right of the centre: in the east root, with the DEM's heights
    lo, hi = rt.scene_box()
    assert np.asarray(g.vertices)[:, 0].max() > 0.5 * hi[0]


@pytest.mark.parametrize("level", [0, 2])
def test_geotiff_products_of_a_root_grid(pair, tmp_path, level):
    """Every product of a root-grid store equals the square store's, sample for sample
    (the same heights, normals and δ), and its GeoTIFF lies on the source grid."""
    sq, rt, dem, _ = pair
    span = rt.grid.span >> level  # a root's side in level-L samples
    for what in PRODUCTS:
        a, b = product(sq, what, level), product(rt, what, level)
        assert a.shape == b.shape
        if what == "error":  # a root's corner is in every mesh: δ 0 there, unbounded
            # (NaN) on the square, whose diamond there reaches into the padding
            corner = (slice(None), slice(None, None, span), slice(None, None, span))
            assert (b[corner] == 0).all()
            a[corner] = b[corner] = 0
        np.testing.assert_array_equal(np.isnan(a) if a.dtype.kind == "f" else a == 0,
                                      np.isnan(b) if b.dtype.kind == "f" else b == 0)
        np.testing.assert_allclose(np.nan_to_num(a), np.nan_to_num(b), rtol=0, atol=1e-6,
                                   err_msg=what)
    out = export_raster(rt, "slope", tmp_path / "s.tif", level=level)
    with rasterio.open(out) as got, rasterio.open(dem) as src:
        s = 1 << level
        assert (got.height, got.width) == (-(-src.height // s), -(-src.width // s))
        assert got.crs == src.crs
        # pixel (r, c)'s centre on sample (r·2^L, c·2^L)'s
        assert got.transform.a == src.transform.a * s
        assert raster_xy(got.transform, 3, 5) == raster_xy(src.transform, 3 * s, 5 * s)
        nan = np.isnan(got.read(1))
        void = src.read(1, masked=True).mask[::s, ::s]
        assert nan[void].all() and (~nan[~void]).mean() > 0.9


def test_web_map_tiles_of_a_root_grid_are_the_squares(pair):
    """Terrain-RGB heights and every imagery of XYZ tiles over both roots (a zoom of the
    finest level, and a coarse one) equal the square store's, pixel for pixel."""
    from geoterrain.export.webtiles import IMAGERY, WebTiler

    sq, rt, _, _ = pair
    a, b = WebTiler(sq), WebTiler(rt)
    assert (a.bounds, a.max_zoom) == (b.bounds, b.max_zoom)
    for z in (b.max_zoom + 2, b.max_zoom - 1):
        xs, ys = b.tile_range(z)
        assert len(xs) >= 2  # the tiles reach both roots
        for x in (xs[0], xs[-1]):
            y = ys[len(ys) // 2]
            ha, hb = a.heights(z, x, y), b.heights(z, x, y)
            np.testing.assert_array_equal(ha, hb)
            assert np.isfinite(hb).mean() > 0.05
            for what in IMAGERY:
                ia, ib = a.image(what, z, x, y), b.image(what, z, x, y)
                if what == "error":  # a root's corner: δ 0 where the square has ∞
                    assert (ia != ib).any(-1).mean() < 0.01
                else:
                    np.testing.assert_array_equal(ia, ib, err_msg=what)


@pytest.mark.slow  # about 14 s at load 8
def test_pmtiles_and_the_static_site_of_a_root_grid(pair, tmp_path):
    """The PMTiles archives of a root-grid store are the square store's, byte for byte,
    and the static site's page is written over them."""
    from geoterrain.export.pmtilesets import write_pmtiles
    from geoterrain.serve.site import write_site

    sq, rt, _, _ = pair
    kw = dict(imagery=("relief", "hillshade"), min_zoom=12, max_zoom=13, name="w")
    fa = write_pmtiles(sq, tmp_path / "a", **kw)
    fb = write_pmtiles(rt, tmp_path / "b", **kw)
    assert sorted(fa["files"]) == sorted(fb["files"]) and len(fb["files"]) == 3
    for f in fb["files"].values():
        assert (tmp_path / "b" / f).read_bytes() == (tmp_path / "a" / f).read_bytes(), f
    site = write_site(rt, tmp_path / "site", imagery=("relief",), min_zoom=12,
                      max_zoom=12, name="w")
    assert (tmp_path / "site" / "index.html").exists() and site["files"]


@pytest.mark.slow  # about 7 s at load 7
def test_quantized_mesh_tiles_of_a_root_grid_are_the_squares(pair, tmp_path):
    """A quantized-mesh tile set of a root-grid store holds the square store's tiles, byte
    for byte (its lattices resample the same heights), and so does the served source."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.export.qmeshtiles import QuantizedMeshTiles

    sq, rt, _, _ = pair
    for k, t in (("a", sq), ("b", rt)):
        write_tileset(t, tmp_path / k, max_zoom=10)
    files = sorted(p.relative_to(tmp_path / "b") for p in (tmp_path / "b").rglob("*.terrain"))
    assert len(files) >= 4
    assert files == sorted(p.relative_to(tmp_path / "a")
                           for p in (tmp_path / "a").rglob("*.terrain"))
    for f in files:
        assert (tmp_path / "b" / f).read_bytes() == (tmp_path / "a" / f).read_bytes(), f
    qa, qb = QuantizedMeshTiles(sq), QuantizedMeshTiles(rt)
    z = qb.max_zoom
    tiles = sorted(qb.level_tiles(z))
    assert tiles == sorted(qa.level_tiles(z)) and len(tiles) >= 2
    for xy in (tiles[0], tiles[-1]):
        assert qb.tile(z, *xy) == qa.tile(z, *xy)


@pytest.fixture(scope="module")
def geo_pair(tmp_path_factory):
    """A 129 × 513 fBm in EPSG:4326 (0.002° at 61° N, a void of nodata) on the square and
    on 2 × 1 roots."""
    d = tmp_path_factory.mktemp("georootexport")
    z = generate("fbm", 513, seed=5, relief=600.0)[:129, :513].astype(np.float32)
    z[40:52, 300:330] = -9999.0
    dem = write_geotiff(d / "geo.tif", z, crs="EPSG:4326", origin=(10.0, 61.26),
                        spacing=0.002, nodata=-9999.0)
    sq = geoterrain.open(geoterrain.preprocess(dem, d / "sq.geoterrain", tile_size=32,
                                               root_grid=False))
    rt = geoterrain.open(geoterrain.preprocess(dem, d / "rt.geoterrain", tile_size=32,
                                               root_grid=True))
    assert rt.grid.roots == (2, 1) and sq.grid.square and rt.frame.kind == "geographic"
    with rasterio.open(dem) as src:
        h = src.read(1, masked=True)
    return sq, rt, dem, np.ma.filled(h.astype(np.float64), np.nan)


def test_exports_of_a_geographic_root_grid(geo_pair, tmp_path):
    """A geographic root grid's exports: the mesh's positions in the square's metric
    frame (the same CRS, the aeqd of the raster's centre), PLY in source coordinates on
    rasterio's longitudes and latitudes with the DEM's heights, and the GeoTIFF
    products (the normals' x, y from pyproj) equal to the square store's, in EPSG:4326."""
    sq, rt, dem, dem_h = geo_pair
    from geoterrain.export.meshdata import georeference

    sel = rt.static_selection(2.0)
    g = georeference(rt)
    assert g == georeference(sq) and g["positions_crs_wkt"] == rt.frame.aeqd_wkt
    m = mesh_arrays(rt, sel)
    _heights_are_the_dems(dem_h, m.ij, m.elevation)
    X, Y, _ = sq.scene_xyz()  # the square's frame places every sample alike
    i, j = m.ij[:, 0].astype(int), m.ij[:, 1].astype(int)
    np.testing.assert_allclose(m.xyz[:, :2], np.stack([X[i, j], Y[i, j]], 1), atol=1e-6)
    out = export_mesh(rt, sel, tmp_path / "c.ply", crs_coords=True)
    raw = trimesh.load(out, process=False).metadata["_ply_raw"]["vertex"]["data"]
    with rasterio.open(dem) as src:
        lon, lat = raster_xy(src.transform, i, j)
    assert np.allclose(raw["x"], lon, atol=1e-9) and np.allclose(raw["y"], lat, atol=1e-9)
    for what in ("normals", "slope", "hillshade", "shade"):
        a, b = product(sq, what, 0), product(rt, what, 0)
        np.testing.assert_allclose(np.nan_to_num(a), np.nan_to_num(b), rtol=0, atol=1e-6,
                                   err_msg=what)
    out = export_raster(rt, "hillshade", tmp_path / "h.tif")
    with rasterio.open(out) as got, rasterio.open(dem) as src:
        assert got.crs == src.crs and got.transform == src.transform

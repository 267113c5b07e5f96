"""Exports for other tools: glTF/GLB, OBJ, PLY, printable STL and GeoTIFF products.

Each file is read back with an independent reader (trimesh, pygltflib, rasterio)
and checked against the store: counts, texture, georeference, watertightness,
the render's shading and the stored δ.
"""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import xy as raster_xy

import geoterrain
from geoterrain.export.formats import export_mesh, export_texture_level
from geoterrain.export.meshdata import mesh_arrays
from geoterrain.export.rasters import Relief, export_raster, product
from geoterrain.rendering.textures import build_texture_image, elevation_range, texture_level
from tests.conftest import write_tif

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

trimesh = pytest.importorskip("trimesh")
pygltflib = pytest.importorskip("pygltflib")


def run(*args):
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def terr(tmp_path_factory):
    from geoterrain.ingest.synth import generate, write_geotiff

    d = tmp_path_factory.mktemp("export")
    z = generate("fbm", 129, seed=5)
    z[:20, :30] = np.nan  # a nodata corner: the mesh has a boundary there
    dem = write_geotiff(d / "dem.tif", z)
    # vertical exaggeration 2: elevations, slopes and δ must take it out
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32, z_scale=2.0))
    yield t, dem
    t.close()


@pytest.fixture(scope="module")
def geo_terr(tmp_path_factory):
    """A small geographic (lon/lat) DEM."""
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("export_geo")
    dem = write_tif(d / "geo.tif", generate("fbm", 65, seed=2).astype(np.float32),
                    crs="EPSG:4326", origin=(138.5, 35.5), spacing=1 / 3600)
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32))
    yield t, dem
    t.close()


def _scene_to_crs_of_gltf(t, pos):
    """Source-CRS x, y of glTF positions (Y-up: x east, y up, z −north) via the frame."""
    return t.frame.scene_to_crs(pos[:, 0].astype(np.float64), -pos[:, 2].astype(np.float64))


@pytest.mark.parametrize("ext", [".glb", ".gltf"])
def test_gltf_round_trip(terr, tmp_path, ext):
    t, _ = terr
    sel = t.static_selection(2.0)
    m = mesh_arrays(t, sel)
    out = export_mesh(t, sel, tmp_path / f"t{ext}")
    scene = trimesh.load(out)
    (g,) = scene.geometry.values()
    assert len(g.vertices) == len(m.xyz) and len(g.faces) == len(m.faces)
    assert g.visual.material.baseColorTexture is not None
    L = export_texture_level(t, 4097)
    # the texture covers the data's rectangle, not the store's padded square
    assert g.visual.material.baseColorTexture.size == (t.grid.cols >> L, t.grid.rows >> L)
    # the origin and CRS are in the asset extras and the sidecar
    doc = pygltflib.GLTF2.load(str(out))
    geo = doc.asset.extras["geoterrain"]
    assert geo == json.loads(out.with_name(out.name + ".json").read_text())
    assert tuple(geo["origin_crs"]) == pytest.approx(t.frame.origin_crs, abs=0)
    assert geo["crs_wkt"] == t.frame.crs_wkt
    # every vertex maps back to the source-CRS coordinates of its sample
    pos = np.asarray(g.vertices)
    x, y = _scene_to_crs_of_gltf(t, pos)
    ex, ey = t.frame.crs_xy(m.ij[:, 0], m.ij[:, 1])
    assert np.abs(x - ex).max() < 1e-2 and np.abs(y - ey).max() < 1e-2  # float32 positions
    assert np.allclose(pos[:, 1], m.xyz[:, 2], atol=1e-3)
    # the elevation attribute, in metres
    acc = doc.accessors[doc.meshes[0].primitives[0].attributes._ELEVATION]
    blob = doc.binary_blob() if ext == ".glb" else None
    if blob is not None:
        bv = doc.bufferViews[acc.bufferView]
        elev = np.frombuffer(blob, np.float32, acc.count, bv.byteOffset)
        h = t.gather(m.ij[:, 0].astype(int), m.ij[:, 1].astype(int), ("height",))["height"]
        assert np.allclose(elev, h * t.frame.z_to_m, atol=1e-3)


def test_glb_view_dependent_cli(terr, tmp_path):
    t, _ = terr
    out = tmp_path / "v.glb"
    res = run("-q", "export", t.path, "-o", out, "--look-from", "0,-2500,1500",
              "--look-at", "0,0,0", "--strategy", "chunked")
    assert res.exit_code == 0, res.output
    (g,) = trimesh.load(out).geometry.values()
    assert len(g.faces) > 0


def test_obj_with_texture(terr, tmp_path):
    t, _ = terr
    sel = t.static_selection(2.0)
    out = export_mesh(t, sel, tmp_path / "t.obj")
    assert out.with_suffix(".mtl").exists() and out.with_suffix(".png").exists()
    g = trimesh.load(out, process=False)
    m = mesh_arrays(t, sel)
    assert len(g.vertices) == len(m.xyz) and len(g.faces) == len(m.faces)
    assert g.visual.material.image is not None
    assert g.visual.uv.shape == (len(m.xyz), 2)
    assert np.allclose(g.vertices, m.xyz, atol=1e-3)


@pytest.mark.parametrize("print_size", [None, 120.0])
def test_stl_is_a_printable_solid(terr, tmp_path, print_size):
    t, _ = terr
    out = export_mesh(t, t.static_selection(3.0), tmp_path / "t.stl", print_size=print_size,
                      base_height=None if print_size is None else 4.0)
    s = trimesh.load(out)
    assert s.is_watertight and s.is_winding_consistent
    assert s.volume > 0
    if print_size is not None:
        ext = s.bounds[1] - s.bounds[0]
        assert max(ext[0], ext[1]) == pytest.approx(print_size, rel=1e-5)
        assert s.bounds[0][2] == pytest.approx(0.0, abs=1e-5)


def test_stl_refuses_a_mesh_with_t_junctions(terr, tmp_path):
    t, _ = terr
    sel = t.select(geoterrain.View((0, -3000, 3000), (0, 0, 0)), 64.0, "chunked")
    assert sel.stats["skirt_triangles"] > 0  # tiles of two levels meet
    with pytest.raises(geoterrain.GeoterrainError, match="conforming"):
        export_mesh(t, sel, tmp_path / "c.stl")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("which", ["terr", "geo_terr"])
def test_ply_crs_coords_are_the_samples_source_coordinates(which, request, tmp_path):
    t, dem = request.getfixturevalue(which)
    out = tmp_path / "c.ply"
    res = run("-q", "export", t.path, "-o", out, "--max-error", "2", "--crs-coords")
    assert res.exit_code == 0, res.output
    p = trimesh.load(out, process=False)
    raw = p.metadata["_ply_raw"]["vertex"]["data"]
    assert raw["x"].dtype == np.float64
    m = mesh_arrays(t, t.static_selection(2.0))
    with rasterio.open(dem) as src:  # rasterio's own pixel-centre coordinates
        ex, ey = raster_xy(src.transform, m.ij[:, 0].astype(int), m.ij[:, 1].astype(int))
    for got, want in ((raw["x"], np.asarray(ex)), (raw["y"], np.asarray(ey))):
        assert (np.abs(got - want) <= 4 * np.spacing(np.abs(want))).all()  # a few ulps
    assert np.allclose(raw["z"], m.elevation, atol=1e-3)
    head = out.read_bytes()[:4000].split(b"end_header")[0].decode()
    assert "comment crs_wkt" in head and "positions source_crs" in head


def test_ply_scene_positions_carry_the_offset(terr, tmp_path):
    t, _ = terr
    out = export_mesh(t, t.static_selection(2.0), tmp_path / "s.ply")
    head = out.read_bytes()[:4000].split(b"end_header")[0].decode()
    line = next(ln for ln in head.splitlines() if ln.startswith("comment offset"))
    ox, oy = (float(v) for v in line.split()[2:4])
    assert (ox, oy) == pytest.approx(t.frame.origin_crs, abs=1e-6)
    raw = trimesh.load(out, process=False).metadata["_ply_raw"]["vertex"]["data"]
    assert "elevation" in raw.dtype.names


def test_export_errors_are_one_line(terr, tmp_path):
    t, _ = terr
    res = run("export", t.path, "-o", tmp_path / "x.fbx")
    assert res.exit_code == 2 and "unknown export format" in res.stderr
    res = run("export", t.path, "-o", tmp_path / "x.ply", "--print-size", "100",
              "--crs-coords")
    assert res.exit_code == 2 and "--crs-coords" in res.stderr
    res = run("export", t.path, "-o", tmp_path / "x.glb", "--crs-coords")
    assert res.exit_code == 2
    assert not list(tmp_path.iterdir())


def test_a_static_export_past_the_memory_limit_is_refused_before_work(terr, tmp_path,
                                                                      monkeypatch):
    """The estimate (triangles counted without building the mesh) against --memory-limit:
    refused in one line naming the estimate and the hint, before any selection."""
    import geoterrain.cli.options as O
    import geoterrain.export.formats as F

    t, _ = terr
    monkeypatch.setattr(F, "EXPORT_BYTES_PER_TRIANGLE", 1 << 30)  # every mesh is too big

    def never(*a, **k):
        raise AssertionError("the mesh was built")

    monkeypatch.setattr(O, "select_mesh", never)
    monkeypatch.setattr("geoterrain.cli.export.select_mesh", never)
    res = run("export", t.path, "-o", tmp_path / "x.glb", "--max-error", "0.1",
              "--memory-limit", "64M")
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "triangles" in res.stderr and "--max-error" in res.stderr
    assert not list(tmp_path.iterdir())


def test_mesh_command_writes_elevation(terr, tmp_path):
    import pyvista as pv

    t, _ = terr
    res = run("-q", "mesh", t.path, "-o", tmp_path / "m.vtp", "--max-error", "2")
    assert res.exit_code == 0, res.output
    m = pv.read(tmp_path / "m.vtp")
    assert np.allclose(m["elevation"], m.points[:, 2] / t.frame.z_scale, atol=1e-3)


# ---------------------------------------------------------------------- GeoTIFF
@pytest.mark.parametrize("level", [0, 2])
def test_geotiff_grid_and_crs(terr, tmp_path, level):
    t, dem = terr
    res = run("-q", "export-raster", t.path, "--what", "slope", "--level", level,
              "-o", tmp_path / "s.tif")
    assert res.exit_code == 0, res.output
    with rasterio.open(dem) as src, rasterio.open(tmp_path / "s.tif") as r:
        assert r.crs == src.crs
        assert r.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        s = 1 << level
        assert r.shape == (-(-src.height // s), -(-src.width // s))
        # pixel centre k of level L is the source pixel centre k·2^L
        for k in (0, 7):
            assert r.xy(k, k) == pytest.approx(src.xy(k * s, k * s), abs=1e-6)
        assert r.res == pytest.approx((src.res[0] * s, src.res[1] * s))
        if level == 0:
            assert r.transform == src.transform


def test_shade_is_the_renders_shading(terr, tmp_path):
    t, _ = terr
    L = texture_level(t)
    export_raster(t, "shade", tmp_path / "h.tif", level=L)
    with rasterio.open(tmp_path / "h.tif") as r:
        shade = r.read(1)
    img = build_texture_image(t, "normals", "gist_earth", level=L).astype(np.float64)
    h, v = t.level_heights(L)
    H, W = shade.shape
    z0, z1 = elevation_range(t)
    rgb = matplotlib.colormaps["gist_earth"](
        np.clip((h[:H, :W] * t.frame.z_to_m - z0) / (z1 - z0), 0, 1))[..., :3]
    expect = np.clip(rgb * shade[..., None], 0, 1) * 255
    ok = v[:H, :W]
    assert ok.sum() > 0 and np.isnan(shade[~ok]).all()
    assert np.abs(img[:H, :W][ok] - expect[ok]).max() <= 1.0  # within 1/255


def test_error_raster_is_the_stored_delta(terr, tmp_path):
    t, _ = terr
    for level in (0, 1):
        export_raster(t, "error", tmp_path / f"e{level}.tif", level=level)
        with rasterio.open(tmp_path / f"e{level}.tif") as r:
            e = r.read(1)
        s = 1 << level
        H, W = e.shape
        rng = np.random.default_rng(level)
        i, j = rng.integers(0, H, 400), rng.integers(0, W, 400)
        d = np.array([t.tile_delta(*_holder(t, a * s, b * s))[_local(t, a * s, b * s)]
                      for a, b in zip(i.tolist(), j.tolist(), strict=True)])
        _, valid = t.level_heights(0)
        ok = valid[i * s, j * s]
        d = np.where(np.isfinite(d), d, np.nan)  # unbounded: nodata
        assert np.array_equal(e[i, j][ok], (d / t.frame.z_scale).astype(np.float32)[ok],
                              equal_nan=True)
        assert np.isnan(e[i, j][~ok]).all()
        assert not np.isinf(e).any()


def _holder(t, i, j):
    """The level-0 tile holding full-resolution sample (i, j) (tile-by-tile reference)."""
    g = t.grid
    T1 = g.tile_samples - 1
    return 0, min(j // T1, g.tiles_per_side(0) - 1), min(i // T1, g.tiles_per_side(0) - 1)


def _local(t, i, j):
    _, x, y = _holder(t, i, j)
    T1 = t.grid.tile_samples - 1
    return i - y * T1, j - x * T1


def test_slope_is_the_dems_slope_in_degrees(terr):
    """Slope against Horn's 3×3 gradient (gdaldem's) of the source heights, written out
    as the eight weighted neighbours (exaggeration taken out); percent as 100·tan."""
    t, dem = terr
    s = product(t, "slope", 0)[0]
    with rasterio.open(dem) as src:
        z = src.read(1).astype(np.float64)
        dx, dy = src.res
    n = lambda a, b: z[1 + a:z.shape[0] - 1 + a, 1 + b:z.shape[1] - 1 + b]  # noqa: E731
    gx = (n(-1, 1) + 2 * n(0, 1) + n(1, 1) - n(-1, -1) - 2 * n(0, -1) - n(1, -1)) / (8 * dx)
    gy = (n(1, -1) + 2 * n(1, 0) + n(1, 1) - n(-1, -1) - 2 * n(-1, 0) - n(-1, 1)) / (8 * dy)
    ref = np.degrees(np.arctan(np.hypot(gx, gy)))
    inner = s[1:-1, 1:-1]
    ok = np.isfinite(ref) & np.isfinite(inner)
    assert ok.sum() > 1000
    assert np.abs(inner - ref)[ok].max() < 1e-3
    pct = product(t, "slope", 0, Relief(slope_units="percent"))[0][1:-1, 1:-1]
    assert np.allclose(pct[ok], 100 * np.tan(np.radians(ref[ok])), rtol=1e-4, atol=1e-3)


def test_products_shapes_and_nodata(terr):
    t, _ = terr
    n = product(t, "normals", 1)
    assert n.shape[0] == 3
    ok = ~np.isnan(n[0])
    assert np.allclose(np.linalg.norm(n[:, ok], axis=0), 1, atol=1e-3)
    assert np.isnan(product(t, "shade", 0)[0, :20, :30]).all()
    hs = product(t, "hillshade", 0)
    assert hs.dtype == np.uint8 and (hs[0, :20, :30] == 0).all() and hs[0, 40:, 40:].min() >= 1


def test_export_raster_errors(terr, tmp_path):
    t, _ = terr
    res = run("export-raster", t.path, "--what", "slope", "--level", 99, "-o", tmp_path / "a.tif")
    assert res.exit_code == 2 and "--level" in res.stderr
    res = run("export-raster", t.path, "--what", "slope", "-o", tmp_path / "a.png")
    assert res.exit_code == 2
    assert not list(tmp_path.iterdir())


def test_export_raster_relief_options(terr, tmp_path):
    t, _ = terr
    res = run("-q", "export-raster", t.path, "--what", "hillshade", "--sun", "300,30", "-z", 2,
              "-o", tmp_path / "h.tif")
    assert res.exit_code == 0, res.output
    with rasterio.open(tmp_path / "h.tif") as r:
        assert r.dtypes[0] == "uint8" and r.nodata == 0 and r.tags()["sun"] == "300,30"
        assert np.array_equal(r.read(1), product(t, "hillshade", 0, Relief(300, 30, 2.0))[0])
    for args in (["--what", "slope", "--sun", "300,30"], ["--what", "error", "-z", "2"],
                 ["--what", "hillshade", "--slope-units", "percent"],
                 ["--what", "hillshade", "--sun", "300"],
                 ["--what", "hillshade", "--sun", "300,95"],
                 ["--what", "slope", "--scale", "-1"]):
        res = run("export-raster", t.path, *args, "-o", tmp_path / "x.tif")
        assert res.exit_code == 2, (args, res.output)
        assert len(res.stderr.strip().splitlines()) <= 4 and "Traceback" not in res.output
    assert not (tmp_path / "x.tif").exists()

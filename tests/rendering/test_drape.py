"""--drape: a georeferenced image reprojected onto the DEM lands at the right texels.

The drape images encode position in their colours (red ∝ easting or longitude,
green ∝ northing or latitude, both linear, so bilinear resampling keeps them
exact to a unit); the expected colour of a DEM sample is computed from its own
source-CRS coordinates (rasterio) and, for the geographic image, pyproj.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from PIL import Image
from pyproj import Transformer
from rasterio.transform import from_origin

import geoterrain
from geoterrain.exceptions import InputError, UsageError
from geoterrain.rendering.drape import drape_image
from tests.conftest import write_tif

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

DEM_CRS = "EPSG:32633"
X0, Y0, SP, N = 500000.0, 5000000.0, 10.0, 129


def _gradient_image(path, crs, west, north, res, size, rx, gy, bands=3):
    """An image whose red is linear in x over rx = (x0, x1), green linear in y (north
    at 0) over gy = (y1, y0); blue 77. Pixel centres carry the exact values, rounded."""
    j = np.arange(size) + 0.5
    x, y = west + j * res, north - j * res
    r = (x - rx[0]) / (rx[1] - rx[0]) * 255
    g = (gy[1] - y) / (gy[1] - gy[0]) * 255
    rgb = np.stack([np.tile(r[None, :], (size, 1)), np.tile(g[:, None], (1, size)),
                    np.full((size, size), 77.0)])
    rgb = np.clip(np.round(rgb), 0, 255).astype(np.uint8)[:bands]
    with rasterio.open(path, "w", driver="GTiff", width=size, height=size, count=bands,
                       dtype="uint8", crs=crs, transform=from_origin(west, north, res, res)
                       ) as dst:
        dst.write(rgb)
    return path


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("drape")
    tif = write_tif(d / "dem.tif", generate("fbm", N, seed=6).astype(np.float32) * 0.2,
                    crs=DEM_CRS, origin=(X0, Y0), spacing=SP)
    store = geoterrain.preprocess(tif)
    t = geoterrain.open(store)
    yield d, tif, store, t
    t.close()


@pytest.fixture(scope="module")
def utm_image(dem):
    d = dem[0]
    # 7 m pixels, larger than the DEM, offset: a real resampling
    return _gradient_image(d / "utm.tif", DEM_CRS, X0 - 100, Y0 + 100, 7.0, 220,
                           (X0 - 100, X0 + 1440), (Y0 - 1440, Y0 + 100))


@pytest.fixture(scope="module")
def geo_image(dem):
    d = dem[0]
    tr = Transformer.from_crs(DEM_CRS, "EPSG:4326", always_xy=True)
    lon, lat = tr.transform([X0 - 200, X0 + 1500, X0 - 200, X0 + 1500],
                            [Y0 + 200, Y0 + 200, Y0 - 1500, Y0 - 1500])
    w, e, s, n = min(lon), max(lon), min(lat), max(lat)
    res = max(e - w, n - s) / 300
    return _gradient_image(d / "geo.tif", "EPSG:4326", w, n, res, 300,
                           (w, w + 300 * res), (n - 300 * res, n)), (w, n, res)


def _samples(rng, k=400):
    return rng.integers(2, N - 2, k), rng.integers(2, N - 2, k)


def _close(got, want, worst: float) -> None:
    """Within rounding everywhere, and no bias: half a DEM sample of shift moves the
    colours by ~0.8, rounding averages out."""
    d = np.asarray(got, np.float64) - want
    assert np.abs(d).max() <= worst and abs(d.mean()) < 0.3, (np.abs(d).max(), d.mean())


def _sample_xy(tif, i, j):
    with rasterio.open(tif) as src:
        x, y = rasterio.transform.xy(src.transform, i, j)
    return np.asarray(x), np.asarray(y)


def test_image_in_the_dem_crs_lands_at_its_samples(dem, utm_image):
    _, tif, _, t = dem
    img = drape_image(t, utm_image, 0)
    i, j = _samples(np.random.default_rng(0))
    x, y = _sample_xy(tif, i, j)
    want_r = (x - (X0 - 100)) / 1540 * 255
    want_g = (Y0 + 100 - y) / 1540 * 255
    _close(img[i, j, 0], want_r, 1.0)
    _close(img[i, j, 1], want_g, 1.0)
    assert (img[i, j, 2] == 77).all()


def test_image_in_another_crs_lands_at_its_samples(dem, geo_image):
    _, tif, _, t = dem
    path, (w, n, res) = geo_image
    img = drape_image(t, path, 0)
    i, j = _samples(np.random.default_rng(1))
    lon, lat = Transformer.from_crs(DEM_CRS, "EPSG:4326", always_xy=True).transform(
        *_sample_xy(tif, i, j))
    want_r = (np.asarray(lon) - w) / (300 * res) * 255
    want_g = (n - np.asarray(lat)) / (300 * res) * 255
    _close(img[i, j, 0], want_r, 1.5)
    _close(img[i, j, 1], want_g, 1.5)
    # a coarser level: texel (r, c) lies over sample (2r, 2c)
    img2 = drape_image(t, path, 1)
    assert np.abs(img2[i // 2, j // 2, :2].astype(int) - img[(i // 2) * 2, (j // 2) * 2, :2]
                  ).max() <= 2


def test_single_band_and_partial_cover(dem):
    d, tif, _, t = dem
    # one band over the western half only: grey there, the base texture elsewhere
    p = _gradient_image(d / "grey.tif", DEM_CRS, X0, Y0, SP, 64, (X0, X0 + 640),
                        (Y0 - 640, Y0), bands=1)
    base = np.full((N, N, 3), 5, np.uint8)
    img = drape_image(t, p, 0, base=base)
    assert (img[10:60, 10:60, 0] == img[10:60, 10:60, 1]).all()  # grey: R = G = B
    assert (img[10:60, 10:60, 0] == img[10:60, 10:60, 2]).all()
    assert (img[:, 70:] == 5).all() and (img[70:, :] == 5).all()


def _texel(png: bytes, uv: np.ndarray, flip: bool) -> np.ndarray:
    im = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    S = im.shape[0]
    v = 1 - uv[:, 1] if flip else uv[:, 1]
    r = np.round(v * S - 0.5).astype(int)
    c = np.round(uv[:, 0] * S - 0.5).astype(int)
    return im[r, c]


def test_glb_and_obj_carry_the_draped_image(dem, utm_image, tmp_path):
    import pygltflib
    import trimesh

    from geoterrain.cli.main import cli

    _, tif, store, t = dem
    out = tmp_path / "d.glb"
    res = CliRunner().invoke(cli, ["-q", "export", str(store), "-o", str(out),
                                   "--max-error", "1", "--drape", str(utm_image)])
    assert res.exit_code == 0, res.output
    g = pygltflib.GLTF2().load(str(out))
    png = g.binary_blob()[g.bufferViews[g.images[0].bufferView].byteOffset:][
        :g.bufferViews[g.images[0].bufferView].byteLength]
    acc = g.accessors[g.meshes[0].primitives[0].attributes.TEXCOORD_0]
    view = g.bufferViews[acc.bufferView]
    uv = np.frombuffer(g.binary_blob(), np.float32, acc.count * 2,
                       view.byteOffset + (acc.byteOffset or 0)).reshape(-1, 2)
    # every vertex's texel is the image's colour at the vertex's own sample
    ij = np.round(np.column_stack([uv[:, 1], uv[:, 0]]) * N - 0.5).astype(int)
    x, y = _sample_xy(tif, ij[:, 0], ij[:, 1])
    got = _texel(png, uv, flip=False).astype(float)
    _close(got[:, 0], (x - (X0 - 100)) / 1540 * 255, 1.0)
    _close(got[:, 1], (Y0 + 100 - y) / 1540 * 255, 1.0)
    # the embedded texture is the draped image, not the shading
    shading = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    assert (shading[..., 2] == 77).mean() > 0.99

    obj = tmp_path / "d.obj"
    res = CliRunner().invoke(cli, ["-q", "export", str(store), "-o", str(obj),
                                   "--max-error", "1", "--drape", str(utm_image)])
    assert res.exit_code == 0, res.output
    m = trimesh.load(obj, process=False)
    tex = np.asarray(m.visual.material.image.convert("RGB"))
    assert np.array_equal(tex, shading)


def test_drape_errors_are_one_line(dem, tmp_path):
    from geoterrain.cli.main import cli

    d, _, store, t = dem
    plain = tmp_path / "plain.png"
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(plain)
    far = _gradient_image(tmp_path / "far.tif", DEM_CRS, X0 + 90000, Y0, 10.0, 16,
                          (0, 1), (0, 1))
    junk = tmp_path / "junk.tif"
    junk.write_text("not an image")
    for img, words in ((plain, "not georeferenced"), (far, "does not overlap"),
                       (junk, "cannot read")):
        with pytest.raises(InputError, match=words):
            drape_image(t, img, 0)
        out = tmp_path / "x.glb"
        res = CliRunner().invoke(cli, ["export", str(store), "-o", str(out), "--drape",
                                       str(img)])
        assert res.exit_code == 1 and words in res.stderr, res.output
        assert len(res.stderr.strip().splitlines()) == 1 and not out.exists()
        assert not list(tmp_path.glob(".x.glb*"))
    res = CliRunner().invoke(cli, ["export", str(store), "-o", str(tmp_path / "x.ply"),
                                   "--drape", str(far)])
    assert res.exit_code == 2 and "--drape applies to" in res.stderr
    with pytest.raises(UsageError, match="no CRS"):
        from geoterrain.ingest.synth import generate, write_geotiff

        pix = geoterrain.open(geoterrain.preprocess(
            write_geotiff(tmp_path / "p.tif", generate("fbm", 33, seed=1)), pixel_size=1.0))
        drape_image(pix, far, 0)


def test_view_textures_take_the_drape_per_tile(dem, tmp_path):
    """render/view drape: each texture tile's texels carry the image reprojected from
    another CRS (its own window only), blended by the opacity; nodata shows the map."""
    from geoterrain.rendering.drape import Drape
    from geoterrain.rendering.tileshader import tile_rgb

    d, _, _, t = dem
    # a 4326 image over the western half only; its eastern half is nodata (alpha 0)
    tr = Transformer.from_crs(DEM_CRS, "EPSG:4326", always_xy=True)
    lon0, lat1 = tr.transform(X0 - 100, Y0 + 100)
    lon1, lat0 = tr.transform(X0 + SP * N + 100, Y0 - SP * N - 100)
    size = 64
    res = (lon1 - lon0) / size
    rgba = np.zeros((4, size, size), np.uint8)
    rgba[0], rgba[1], rgba[2] = 200, 30, 40
    rgba[3, :, : size // 2] = 255
    img = d / "half.tif"
    with rasterio.open(img, "w", driver="GTiff", width=size, height=size, count=4,
                       dtype="uint8", crs="EPSG:4326", photometric="RGB", alpha="YES",
                       transform=from_origin(lon0, lat1, res, (lat1 - lat0) / size)) as dst:
        dst.write(rgba)
    L = t.grid.top_level
    plain = tile_rgb(t, L, 0, 0, "elevation").astype(int)
    full = tile_rgb(t, L, 0, 0, "elevation", drape=Drape(str(img))).astype(int)
    half = tile_rgb(t, L, 0, 0, "elevation", drape=Drape(str(img), 0.5)).astype(int)
    T = t.grid.tile_samples
    west, east = (slice(2, T - 2), slice(2, T // 4)), (slice(2, T - 2), slice(3 * T // 4, T - 2))
    assert (np.abs(full[west] - [200, 30, 40]) <= 2).all()  # the image, in place
    assert (full[east] == plain[east]).all()  # its nodata: the colour map
    assert (np.abs(half[west] - (plain[west] + [200, 30, 40]) / 2) <= 2).all()


def test_render_drape_cli(dem, tmp_path):
    from geoterrain.cli.main import cli

    d, _, store, _ = dem
    img = _gradient_image(tmp_path / "g.tif", DEM_CRS, X0, Y0, SP, N, (X0, X0 + SP * N),
                          (Y0 - SP * N, Y0))
    out = tmp_path / "d.png"
    r = CliRunner().invoke(cli, ["-q", "render", str(store), "-o", str(out), "--size",
                                 "240x180", "--drape", str(img), "--drape-opacity", "0.7",
                                 "--shadows"])
    assert r.exit_code == 0, r.output
    assert out.exists()
    bad = CliRunner().invoke(cli, ["render", str(store), "-o", str(tmp_path / "x.png"),
                                   "--drape", str(img), "--drape-opacity", "2"])
    assert bad.exit_code == 2

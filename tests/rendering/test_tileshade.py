"""The fused tile shading (geoterrain.rendering.tileshade) against the numpy composition it
replaces:
colours.colorize × shading.hillshade(decode_octahedral(codes)), clipped, rounded."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.normalbytes import normals_from_bytes, normals_to_bytes
from geoterrain.bounds.normals import decode_octahedral
from geoterrain.rendering.colours import LAND, WATER, Palette, colorize, water_level
from geoterrain.rendering.shading import AMBIENT, DEFAULT_SUN, SHADE_CEILING, hillshade
from geoterrain.rendering.tileshade import (
    magnify_tiles,
    magnify_tint_tiles,
    shade_tile,
    tint_tiles,
)
from geoterrain.rendering.tileshader import magnified

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.booleans(), st.booleans(),
       st.sampled_from([None, -20.0, 0.0, 150.0]), st.booleans(),
       st.sampled_from([0.0, 0.5, 30.0]))
def test_fused_shading_is_the_numpy_composition(seed, planar, with_clim, wl, low_data, tol):
    rng = np.random.default_rng(seed)
    T = int(rng.integers(2, 40))
    lo = -300.0 if low_data else 50.0
    h = rng.uniform(lo, 900.0, (T, T))
    h[rng.random((T, T)) < 0.1] = np.nan  # nodata: coloured as 0 m
    h[0, 0] = 0.0
    codes = rng.integers(0, 256, (T, T, 2)).astype(np.uint8)
    pal = Palette("auto", clim=(-100.0, 700.0) if with_clim else None, water_level=wl)
    rng_data = (lo, 900.0)
    rgb = colorize(np.nan_to_num(h, nan=0.0), pal, rng_data, tol)
    rgb *= hillshade(decode_octahedral(codes, 8))[..., None]
    want = (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    raw = normals_to_bytes(codes) if planar else codes.tobytes()
    assert planar is False or np.array_equal(normals_from_bytes(raw, T), codes)
    got = shade_tile(h, np.frombuffer(raw, np.uint8), planar, 8, DEFAULT_SUN, AMBIENT,
                     SHADE_CEILING, pal.clim if pal.clim is not None else rng_data,
                     water_level(pal, rng_data), LAND, WATER, tol)
    d = np.abs(got.astype(int) - want.astype(int))
    assert d.max() <= 1  # the dot product's float32 rounding (numpy's matmul order)
    assert (d > 0).mean() < 0.01


def test_shade_table_is_the_per_code_hillshade():
    """The table the fused shading looks codes up in holds, for every 8-bit code, exactly
    the hillshade the code decodes to (hillshade_codes, one code at a time)."""
    from geoterrain.rendering.shading import hillshade_codes
    from geoterrain.rendering.tileshade import shade_lut

    u, v = np.meshgrid(np.arange(256), np.arange(256), indexing="ij")
    codes = np.stack([u, v], -1).astype(np.uint8)
    for light in (DEFAULT_SUN, np.array([0.6, -0.3, 0.74], np.float32)):
        light = (light / np.linalg.norm(light)).astype(np.float32)
        want = hillshade_codes(codes, 8, light, AMBIENT, SHADE_CEILING)
        assert np.array_equal(shade_lut(light, AMBIENT, SHADE_CEILING), want)


def test_ramp_slopes_are_numpy_s():
    """The ramps' cached slopes give np.interp's values to the bit (its formula)."""
    from geoterrain.rendering.tileshade import _stops

    x = np.linspace(-0.1, 1.1, 2001)
    x = np.clip(np.concatenate([x, [0.15, 0.35, 0.6, 0.82, 1.0, 0.0]]), 0.0, 1.0)
    for ramp in (LAND, WATER):
        xp, fp, slope = _stops(ramp)
        for k in range(3):
            j = np.clip(np.searchsorted(xp, x, side="right") - 1, 0, len(xp) - 1)
            last = j == len(xp) - 1
            jj = np.minimum(j, len(xp) - 2)
            got = np.where(last | (xp[j] == x), fp[j, k], slope[jj, k] * (x - xp[j]) + fp[j, k])
            assert np.array_equal(got, np.interp(x, xp, fp[:, k]))


def test_a_lossy_flat_sea_keeps_one_colour(tmp_path):
    """A store coded within ε decodes a flat sea at 0 m to heights that wander within
    ±ε (residual bins keep each prediction's error); the colours treat heights within ε
    of the water level as its surface, so the sea stays one colour, as losslessly."""
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.rendering.textures import elevation_range, height_tolerance

    z = generate("fbm", 257, seed=3).astype(np.float64)
    z = np.round((z - z.min()) / (z.max() - z.min()) * 800.0 - 250.0)
    z[z < 0] = 0.0  # a sea at 0 m around a coast
    dem = write_geotiff(str(tmp_path / "sea.tif"), z.astype(np.int16))
    t = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "sea.gt", codec_error=2.0))
    sea = [t.tile(0, x, y).heights[z[y * 64:y * 64 + 65, x * 64:x * 64 + 65] == 0]
           for y in range(4) for x in range(4)]
    sea = np.concatenate(sea)
    assert t.quantizer.bins == 5 and np.abs(sea).max() <= 2.0
    assert np.unique(sea).size > 1  # the premise: the decoded sea is not flat
    pal = Palette("auto")
    rgb = colorize(sea, pal, elevation_range(t), height_tolerance(t))
    assert height_tolerance(t) == 2.0 and (rgb == rgb[0]).all()
    assert not (colorize(sea, pal, elevation_range(t)) == rgb[0]).all()  # without it


def _reference(a: np.ndarray, level: int, x: int, y: int, step: int) -> np.ndarray:
    """An independent magnification (the numpy one the renderer had before it kept the
    compiled pass alone): separable bilinear weights through einsum, NaN-aware."""
    k = -level
    n = step >> k

    def weights(T, o):
        c = o + np.arange(step + 1, dtype=np.float64) / (1 << k)
        i0 = np.minimum(np.floor(c).astype(np.int64), T - 2)
        w = np.zeros((step + 1, T))
        w[np.arange(step + 1), i0] = 1.0 - (c - i0)
        w[np.arange(step + 1), i0 + 1] += c - i0
        return w

    m = (1 << k) - 1
    wy, wx = weights(a.shape[0], (y & m) * n), weights(a.shape[1], (x & m) * n)
    v = np.asarray(a, np.float64)
    ok = np.isfinite(v)
    if ok.all():  # separable: rows, then columns
        return np.einsum("ri,ij...,cj->rc...", wy, v, wx, optimize=True)
    num = np.einsum("ri,ij...,cj->rc...", wy, np.where(ok, v, 0.0), wx, optimize=True)
    den = np.einsum("ri,ij...,cj->rc...", wy, ok.astype(np.float64), wx, optimize=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-12, num / np.maximum(den, 1e-300), np.nan)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(1, 6), st.sampled_from([0.0, 0.05, 0.6, 1.0]))
def test_magnified_tiles_in_one_pass_are_the_reference_interpolation(seed, t, voids):
    """The compiled pass gives each magnified tile's texels as an independent numpy
    interpolation does (the same weights; the sums rounded in another order), NaN where it
    gives NaN, tiles of several sources in one call; magnified, one tile and its channels
    at a time, the same bytes as the pass."""
    rng = np.random.default_rng(seed)
    step = 1 << t
    src = rng.uniform(-500.0, 3000.0, (3, step + 1, step + 1))
    src[0][rng.random((step + 1, step + 1)) < voids] = np.nan  # one source with voids
    n = int(rng.integers(1, 12))
    k = rng.integers(1, min(t, 3) + 1, n)  # the tile's width stays >= 1 sample
    x = rng.integers(0, 64, n)
    y = rng.integers(0, 64, n)
    which = rng.integers(0, 3, n)
    got = magnify_tiles(src, which, -k, x, y, step)
    assert got.shape == (n, step + 1, step + 1)
    rgb = np.moveaxis(src, 0, -1)  # the three sources as one tile's channels
    for m in range(n):
        want = _reference(src[which[m]], -int(k[m]), int(x[m]), int(y[m]), step)
        assert np.array_equal(np.isnan(got[m]), np.isnan(want))
        ok = ~np.isnan(want)
        assert np.allclose(got[m][ok], want[ok], rtol=1e-12, atol=1e-9)
        one = magnified(rgb, -int(k[m]), int(x[m]), int(y[m]), step)[..., which[m]]
        assert np.array_equal(one, got[m], equal_nan=True)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(1, 6), st.sampled_from([0.0, 0.05, 1.0]),
       st.sampled_from([None, -20.0, 150.0]), st.sampled_from([1.0, 0.3048]))
def test_magnify_and_tint_in_one_pass_is_the_two_passes(seed, t, voids, wl, cf):
    """The default style's magnified tiles in one pass are, byte for byte, the heights and
    the shade magnified (the shade rounded to float32), then tinted: sources with and
    without voids (in the heights, in the shade), with and without water."""
    rng = np.random.default_rng(seed)
    step = 1 << t
    h = rng.uniform(-300.0, 3000.0, (3, step + 1, step + 1))
    s = rng.uniform(0.2, 1.25, (3, step + 1, step + 1)).astype(np.float32).astype(np.float64)
    h[0][rng.random((step + 1, step + 1)) < voids] = np.nan
    s[1][rng.random((step + 1, step + 1)) < voids] = np.nan
    n = int(rng.integers(1, 12))
    k = rng.integers(1, min(t, 3) + 1, n)
    x, y, which = rng.integers(0, 64, n), rng.integers(0, 64, n), rng.integers(0, 3, n)
    args = ((-100.0, 2500.0), wl, LAND, WATER, 0.5, None)
    got = magnify_tint_tiles(h, s, which, -k, x, y, step, cf, *args)
    want = tint_tiles(magnify_tiles(h, which, -k, x, y, step), cf,
                      magnify_tiles(s, which, -k, x, y, step).astype(np.float32), *args)
    assert np.array_equal(got, want)
    one = magnify_tint_tiles(h, s, which[:1], -k[:1], x[:1], y[:1], step, cf, *args)
    assert np.array_equal(one, want[:1])  # one tile: the serial twin, the same bytes
    with pytest.raises(ValueError):
        magnify_tint_tiles(h, s[:2], which, -k, x, y, step, cf, *args)


def test_every_style_shades_magnified_tiles_as_with_the_reference(tmp_path, monkeypatch):
    """The one magnification serves every style's magnified tiles (heights, a drape's
    colours and cover, the lit shade, several channels) with the same bytes as the
    reference interpolation: a DEM with a void, each style, magnified tiles of two
    level-0 tiles at three magnifications."""
    import rasterio
    from rasterio.transform import from_origin

    import geoterrain
    import geoterrain.rendering.tileshader as shader_module
    from geoterrain.ingest.synth import generate
    from geoterrain.rendering.drape import Drape
    from geoterrain.rendering.shading import Light
    from tests.conftest import write_tif

    z = (generate("fbm", 65, seed=3) * 0.1).astype(np.float32)
    z[20:34, 10:30] = -9999.0
    tif = write_tif(tmp_path / "d.tif", z, crs="EPSG:4326", origin=(10.0, 46.0),
                    spacing=1 / 1200, nodata=-9999)
    rng = np.random.default_rng(1)
    rgba = rng.integers(0, 256, (4, 48, 48)).astype(np.uint8)
    rgba[3] = np.where(np.add.outer(np.arange(48), np.arange(48)) % 13 < 8, 255, 0)
    img = tmp_path / "drape.tif"
    with rasterio.open(img, "w", driver="GTiff", width=48, height=48, count=4, dtype="uint8",
                       crs="EPSG:4326", photometric="RGB", alpha="YES",
                       transform=from_origin(9.99, 46.01, 0.075 / 48, 0.075 / 48)) as dst:
        dst.write(rgba)
    styles = [("normals", "terrain", None, None), ("normals", "auto", Light(200.0, 30.0), None),
              ("normals", "auto", Light(shadows=True), None), ("elevation", "auto", None, None),
              ("plain", "auto", None, None), ("normals", "auto", None, Drape(str(img))),
              ("elevation", "auto", None, Drape(str(img), 0.5))]
    with geoterrain.open(geoterrain.preprocess(tif, tmp_path / "d.geoterrain",
                                               tile_size=16)) as t:
        keys = [(0, 1, 1), (0, 3, 2)]  # the void's tile, and one without
        assert all(k in t.tile_info for k in keys)
        texels, outs = 0, {}
        for shading, cmap, light, drape in styles:
            sh = shader_module.TileShader(t, shading, cmap, light, drape)
            outs[sh.style] = out = []
            assert not sh.tinted  # these go through magnified, one tile at a time
            for _, X, Y in keys:
                for k in (1, 2, 3):
                    for x in range(X << k, (X + 1) << k):
                        for y in range(Y << k, (Y + 1) << k, 1 << max(k - 1, 0)):
                            got = sh._one(-k, x, y)
                            monkeypatch.setattr(shader_module, "magnified", _reference)
                            want = sh._one(-k, x, y)
                            monkeypatch.undo()
                            assert np.array_equal(got, want), (shading, drape, k, x, y)
                            texels += got.shape[0] * got.shape[1]
                            out.append(got)
        assert texels > 50_000
        plain, draped = (np.stack(outs[shader_module.TileShader(t, "elevation", "auto", None,
                                                                 dr).style])
                         for dr in (None, styles[-1][3]))
        assert 0.2 < (plain != draped).any(-1).mean() < 1  # the drape's colours and cover


def test_magnify_tiles_refuses_what_it_would_read_past():
    src = np.zeros((1, 5, 5))
    for args in ((np.array([1]), np.array([-1])), (np.array([0]), np.array([0]))):
        with pytest.raises(ValueError):
            magnify_tiles(src, args[0], args[1], np.array([0]), np.array([0]), 4)
    with pytest.raises(ValueError):  # a tile wider than its source
        magnify_tiles(src, np.array([0]), np.array([-1]), np.array([0]), np.array([0]), 16)

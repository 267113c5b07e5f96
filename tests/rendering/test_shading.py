"""Sun, cast shadows and ambient occlusion (geoterrain.rendering.shading).

The shadow sweep is checked against the per-sample ray march of
``reference.shadow_reference`` (no shared code), on real DEM crops and synthetic ones.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.cli.main import cli
from geoterrain.ingest.synth import generate
from geoterrain.rendering.shading import Light, hillshade, shadow_mask, sky_view
from geoterrain.testing.reference import shadow_reference
from tests.conftest import has_real_dem, real_dem

_SYN = {}


def _synthetic(name: str) -> np.ndarray:
    """129² DEMs at 30 m: fBm and ridged noise with 600 m of relief."""
    if name not in _SYN:
        z = generate(name, 129, seed=3)
        _SYN[name] = (z - z.min()) * (600.0 / (z.max() - z.min()))
    return _SYN[name]


def _agreement(z, valid, az, el) -> float:
    a = shadow_mask(z, valid, 30.0, az, el)
    b = shadow_reference(z, valid, 30.0, az, el)
    return float((a == b)[valid].mean())


@pytest.mark.fast
@settings(max_examples=8, deadline=None)
@given(name=st.sampled_from(["fbm", "ridged"]), az=st.floats(0, 360),
       el=st.floats(20, 70), hole=st.booleans())
def test_shadows_agree_with_a_ray_march(name, az, el, hole):
    z = _synthetic(name)
    valid = np.ones(z.shape, bool)
    if hole:
        valid[40:60, 70:95] = False  # nodata casts no shadow and gets none
    assert _agreement(z, valid, az, el) >= 0.99


@pytest.mark.skipif(not has_real_dem("srtm1_japan.tif"), reason="real DEMs absent")
@pytest.mark.parametrize("az,el", [(315, 45), (200, 20), (135, 35), (250, 25)])
def test_shadows_agree_on_a_real_dem(az, el):
    import rasterio

    with rasterio.open(real_dem("srtm1_japan.tif")) as src:
        z = src.read(1).astype(np.float64)[0:160, 0:160]  # Hakone's slopes, 1020 m relief
    assert _agreement(z, np.ones(z.shape, bool), az, el) >= 0.99


@pytest.mark.fast
def test_a_spike_shades_the_ground_away_from_the_sun():
    z = np.zeros((21, 21))
    z[10, 10] = 5.0  # at 45°, a 5 m spike on 1 m samples casts a 5-sample shadow
    for az, away in ((90, (0, -1)), (270, (0, 1)), (0, (1, 0)), (180, (-1, 0))):
        m = shadow_mask(z, np.ones_like(z, bool), 1.0, az, 45.0)
        di, dj = away
        assert all(m[10 + di * k, 10 + dj * k] for k in range(1, 5))
        assert not m[10 + di * 7, 10 + dj * 7]
        assert not m[10 - di, 10 - dj]  # nothing on the sunny side
        assert m.sum() < 15


@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(h=st.floats(-500, 5000), az=st.floats(0, 360), el=st.floats(1, 90))
def test_a_level_plane_has_no_shadow_and_an_open_sky(h, az, el):
    z = np.full((17, 17), h)
    v = np.ones(z.shape, bool)
    assert not shadow_mask(z, v, 10.0, az, el).any()
    assert (sky_view(z, v, 10.0) == 1.0).all()


@pytest.mark.fast
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 1000))
def test_sky_view_is_within_0_and_1_and_lower_in_a_valley(seed):
    z = generate("fbm", 65, seed=seed)
    s = sky_view(z, np.ones(z.shape, bool), 30.0)
    assert (s >= 0).all() and (s <= 1).all()
    bowl = np.add.outer(np.arange(33.0) - 16, np.zeros(33)) ** 2
    bowl = bowl + bowl.T  # a paraboloid bowl: its bottom sees less sky than its rim
    sb = sky_view(bowl, np.ones(bowl.shape, bool), 1.0)
    assert sb[16, 16] < sb[0, 16]


@pytest.mark.fast
def test_the_default_light_is_the_classic_hillshade():
    """The default light is the cartographic sun (north-west, 45°) of the classic
    formula min(0.35 + 0.65 · max(n·l, 0) / l_z, 1.25), written out here."""
    rng = np.random.default_rng(0)
    n = rng.normal(size=(50, 3)).astype(np.float32)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    s = np.sqrt(0.5)
    sun = np.array([-s * s, s * s, s], np.float32)  # 315°: x = sin·cos, y = cos·cos
    want = np.minimum(0.35 + 0.65 * np.clip(n @ sun, 0.0, None) / sun[2], 1.25)
    np.testing.assert_allclose(hillshade(n, Light()), want, rtol=0, atol=1e-6)


def test_render_with_sun_shadows_and_occlusion(tmp_path):
    from geoterrain.ingest.synth import write_geotiff

    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=2))
    runner = CliRunner()
    store = tmp_path / "d.geoterrain"
    assert runner.invoke(cli, ["-q", "preprocess", str(dem), "-o", str(store)]).exit_code == 0
    out = tmp_path / "lit.png"
    r = runner.invoke(cli, ["-q", "render", str(store), "-o", str(out), "--size", "320x240",
                            "--sun", "250,20", "--shadows", "--ambient-occlusion",
                            "--hillshade", "multi"])
    assert r.exit_code == 0, r.output
    plain = tmp_path / "plain.png"
    assert runner.invoke(cli, ["-q", "render", str(store), "-o", str(plain), "--size",
                               "320x240"]).exit_code == 0
    import imageio.v3 as iio

    a, b = iio.imread(out).astype(float), iio.imread(plain).astype(float)
    assert a.shape == b.shape and np.abs(a - b).mean() > 1.0  # the light changed the picture
    bad = runner.invoke(cli, ["render", str(store), "-o", str(tmp_path / "x.png"),
                              "--sun", "north"])
    assert bad.exit_code == 2 and "AZ,EL" in bad.output
    bad = runner.invoke(cli, ["render", str(store), "-o", str(tmp_path / "x.png"),
                              "--shadows", "--shading", "elevation"])
    assert bad.exit_code == 2 and "--shading normals" in bad.output
    low = runner.invoke(cli, ["render", str(store), "-o", str(tmp_path / "x.png"),
                              "--sun", "100,-5"])
    assert low.exit_code == 2 and "(0, 90]" in low.output


@pytest.mark.fast
def test_tile_windows_cast_the_shadows_of_the_whole_dem(tmp_path):
    """The textures shade each level-0 tile from a window of its neighbours: where the
    shadows are shorter than a tile, the tiles' shadows are the whole DEM's."""
    import geoterrain
    from geoterrain.ingest.synth import write_geotiff
    from geoterrain.rendering.shading import _level_window, shadow_reach
    from geoterrain.rendering.textures import sample_spacing as _spacing

    z = _synthetic("fbm")
    dem = write_geotiff(tmp_path / "d.tif", z, spacing=30.0)
    t = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=32))
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    s = _spacing(t)
    T = t.grid.tile_samples
    for az, el in ((300, 50), (120, 40)):
        reach = shadow_reach(float(np.nanmax(Z)), float(np.nanmin(Z)), s, el)
        assert reach < T - 1  # shadows shorter than a tile: the window holds them
        whole = shadow_mask(np.where(valid, Z, 0), valid, s, az, el)
        agree = []
        for (_, x, y) in t.tile_keys(0):
            w, v = _level_window(t, 0, x, y, T - 1)
            tile = shadow_mask(w, v, s, az, el)[T - 1:2 * T - 1, T - 1:2 * T - 1]
            r0, c0 = y * (T - 1), x * (T - 1)
            ref, ok = whole[r0:r0 + T, c0:c0 + T], valid[r0:r0 + T, c0:c0 + T]
            tile = tile[:ref.shape[0], :ref.shape[1]]
            agree.append((tile == ref)[ok].mean())
        assert min(agree) >= 0.99, (az, el, min(agree))

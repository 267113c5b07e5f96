"""Seed 004's HAM-driven tessellation: the HAM's numerical targets, the distance law,
and factors that follow the camera (conformity, coverage and the stress cameras are
checked for every registered strategy in test_lod.py and test_stress.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod.tessellation import factors, ham, sobel_magnitude, tess_factor
from geoterrain.lod.tiles import tile_index

INTERIOR = (slice(3, -3), slice(3, -3))  # away from the edge-replicated border


@pytest.mark.fast
@given(a=st.floats(-5, 5), b=st.floats(-5, 5), c=st.floats(-100, 100))
def test_a_plane_has_no_acceleration(a, b, c):
    i, j = np.indices((12, 12)).astype(float)
    h = a * j + b * i + c
    np.testing.assert_allclose(sobel_magnitude(h)[INTERIOR], 8 * np.hypot(a, b), atol=1e-9)
    np.testing.assert_allclose(ham(h)[INTERIOR], 0.0, atol=1e-8)


@pytest.mark.fast
@given(a=st.floats(1e-3, 10))
def test_a_parabola_has_ham_128a(a):
    x = np.tile(np.arange(1.0, 14.0), (13, 1))  # x ≥ 1: away from the fold at the vertex
    np.testing.assert_allclose(ham(a * x * x)[INTERIOR], 128 * a, rtol=1e-9)


@pytest.mark.fast
@given(h=st.floats(0.1, 1000))
def test_a_step_peaks_at_16h(h):
    z = np.zeros((15, 15))
    z[:, 8:] = h
    assert abs(ham(z)[5:10].max() - 16 * h) <= 1e-9 * h


@pytest.mark.fast
def test_the_distance_law():
    # eq. 5-5…5-7: (64, 4, 100) → d_min = 400, T(200) = 16, continuous at both ends
    T = tess_factor(np.array([0.0, 99.999, 100.0, 200.0, 400.0, 1e6]), 64.0, 4.0, 100.0)
    np.testing.assert_allclose(T, [64, 64, 64, 16, 4, 4], rtol=1e-3)


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 100))
def test_factors_grow_as_the_camera_nears_and_are_powers_of_two(tmp_path_factory, seed):
    d = tmp_path_factory.mktemp("tess")
    t = geoterrain.open(geoterrain.preprocess(
        write_geotiff(d / "d.tif", generate("fbm", 257, seed=seed), spacing=30.0),
        d / "d.geoterrain", tile_size=32))
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    index = tile_index(t)
    patches = np.flatnonzero(index.keys[:, 0] == 0)
    last = None
    for k in (3.0, 1.0, 0.3):  # the same patches seen from nearer and nearer
        eye = c + k * (hi - lo) * np.array([0.3, -1.0, 0.6])
        v = geoterrain.View(tuple(eye), tuple(c), size=(320, 240))
        T = factors(t, index, patches, v, 1.0)
        assert ((T >= 1) & (T <= 64)).all() and (np.log2(T) % 1 == 0).all()
        if last is not None:
            assert (T >= last).all()  # nearer: never coarser
        last = T
        sel = t.select(v, 1.0, "tessellation")
        assert 1 <= sel.stats["mean_factor"] <= 64
    # flat terrain: T_max = 1, two triangles a patch wherever the camera is (1025² so
    # that the pyramid has a level as coarse as one quad a patch)
    flat = geoterrain.open(geoterrain.preprocess(
        write_geotiff(d / "f.tif", np.full((1025, 1025), 50.0), spacing=30.0),
        d / "f.geoterrain", tile_size=32))
    lo, hi = flat.scene_box()
    c = 0.5 * (lo + hi)
    sel = flat.select(geoterrain.View(tuple(c + [0, -2000.0, 800]), tuple(c), size=(320, 240)),
                      1.0, "tessellation")
    assert sel.stats["triangles"] == 2 * sel.stats["patches"]


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 100), k=st.floats(0.1, 3.0), az=st.floats(0, 2 * np.pi),
       tau=st.sampled_from([0.5, 1.0, 4.0]))
def test_the_ham_only_lowers_factors(tmp_path_factory, seed, k, az, tau):
    # seed 004 H13: triangles(HAM) ≤ triangles(straight view-dependent LOD) ≤ T = 64
    # everywhere, patch by patch: the HAM caps T_max and leaves the distance law's d_max
    d = tmp_path_factory.mktemp("h13")
    z = generate("fbm", 257, seed=seed)
    z[:, :128] = 20.0  # a flat half, where the HAM is 0
    t = geoterrain.open(geoterrain.preprocess(
        write_geotiff(d / "d.tif", z, spacing=30.0), d / "d.geoterrain", tile_size=32))
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    eye = c + k * (hi - lo) * np.array([np.cos(az), np.sin(az), 0.5])
    v = geoterrain.View(tuple(eye), tuple(c), size=(320, 240))
    index = tile_index(t)
    patches = np.flatnonzero(index.keys[:, 0] == 0)
    ours = factors(t, index, patches, v, tau)
    straight = factors(t, index, patches, v, tau, ham=False)
    assert (ours <= straight).all() and (straight <= 64).all()
    # patches and their edge neighbours all flat: T_max = 1
    assert (ours[index.keys[patches, 1] <= 1] == 1).all()
    from geoterrain.lod import tessellation
    tri = [tessellation.select(t, v, tau, ham=h)[0].n_cells for h in (True, False)]
    assert tri[0] <= tri[1] <= 2 * 32 * 32 * len(patches)


def _store(tmp_path, size=129, holes=False):
    z = generate("fbm", size, seed=5)
    if holes:
        z[40:47, 60:70] = np.nan
    return geoterrain.open(geoterrain.preprocess(
        write_geotiff(tmp_path / "d.tif", z, spacing=30.0, nodata=np.nan if holes else None),
        tmp_path / "d.geoterrain", tile_size=16))


@pytest.mark.fast
def test_patch_statistics_are_the_whole_maps_ham(tmp_path):
    """HAM_max of a patch is the whole map's HAM (edge-replicated at the map's border
    only) over the patch: the two-sample halo makes it exact."""
    from geoterrain.bounds.tilebounds import closed_blocks
    from geoterrain.lod.tessellation import HamStats

    t = _store(tmp_path)
    h, _ = t.level_heights(0)
    full = closed_blocks(ham(h * t.frame.z_to_m), 16, np.maximum)
    n = t.grid.tiles_per_side(0)
    ys, xs = np.divmod(np.arange(n * n), n)
    got = HamStats(t).stats(xs, ys)[:, 0].reshape(n, n)
    np.testing.assert_array_equal(got, full)


@pytest.mark.parametrize("holes", [False, True])
def test_ham_after_an_edit_equals_a_full_recompute(tmp_path, holes):
    """Seed 004 H16: after an edit only the patches within two samples of it are
    computed again, and the statistics equal a full recompute on the edited store."""
    from geoterrain.lod.tessellation import HamStats

    t = _store(tmp_path, holes=holes)
    n = t.grid.tiles_per_side(0)
    ys, xs = np.divmod(np.arange(n * n), n)
    hs = t.derived("geoterrain.lod.tessellation", lambda: HamStats(t))
    hs.stats(xs, ys)
    before = hs.computed
    row, col = 30, 47  # rows 30 … 44, columns 47 … 58: within 2 of tiles 1 … 2 and 2 … 3
    res = t.edit((row, col), np.full((15, 12), -25.0), "add")
    assert res.window == (row, col, 15, 12) or holes
    assert t.derived("geoterrain.lod.tessellation", dict) is hs  # kept, patched
    dropped = np.isnan(hs.values[..., 0])
    want = np.zeros((n, n), bool)
    for y in range(n):
        for x in range(n):
            want[y, x] = (y * 16 - 2 <= row + 14 and y * 16 + 18 >= row
                          and x * 16 - 2 <= col + 11 and x * 16 + 18 >= col)
    np.testing.assert_array_equal(dropped, want)
    after = hs.stats(xs, ys)
    assert hs.computed - before == want.sum()
    fresh = HamStats(geoterrain.open(t.path)).stats(xs, ys)
    np.testing.assert_array_equal(after, fresh)

"""Tests of normal maps (geoterrain.bounds.normals)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from geoterrain.bounds.normalbytes import ring_index
from geoterrain.bounds.normals import (
    OCTAHEDRAL_MAX_ERROR_DEG,
    OCTAHEDRAL_MAX_ERROR_DEG_PRECISE,
    decode_octahedral,
    encode_octahedral,
    level_normal_codes,
    level_normal_maps,
    level_normals,
    normal_map,
    normal_pyramid,
)
from geoterrain.rendering import tileshader

KERNELS = ["central", "horn"]


def plane_normal(a, b):
    n = np.array([-a, -b, 1.0])
    return n / np.linalg.norm(n)


def check_unit(n):
    assert n.dtype == np.float32
    assert np.all(np.isfinite(n))
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-6)
    assert np.all(n[..., 2] >= 0)


@pytest.mark.fast
@pytest.mark.parametrize("kernel", KERNELS)
def test_plane_regular_grid(kernel):
    i, j = np.indices((33, 33), dtype=np.float64)
    x, y = 5.5e5 + 30.0 * j - 4.1e5, 4.2e6 - 30.0 * i - 4.1e6  # north-up, scene frame
    a, b = 0.3, -0.7
    z = a * x + b * y + 12.0
    n = normal_map(x, y, z, np.ones(x.shape, bool), kernel=kernel)
    check_unit(n)
    assert np.allclose(n, plane_normal(a, b), atol=1e-6)  # borders included


@pytest.mark.fast
@pytest.mark.parametrize("kernel", KERNELS)
def test_plane_curvilinear_grid(kernel):
    pyproj = pytest.importorskip("pyproj")
    lat, lon = np.meshgrid(np.linspace(60.5, 60.0, 41), np.linspace(10.0, 11.0, 41), indexing="ij")
    aeqd = pyproj.Proj(proj="aeqd", lat_0=60.25, lon_0=10.5, datum="WGS84")
    x, y = aeqd(lon, lat)
    assert np.ptp(np.diff(x, axis=1)) > 1.0  # really curvilinear
    a, b = 0.05, 0.12
    z = a * x + b * y
    holes = np.ones(x.shape, bool)
    holes[10:13, 20] = False
    n = normal_map(x, y, z, holes, kernel=kernel)
    check_unit(n)
    assert np.allclose(n[holes], plane_normal(a, b), atol=1e-6)


@pytest.mark.fast
def test_plane_synthetic_warp():
    u, v = np.meshgrid(np.linspace(0, 1, 25), np.linspace(0, 1, 25))
    x = 100 * u + 7 * np.sin(3 * v) + 3 * u * v
    y = -100 * v + 5 * np.cos(2 * u) - 2 * u**2
    a, b = -1.5, 0.4
    n = normal_map(x, y, a * x + b * y, np.ones(x.shape, bool))
    assert np.allclose(n, plane_normal(a, b), atol=1e-6)


@pytest.mark.fast
@pytest.mark.parametrize("kernel", KERNELS)
def test_cone_radially_symmetric(kernel):
    m = 41
    i, j = np.indices((m, m), dtype=np.float64)
    x, y = j - 20.0, 20.0 - i
    r = np.hypot(x, y)
    z = 500.0 - 2.0 * r
    n32 = normal_map(x, y, z, np.ones(x.shape, bool), kernel=kernel)
    check_unit(n32)
    n = n32.astype(np.float64)
    # 90-degree rotation of the grid rotates the normals
    rot = np.rot90(n, 1)
    rot_xy = np.stack([-rot[..., 1], rot[..., 0]], axis=-1)  # undo the vector rotation
    assert np.allclose(n[..., :2], rot_xy, atol=1e-6)
    assert np.allclose(n[..., 2], rot[..., 2], atol=1e-6)
    # horizontal part points outward along the radius, away from the apex
    ring = (r > 3) & (r < 17)
    radial = np.stack([x, y], axis=-1) / np.maximum(r, 1e-9)[..., None]
    cross = n[..., 0] * radial[..., 1] - n[..., 1] * radial[..., 0]
    assert np.all(np.abs(cross[ring]) < 0.02)
    assert np.all(np.sum(n[..., :2] * radial, axis=-1)[ring] > 0)
    # samples at the same radius agree (axis-aligned ones exactly)
    assert np.isclose(n[20, 30, 2], n[30, 20, 2]) and np.isclose(n[20, 30, 2], n[20, 10, 2])
    if kernel == "central":  # on an axis the central tangents are exact
        assert np.isclose(n[20, 30, 2], plane_normal(2.0, 0.0)[2], atol=1e-6)


@pytest.mark.fast
@pytest.mark.parametrize("kernel", KERNELS)
def test_holes_borders_no_nan(kernel):
    rng = np.random.default_rng(0)
    i, j = np.indices((30, 30), dtype=np.float64)
    z = rng.normal(0, 5, i.shape)
    valid = rng.random(i.shape) > 0.4
    valid[0, 0], valid[0, 1], valid[1, 0] = True, False, False  # isolated corner sample
    z[~valid] = np.nan
    n = normal_map(j, -i, z, valid, kernel=kernel)
    check_unit(n)
    assert np.array_equal(n[0, 0], [0, 0, 1])
    assert np.all(n[~valid] == np.array([0, 0, 1], np.float32))
    # a one-sample-wide valid row: slope along the row only
    valid = np.zeros((9, 9), bool)
    valid[4] = True
    zz = 2.0 * j[:9, :9]
    n = normal_map(j[:9, :9], -i[:9, :9], zz, valid, kernel=kernel)
    assert np.allclose(n[4], plane_normal(2.0, 0.0), atol=1e-6)
    # degenerate positions (coincident) do not give NaN
    n = normal_map(np.zeros((4, 4)), np.zeros((4, 4)), np.zeros((4, 4)))
    assert np.array_equal(n, np.broadcast_to(np.float32([0, 0, 1]), (4, 4, 3)))


@pytest.mark.fast
def test_level_normals_matches_brute_force():
    rng = np.random.default_rng(1)
    nf = rng.normal(0, 0.3, (17, 17, 3))
    nf[..., 2] = 1.0
    nf /= np.linalg.norm(nf, axis=-1, keepdims=True)
    valid = rng.random((17, 17)) > 0.2
    for level in range(5):
        got = level_normals(nf, level, valid)
        s = 1 << level
        assert got.shape == ((16 >> level) + 1, (16 >> level) + 1, 3)
        for a in range(got.shape[0]):
            for b in range(got.shape[1]):
                r0, r1 = max(a * s - s // 2, 0), min(a * s + s // 2, 16)
                c0, c1 = max(b * s - s // 2, 0), min(b * s + s // 2, 16)
                box = nf[r0 : r1 + 1, c0 : c1 + 1][valid[r0 : r1 + 1, c0 : c1 + 1]]
                ref = box.sum(axis=0) if len(box) else np.array([0.0, 0, 1])
                ref = ref / np.linalg.norm(ref)
                assert np.allclose(got[a, b], ref, atol=1e-6)
    assert np.allclose(level_normals(nf, 0), nf, atol=1e-6)


@pytest.mark.fast
def test_level_normals_of_plane_is_plane():
    i, j = np.indices((65, 65), dtype=np.float64)
    n = normal_map(j, -i, 0.2 * j - 0.1 * i)
    for level in range(7):
        assert np.allclose(level_normals(n, level), plane_normal(0.2, 0.1), atol=1e-6)


@pytest.mark.fast
@pytest.mark.parametrize("precise", [False, True])
@pytest.mark.parametrize("bits", [8, 16])
def test_octahedral_roundtrip(bits, precise):
    rng = np.random.default_rng(2)
    v = rng.normal(size=(200000, 3))
    v = np.concatenate([v, np.eye(3), -np.eye(3), [[1, 1, 0], [0, -1, -1], [1, 1, 1]]])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    e = encode_octahedral(v, bits, precise=precise)
    assert e.dtype == (np.uint8 if bits == 8 else np.uint16) and e.shape == (len(v), 2)
    d = decode_octahedral(e, bits).astype(np.float64)
    assert d.dtype == np.float64 and d.shape == v.shape
    ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(d, v), axis=1), np.sum(d * v, axis=1)))
    bound = (OCTAHEDRAL_MAX_ERROR_DEG_PRECISE if precise else OCTAHEDRAL_MAX_ERROR_DEG)[bits]
    assert ang.max() <= bound
    # float32 input (normal maps) within the same bound
    e32 = encode_octahedral(v.astype(np.float32), bits, precise=precise)
    d32 = decode_octahedral(e32, bits).astype(np.float64)
    cos32 = np.sum(d32 * v, axis=1)
    assert np.degrees(np.arctan2(np.linalg.norm(np.cross(d32, v), axis=1), cos32)).max() <= bound
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    # grid shapes pass through
    grid = encode_octahedral(v[:12].reshape(3, 4, 3), bits)
    assert grid.shape == (3, 4, 2)
    with pytest.raises(ValueError):
        encode_octahedral(v, 12)


@pytest.mark.fast
@pytest.mark.parametrize("kernel", KERNELS)
def test_row_blocks_are_exact(kernel, monkeypatch):
    """The compiled kernel matches the vectorised reference, itself exact by row blocks."""
    import geoterrain.testing.reference as ref_mod

    rng = np.random.default_rng(5)
    i, j = np.indices((40, 23), dtype=np.float64)
    x = j + 0.2 * rng.normal(size=i.shape)
    y = -i + 0.2 * rng.normal(size=i.shape)
    z = rng.normal(0, 3, i.shape)
    valid = rng.random(i.shape) > 0.3
    ref = ref_mod.normal_map_reference(x, y, z, valid, kernel=kernel)
    got = normal_map(x, y, z, valid, kernel=kernel)
    assert np.allclose(got, ref, atol=1e-6, rtol=0)
    assert np.array_equal(got[~valid], np.broadcast_to(np.float32([0, 0, 1]), got[~valid].shape))
    monkeypatch.setattr(ref_mod, "_BLOCK_ROWS", 7)
    assert np.array_equal(ref_mod.normal_map_reference(x, y, z, valid, kernel=kernel), ref)


@pytest.mark.fast
def test_normal_map_degenerate_shapes():
    for shape in [(1, 1), (1, 6), (6, 1), (2, 2)]:
        i, j = np.indices(shape, dtype=np.float64)
        n = normal_map(j, -i, 0.5 * j)
        check_unit(n)
        assert np.allclose(n, normal_map(j, -i, 0.5 * j, kernel="horn"), atol=1e-6)


def _pyramid_reference(nf, valid, levels):
    """Brute force of the filter documented in normal_pyramid."""
    k = (1.0, 2.0, 1.0)
    cur = nf.astype(np.float64)
    w = np.ones(nf.shape[:2]) if valid is None else valid.astype(np.float64)
    out = [cur]
    for _ in range(1, levels):
        rows, cols = (cur.shape[0] + 1) // 2, (cur.shape[1] + 1) // 2
        nxt, wn = np.zeros((rows, cols, 3)), np.zeros((rows, cols))
        for a in range(rows):
            for b in range(cols):
                s, anyw = np.zeros(3), False
                for di in (-1, 0, 1):
                    for dj in (-1, 0, 1):
                        i, j = 2 * a + di, 2 * b + dj
                        if 0 <= i < cur.shape[0] and 0 <= j < cur.shape[1] and w[i, j]:
                            s += k[di + 1] * k[dj + 1] * w[i, j] * cur[i, j]
                            anyw = True
                ln = np.linalg.norm(s)
                nxt[a, b] = s / ln if ln > 1e-12 else (0.0, 0.0, 1.0)
                wn[a, b] = float(anyw)
        out.append(nxt)
        cur, w = nxt, wn
    return out


@pytest.mark.fast
@pytest.mark.parametrize("size", [17, 20])
def test_normal_pyramid_matches_brute_force(size):
    rng = np.random.default_rng(11)
    nf = rng.normal(0, 0.4, (size, size, 3))
    nf[..., 2] = 1.0
    nf /= np.linalg.norm(nf, axis=-1, keepdims=True)
    nf = nf.astype(np.float32)
    valid = rng.random((size, size)) > 0.3
    valid[:6, :6] = False  # a hole wider than one level-1 footprint
    for v in (valid, None):
        got = normal_pyramid(nf, v, 5)
        ref = _pyramid_reference(nf, v, 5)
        assert len(got) == 5
        for g, r in zip(got, ref, strict=True):
            assert g.dtype == np.float32 and g.shape == r.shape
            check_unit(g)
            assert np.allclose(g, r, atol=1e-6)
    got = normal_pyramid(nf, valid, 3)
    assert np.array_equal(got[1][:2, :2], np.broadcast_to(np.float32([0, 0, 1]), (2, 2, 3)))


@pytest.mark.fast
def test_normal_pyramid_of_plane_is_plane():
    i, j = np.indices((65, 65), dtype=np.float64)
    n = normal_map(j, -i, 0.2 * j - 0.1 * i)
    valid = np.random.default_rng(3).random((65, 65)) > 0.2  # every 3x3 holds one
    for v in (None, valid):
        levels = normal_pyramid(n, v, 7)
        assert [a.shape[0] for a in levels] == [65, 33, 17, 9, 5, 3, 2]
        for a in levels:
            assert np.allclose(a, plane_normal(0.2, 0.1), atol=1e-6)
    with pytest.raises(ValueError):
        normal_pyramid(n, None, 0)


@pytest.mark.fast
@pytest.mark.parametrize("bits", [8, 16])
def test_compiled_octahedral_decode_equals_the_array_formula(bits):
    """The compiled decode does the array formula's float64 operations in its order."""

    def _oct_unpack(u, v):  # the array formula the decoder had before it was compiled
        zz = 1.0 - np.abs(u) - np.abs(v)
        neg = zz < 0
        x = np.where(neg, (1.0 - np.abs(v)) * np.where(u >= 0, 1.0, -1.0), u)
        y = np.where(neg, (1.0 - np.abs(u)) * np.where(v >= 0, 1.0, -1.0), v)
        n = np.stack([x, y, zz], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    m = (1 << bits) - 1
    e = np.random.default_rng(bits).integers(0, m + 1, (3, 4096, 2))
    e[0, :4] = [[0, 0], [m, m], [m // 2, m // 2], [0, m]]  # poles, the fold's edges
    e = e.astype(np.uint8 if bits == 8 else np.uint16)
    f = e.astype(np.float64)
    want = _oct_unpack(f[..., 0] / m * 2 - 1, f[..., 1] / m * 2 - 1).astype(np.float32)
    got = decode_octahedral(e, bits)
    assert got.shape == (3, 4096, 3) and np.array_equal(got, want)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.sampled_from([8, 16]), st.integers(0, 2 ** 32 - 1),
       st.floats(0.0, 360.0), st.floats(5.0, 90.0))
def test_hillshade_from_codes_is_the_array_formula(bits, seed, az, alt):
    """The compiled shade of stored codes equals decode-then-shade (float32 rounding)."""
    from geoterrain.rendering.shading import hillshade_codes

    rng = np.random.default_rng(seed)
    codes = rng.integers(0, 1 << bits, (17, 19, 2)).astype(np.uint8 if bits == 8 else np.uint16)
    a, b = np.radians(az), np.radians(alt)
    light = np.array([np.sin(a) * np.cos(b), np.cos(a) * np.cos(b), np.sin(b)], np.float32)
    n = decode_octahedral(codes, bits)
    want = np.minimum(0.35 + 0.65 * (np.clip(n @ light, 0, 1) / light[2]), 1.25)
    got = hillshade_codes(codes, bits, light, 0.35, 1.25)
    assert got.dtype == np.float32 and got.shape == (17, 19)
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=2e-6)


# ----------------------------------- every level's normals derived from its heights
def _pair(tmp_path, z, **kw):
    """The same DEM preprocessed with every normal stored and with every level's derived
    from the heights and the stored border rings."""
    from tests.conftest import store_pair

    return store_pair(tmp_path, z, "derive_normals", **kw)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), shape=st.sampled_from([(33, 33), (50, 37), (20, 65)]),
       tile=st.sampled_from([2, 4, 16]), holes=st.booleans(), lossy=st.booleans(),
       z_scale=st.sampled_from([1.0, 3.0]), z_units=st.sampled_from(["m", "ft"]))
def test_derived_normals_are_the_stored_ones(tmp_path_factory, seed, shape, tile,
                                             holes, lossy, z_scale, z_units):
    """A store whose normals blobs hold only the border ring, at every level, decodes
    every tile's normal codes (and its shaded texture) exactly as the store that keeps them
    all: random rough DEMs, nodata holes, padded shapes, lossless and ε = 2, heights
    exaggerated and in feet (the scene z the reader must rebuild)."""
    tmp = tmp_path_factory.mktemp("nd")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, shape).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, shape)
    if holes:
        z[rng.random(shape) < 0.08] = -9999.0
    full, ring = _pair(tmp, z.astype(np.float32), nodata=-9999.0, tile_size=tile,
                       codec_error=2.0 if lossy else None,
                       pre={"z_scale": z_scale, "z_units": z_units})
    assert "normals_derived" not in full.meta
    assert ring.meta["normals_derived"] == list(range(ring.grid.top_level + 1))
    for L, x, y in full.tile_info:
        assert np.array_equal(full.tile_normal_codes(L, x, y), ring.tile_normal_codes(L, x, y))
        assert np.array_equal(tileshader.tile_rgb(full, L, x, y, "normals"),
                              tileshader.tile_rgb(ring, L, x, y, "normals"))
    _batch_is_tile_by_tile(full, ring)
    if tile >= 16:  # a 3- or 5-sample tile is nearly all ring: the sizes tie, ± a page
        assert ring.path.stat().st_size <= full.path.stat().st_size


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), origin=st.sampled_from([(139.0, 35.0), (-122.3, 46.2),
                                                            (20.0, 69.5), (-70.0, -33.0)]),
       arcsec=st.sampled_from([1.0, 3.0, 30.0]), tile=st.sampled_from([4, 16, 64]))
@example(seed=1, origin=(20.0, 69.5), arcsec=30.0, tile=64)  # corner-only nodes fail here
@example(seed=2, origin=(139.0, 35.0), arcsec=30.0, tile=64)
def test_geographic_stores_derive_normals_to_a_code(tmp_path_factory, seed, origin, arcsec,
                                                     tile):
    """On a geographic frame the reader derives every level's interior normals from
    scene x, y bilinear between pyproj nodes (one call a tile): every code is the full
    store's or next to it, the ring is the full store's, and the tangents of the
    bilinear positions are pyproj's to 10⁻³ of a sample spacing."""
    from geoterrain.bounds.leafbounds import normal_xy

    tmp = tmp_path_factory.mktemp("gn")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 5, (80, 70)).cumsum(0).cumsum(1) / 3 + 500.0
    full, ring = _pair(tmp, z.astype(np.float32), crs="EPSG:4326", spacing=arcsec / 3600,
                       origin=origin, tile_size=tile)
    assert ring.frame.kind == "geographic"
    assert ring.meta["normals_derived"] == list(range(ring.grid.top_level + 1))
    rr, cc = ring_index(ring.grid.tile_samples)
    for L, x, y in full.tile_info:
        a = full.tile_normal_codes(L, x, y).astype(int)
        b = ring.tile_normal_codes(L, x, y).astype(int)
        assert np.array_equal(a[rr, cc], b[rr, cc])
        tileshader.tile_rgb(ring, L, x, y, "normals")
        assert np.abs(a - b).max() <= 1
        X, Y = normal_xy(ring, L, x, y)
        g = ring.grid
        ii, jj = np.meshgrid(g.tile_rows(L, y), g.tile_cols(L, x), indexing="ij")
        X0, Y0 = ring.frame.xy(ii, jj)
        step = float(np.hypot(X0[0, 1] - X0[0, 0], Y0[0, 1] - Y0[0, 0]))
        for e in (X - X0, Y - Y0):  # the tangents' error: under 10⁻³ rad (0.06°)
            assert max(np.abs(np.diff(e, axis=0)).max(),
                       np.abs(np.diff(e, axis=1)).max()) <= 1e-3 * step
    _batch_is_tile_by_tile(ring)
    if tile >= 16:  # a 5-sample tile is nearly all ring: the sizes may tie
        assert ring.path.stat().st_size < full.path.stat().st_size


def _batch_is_tile_by_tile(*terrains) -> None:
    """A frame's new tiles shaded in one compiled call over all of them (derived and
    stored codes, on every core) are, pixel for pixel, the tiles shaded one by one from
    their normal codes as the terrain reads them (tile_normal_codes, shade_tile), and
    what tile_rgb gives."""
    from geoterrain.rendering.colours import LAND, WATER, as_palette, water_level
    from geoterrain.rendering.shading import AMBIENT, DEFAULT_SUN, SHADE_CEILING
    from geoterrain.rendering.textures import elevation_range, height_tolerance
    from geoterrain.rendering.tileshade import shade_tile

    for t in terrains:
        keys = sorted(t.tile_info)
        n0 = t.decoded_normals
        got = tileshader.TileShader(t)._batch(keys)
        assert t.decoded_normals - n0 == len(keys)  # every normals read is counted
        lim = elevation_range(t)
        for k, rgb in zip(keys, got, strict=True):
            one = shade_tile(t.tile(*k).heights * t.frame.z_to_m, t.tile_normal_codes(*k),
                             False, 8, DEFAULT_SUN, AMBIENT, SHADE_CEILING, lim,
                             water_level(as_palette("auto"), lim), LAND, WATER,
                             height_tolerance(t))
            assert np.array_equal(rgb, one), k
            assert np.array_equal(rgb, tileshader.tile_rgb(t, *k, "normals")), k


def test_geographic_normals_take_exact_xy_where_the_frame_bends(tmp_path):
    """A whole-world 1° grid: cells of 8° bend too much for bilinear x, y (next to the
    poles, where latitudes clamp, and at the scene frame's antipode), so those tiles
    take their own x, y and every code is the full store's or next to it (bilinear
    everywhere: level-0 codes off by up to 31 steps)."""
    rng = np.random.default_rng(1)
    z = (rng.normal(0, 60, (180, 360)).cumsum(0) + 2000).astype(np.float32)
    full, ring = _pair(tmp_path, z, crs="EPSG:4326", spacing=1.0, origin=(-180.0, 90.0),
                       tile_size=64)
    assert ring.meta["normals_derived"] == list(range(ring.grid.top_level + 1))
    for L, x, y in full.tile_info:
        a = full.tile_normal_codes(L, x, y).astype(int)
        assert np.abs(a - ring.tile_normal_codes(L, x, y).astype(int)).max() <= 1


@pytest.mark.fast
def test_a_damaged_ring_is_refused_in_one_line(tmp_path):
    """A ring blob of the wrong length (a stranger's store) is a one-line error."""
    import zstandard

    from geoterrain.exceptions import StoreCorruptError

    z = np.random.default_rng(2).normal(0, 5, (33, 33)).cumsum(1)
    _, ring = _pair(tmp_path, z)
    blob = ring._blob
    bad = zstandard.ZstdCompressor().compress(bytes(10))
    ring._blob = lambda key, kind: bad if kind == "normals" else blob(key, kind)
    with pytest.raises(StoreCorruptError, match="normals cannot be decoded"):
        ring.tile_normal_codes(0, 0, 0)


@pytest.mark.fast
def test_a_forked_child_derives_the_same_normals(tmp_path, parallel_always):
    """After the parent has run the parallel kernels (the preprocess, a derived read), a
    child made by fork() reads derived normals with the serial kernels: GNU OpenMP would
    abort it at a parallel launch."""
    from tests.conftest import in_fork

    z = np.random.default_rng(3).normal(0, 5, (65, 65)).cumsum(0)
    full, ring = _pair(tmp_path, z)
    want = full.tile_normal_codes(0, 1, 1).tobytes()
    ring.tile_normal_codes(0, 0, 0)
    got, status = in_fork(lambda: ring.tile_normal_codes(0, 1, 1).tobytes() == want)
    assert got == b"same", (got, status)


@pytest.mark.fast
@settings(max_examples=30, deadline=None)
@given(k=st.integers(1, 5), band=st.integers(1, 12), seed=st.integers(0, 2**31 - 1),
       voids=st.floats(0.0, 0.6), bits=st.sampled_from([8, 16]))
def test_level_normal_codes_by_bands_are_the_maps_codes(k, band, seed, voids, bits):
    """Coded a band of rows at a time (one row of halo each side), every level's codes
    are those of its whole map, on curvilinear grids with voids and any band height."""
    rng = np.random.default_rng(seed)
    N = (1 << k) + 1
    i, j = np.indices((N, N), dtype=np.float64)
    x = j + 0.2 * rng.normal(size=i.shape)
    y = -i + 0.2 * rng.normal(size=i.shape)
    z = rng.normal(0, 3, i.shape)
    valid = rng.random(i.shape) >= voids
    levels = k + 1
    got = level_normal_codes(x, y, z, valid, levels, bits, band=band)
    want = [encode_octahedral(m, bits) for m in level_normal_maps(x, y, z, valid, levels)]
    assert len(got) == levels
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and np.array_equal(g, w)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 6), t=st.integers(1, 4), wide=st.integers(1, 3),
       seed=st.integers(0, 2**31 - 1), voids=st.floats(0.0, 0.6),
       bits=st.sampled_from([8, 16]), projected=st.booleans())
def test_ring_normal_codes_are_the_full_codes_on_the_rings(k, t, wide, seed, voids, bits,
                                                            projected):
    """The codes of the tiles' rings alone (three-line strips stacked) are the whole maps'
    codes on every ring row and column, and every tile's ring gathers the full map's, on
    squares and root grids' rectangles, with voids, on curvilinear and broadcast x, y."""
    from geoterrain.bounds.normals import ring_normal_codes
    from geoterrain.bounds.tileblobs import ring_blobs

    t = min(t, k)
    rng = np.random.default_rng(seed)
    R, C = (1 << k) + 1, wide * (1 << k) + 1
    i, j = np.indices((R, C), dtype=np.float64)
    if projected:  # read-only broadcast views, as Frame.grid_xy gives
        x = np.broadcast_to(np.arange(C) * 10.0, (R, C))
        y = np.broadcast_to((-np.arange(R) * 10.0)[:, None], (R, C))
    else:
        x = j + 0.2 * rng.normal(size=i.shape)
        y = -i + 0.2 * rng.normal(size=i.shape)
    z = rng.normal(0, 3, i.shape)
    valid = rng.random(i.shape) >= voids
    levels = k - t + 1
    full = level_normal_codes(x, y, z, valid, levels, bits)
    rings = ring_normal_codes(x, y, z, valid, levels, t, bits)
    assert len(rings) == levels
    for L, (f, r) in enumerate(zip(full, rings, strict=True)):
        step = 1 << t
        assert r.lines_r.tolist() == list(range(0, f.shape[0], step))
        assert r.lines_c.tolist() == list(range(0, f.shape[1], step))
        assert r.rows.dtype == f.dtype and np.array_equal(r.rows, f[r.lines_r])
        assert np.array_equal(r.cols, f[:, r.lines_c])
        if bits == 8:  # the stored blobs of every tile of the level
            tiles = [(tx, ty) for ty in range((f.shape[0] - 1) >> t)
                     for tx in range((f.shape[1] - 1) >> t)]
            assert ring_blobs(r, t, tiles, L) == ring_blobs(f, t, tiles, L)

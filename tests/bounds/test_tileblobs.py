"""The level-at-once blob builder gives the bytes the per-tile packers give."""

from __future__ import annotations

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.log8codes import log8_codes, log8_exponent, log8_table
from geoterrain.bounds.normalbytes import normals_to_bytes
from geoterrain.bounds.tileblobs import BoundsCoding, compress_rows, level_blobs
from geoterrain.bounds.vertexdata import decode_bounds, pack_bounds_v2, scale_bounds, scale_exponent
from geoterrain.core.grid import level_tiles
from geoterrain.core.rounding import round_up
from geoterrain.core.zstdsafe import strip_magic

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def per_tile(delta, radius, nrm, t, L, top, tiles):
    """The blobs and maxima as each tile's own packers make them (the reference)."""
    cctx = zstandard.ZstdCompressor(level=3)
    ed, kr = log8_exponent(delta), scale_exponent(radius)
    dc = log8_codes(level_tiles(delta, t, L), ed)
    r16, _ = scale_bounds(level_tiles(radius, t, L), kr)
    tn = level_tiles(nrm, t, 0)
    new_only = L < top
    new = np.ones(((1 << t) + 1,) * 2, bool)
    if new_only:
        new[::2, ::2] = False
    out = {"delta": {}, "radius": {}, "normals": {}}
    dmax, rmax = [], []
    for x, y in tiles:
        key = (L, x, y)
        out["delta"][key] = pack_bounds_v2(dc[y, x], ed, True, new_only, cctx)
        out["radius"][key] = pack_bounds_v2(r16[y, x], kr, False, new_only, cctx)
        out["normals"][key] = strip_magic(cctx.compress(normals_to_bytes(tn[y, x])))
        dmax.append(log8_table(ed)[dc[y, x][new]].max())
        rmax.append(round_up(r16[y, x][new].astype(np.float64) * 2.0**kr, np.float32).max())
    return out, np.array(dmax, np.float32), np.array(rmax, np.float32)


@settings(max_examples=40, deadline=None)
@given(t=st.integers(1, 3), levels=st.integers(0, 2), seed=st.integers(0, 2**31),
       scale=st.sampled_from([1e-6, 1.0, 3e4]), holes=st.booleans())
def test_level_blobs_match_the_per_tile_packers(t, levels, seed, scale, holes):
    rng = np.random.default_rng(seed)
    n = (1 << (t + levels)) + 1
    delta = np.abs(rng.normal(0, scale, (n, n)))
    radius = np.abs(rng.normal(0, scale, (n, n))) + delta
    if holes:  # +inf marks mixed diamonds; exact zeros are common on flat ground
        delta[rng.random((n, n)) < 0.1] = np.inf
        delta[rng.random((n, n)) < 0.1] = 0.0
        radius[0, 1], radius[1, 0] = np.nan, -0.0  # never made, but coded as numpy does
    coding = BoundsCoding(delta, radius)
    for L in range(levels + 1):
        nt = 1 << (levels - L)
        nrm = rng.integers(0, 256, ((n - 1) // (1 << L) + 1,) * 2 + (2,)).astype(np.uint8)
        tiles = [(x, y) for y in range(nt) for x in range(nt) if rng.random() < 0.8]
        got, dmax, rmax = level_blobs(coding, nrm, t, L, levels, tiles)
        want, wd, wr = per_tile(delta, radius, nrm, t, L, levels, tiles)
        assert got == want
        np.testing.assert_array_equal(dmax, wd)
        np.testing.assert_array_equal(rmax, wr)


def test_stored_maxima_bound_every_decoded_value():
    rng = np.random.default_rng(5)
    delta = np.abs(rng.normal(0, 7, (17, 17)))
    coding = BoundsCoding(delta, delta + 1)
    blobs, dmax, _ = level_blobs(coding, np.zeros((17, 17, 2), np.uint8), 4, 0, 0, [(0, 0)])
    dec = decode_bounds(blobs["delta"][(0, 0, 0)], (17, 17))
    assert (dec >= delta).all() and dmax[0] == dec.max()


def test_compress_rows_is_one_compress_per_row():
    rows = np.random.default_rng(0).integers(0, 4, (50, 300)).astype(np.uint8)
    cctx = zstandard.ZstdCompressor(level=3)
    assert compress_rows(rows, b"\x02") == [b"\x02" + strip_magic(cctx.compress(r.tobytes()))
                                            for r in rows]
    assert compress_rows(rows[:0]) == []


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), scale=st.sampled_from([1e-30, 1e-6, 1.0, 1e4, 1e30]))
def test_the_compiled_coding_is_numpys(seed, scale):
    rng = np.random.default_rng(seed)
    delta = np.abs(rng.normal(0, scale, (7, 9))).astype(np.float32)
    radius = np.abs(rng.normal(0, scale, (7, 9))).astype(np.float32)
    delta.ravel()[:3] = [np.nan, np.inf, 0.0]
    radius.ravel()[:5] = [np.inf, 0.0, -0.0, np.nan, 1e-45]  # -0.0 and NaN: numpy's path
    c = BoundsCoding(delta, radius)
    ed, kr = log8_exponent(delta), scale_exponent(radius)
    assert (c.ed, c.kr) == (ed, kr)
    np.testing.assert_array_equal(c.dc, log8_codes(delta, ed))
    np.testing.assert_array_equal(c.d_stored, log8_table(ed)[c.dc])
    r16 = round_up(radius.astype(np.float64) * 2.0**-kr, np.float16)
    assert c.r16.tobytes() == r16.tobytes()  # bit for bit: signed zero, NaN
    want = round_up(r16.astype(np.float64) * 2.0**kr, np.float32)
    assert c.r_stored.tobytes() == want.tobytes()


@given(seed=st.integers(0, 2**31), e=st.integers(-128, 127),
       special=st.lists(st.sampled_from([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, -1.0,
                                         1e-45, 3.4e38]), max_size=6))
def test_float32_delta_codes_by_prefix_are_numpys(seed, e, special):
    # δ alone (r given as codes), float32: the prefix look-up path (_code_delta32); every
    # code the first table entry ≥ the value, at the table's own values and one ulp either
    # side of them, at any exponent
    rng = np.random.default_rng(seed)
    t = log8_table(e)
    near = np.concatenate([t, np.nextafter(t, np.float32(np.inf)), np.nextafter(t, np.float32(0))])
    wide = (rng.random(200) * 2.0 ** rng.integers(-150, 128, 200)).astype(np.float32)
    delta = np.concatenate([near, wide, np.array(special, np.float32)]).astype(np.float32)
    delta = np.resize(delta, (9, delta.size // 9 + 1))
    c = BoundsCoding(delta, None, e, r_codes=(np.zeros(delta.shape, np.uint8), 0))
    np.testing.assert_array_equal(c.dc, log8_codes(delta, e))


@given(seed=st.integers(0, 2**31), e=st.integers(-128, 127),
       special=st.lists(st.sampled_from([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, -1.0,
                                         5e-324, 1e-46, 3.5e38, 1e300]), max_size=6))
def test_the_prefix_code_is_the_binary_searchs(seed, e, special):
    # code_lut_nb (the nested radii's codes) against code_up_nb's binary search, on
    # float64 values: the table's entries, one float64 ulp and one float32 ulp either
    # side, values whose nearest float32 lies above them, any exponent
    from geoterrain.bounds.radii import code_lut_nb, code_up_nb, prefix_codes

    rng = np.random.default_rng(seed)
    t = log8_table(e).astype(np.float64)
    f32 = log8_table(e)
    mids = (f32.astype(np.float64) + np.nextafter(f32, np.float32(np.inf))) / 2
    x = np.concatenate([t, np.nextafter(t, np.inf), np.nextafter(t, -np.inf), mids,
                        np.nextafter(mids, np.inf), np.nextafter(mids, -np.inf),
                        np.nextafter(f32, np.float32(0)).astype(np.float64),
                        rng.random(200) * 2.0 ** rng.integers(-160, 140, 200),
                        np.array(special, np.float64)])
    lut = prefix_codes(t)
    got = [code_lut_nb(t, lut, v) for v in x.tolist()]
    want = [code_up_nb(t, v) for v in x.tolist()]
    assert got == want


def test_radius_codes_keep_their_exponent_in_the_header_range():
    """Coordinates so large that the radii's exponent would pass int8's 127 (the blob
    header's byte): e stays 127 and the codes still bound the radii (+inf at worst),
    never a wrapped, tiny scale."""
    import warnings

    from geoterrain.bounds.log8codes import log8_table
    from geoterrain.bounds.radii import vertex_radii
    from geoterrain.bounds.tileblobs import radius_codes

    ii, jj = np.indices((9, 9)).astype(np.float64)
    x, y, z = jj * 1e42, -ii * 1e42, np.zeros((9, 9))
    ok = np.ones((9, 9), bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # float32 overflow: +inf radii
        r = vertex_radii(x, y, z, ok)
        codes, e = radius_codes(x, y, z, ok)
    assert e == 127
    assert (log8_table(e)[codes] >= r).all()


@settings(max_examples=25, deadline=None)
@given(t=st.integers(1, 3), levels=st.integers(0, 2), seed=st.integers(0, 2**31))
def test_level_blobs_with_log8_radii_match_the_per_tile_packers(t, levels, seed):
    """r given as log8 codes (radius_codes): each tile's r blob is that tile's codes in a
    log8 version-2 blob (new vertices only below the top), its maxima the codes' values."""
    rng = np.random.default_rng(seed)
    n = (1 << (t + levels)) + 1
    delta = np.abs(rng.normal(0, 5, (n, n)))
    rc = rng.integers(0, 255, (n, n)).astype(np.uint8)
    er = int(rng.integers(-20, 20))
    coding = BoundsCoding(delta, None, r_codes=(rc, er))
    cctx = zstandard.ZstdCompressor(level=3)
    for L in range(levels + 1):
        nt = 1 << (levels - L)
        nrm = np.zeros(((n - 1) // (1 << L) + 1,) * 2 + (2,), np.uint8)
        tiles = [(x, y) for y in range(nt) for x in range(nt)]
        got, _, rmax = level_blobs(coding, nrm, t, L, levels, tiles, ("radius",))
        codes = level_tiles(rc, t, L)
        new = np.ones(((1 << t) + 1,) * 2, bool)
        if L < levels:
            new[::2, ::2] = False
        for k, (x, y) in enumerate(tiles):
            want = pack_bounds_v2(codes[y, x], er, True, L < levels, cctx)
            assert got["radius"][(L, x, y)] == want
            assert rmax[k] == log8_table(er)[codes[y, x][new]].max()
            parent = None
            if L < levels:  # the vertices shared with the parent hold the same codes
                parent = np.zeros_like(codes[y, x], np.float32)
                h = (codes.shape[-1] - 1) // 2
                parent[(y % 2) * h: (y % 2) * h + h + 1, (x % 2) * h: (x % 2) * h + h + 1] = \
                    log8_table(er)[codes[y, x][::2, ::2]]
            dec = decode_bounds(want, codes[y, x].shape, parent, (x % 2, y % 2))
            assert (dec[new] == log8_table(er)[codes[y, x][new]]).all()


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31), t=st.integers(5, 6), small=st.booleans())
def test_shaped_payloads_are_zstd_11_whole_and_edge_ones_15_the_others_3(seed, t, small):
    """Every δ and r blob flagged CENTRES, PRED or RING is its header and its payload at
    zstd level SHAPED_ZSTD_LEVEL (11), or the level passed (``zlevel``: 15 for a small
    grid, vertexdata.shaped_zstd_level; schema 23); every other δ and r blob of a whole
    tile (the top level's: no NEW_ONLY) or flagged DIFF (a δ_edge) at EDGE_ZSTD_LEVEL (15: a tile a
    store, or the tiles along the data's edge); every other δ, r and normals blob at 3:
    the level is part of the store's bytes, which all writers share through level_blobs.
    The tiles (33² or 65², codes from a few values) are large enough for the levels to
    differ."""
    from geoterrain.bounds.tileblobs import EDGE_ZSTD_LEVEL
    from geoterrain.bounds.vertexdata import (
        CENTRES,
        DIFF,
        NEW_ONLY,
        PRED,
        RING,
        SHAPED_ZSTD_LEVEL,
        SLACK,
        SMALL_SHAPED_ZSTD_LEVEL,
        VERSION_2,
    )
    from geoterrain.core.zstdsafe import compress_one, decompress

    rng = np.random.default_rng(seed)
    levels = 1
    n = (1 << (t + levels)) + 1
    delta = rng.choice([0.0, 0.5, 1.0, 2.0, 7.0], (n, n), p=[0.5, 0.2, 0.1, 0.1, 0.1])
    rc = rng.choice(np.array([0, 3, 9, 20], np.uint8), (n, n), p=[0.4, 0.3, 0.2, 0.1])
    rc[::2, 1::2] = 0
    if seed % 2:  # r with only cell centres (CENTRES) on every tile
        rc[1::2, ::2] = 0
    coding = BoundsCoding(delta, None, r_codes=(rc, 0))
    # a δ_edge: δ raised on the last rows (the same code table), stored as DIFF blobs
    edge = delta.copy()
    edge[-(n // 4):] = np.maximum(edge[-(n // 4):], rng.choice([0.5, 2.0, 7.0], (n // 4, n)))
    coding_e = BoundsCoding(edge, None, ed=coding.ed, r_codes=(rc, 0))
    shaped_level = SMALL_SHAPED_ZSTD_LEVEL if small else SHAPED_ZSTD_LEVEL
    kw = {"zlevel": SMALL_SHAPED_ZSTD_LEVEL} if small else {}
    seen = {3: 0, SHAPED_ZSTD_LEVEL: 0, EDGE_ZSTD_LEVEL: 0}
    differ = {SHAPED_ZSTD_LEVEL: 0, EDGE_ZSTD_LEVEL: 0}
    for L in range(levels + 1):
        nt = 1 << (levels - L)
        nrm = rng.integers(0, 4, ((n - 1) // (1 << L) + 1,) * 2 + (2,)).astype(np.uint8)
        tiles = [(x, y) for y in range(nt) for x in range(nt)]
        got, _, _ = level_blobs(coding, nrm, t, L, levels, tiles, ring=("delta",) if L == 0
                                else False, **kw)
        diff, _, _ = level_blobs(coding_e, nrm, t, L, levels, tiles, kinds=("delta",),
                                 base=coding, **kw)
        for kind, blobs in [*got.items(), ("delta_edge", diff["delta"])]:
            for blob in blobs.values():
                head = 0 if kind == "normals" else 3 + 4 * bool(blob[1] & SLACK)
                bound = kind != "normals" and blob[0] == VERSION_2
                shaped = bound and bool(blob[1] & (CENTRES | PRED | RING))
                whole = bound and not shaped and bool(blob[1] & DIFF or not blob[1] & NEW_ONLY)
                assert (kind == "delta_edge") == bool(bound and blob[1] & DIFF)
                level = shaped_level if shaped else EDGE_ZSTD_LEVEL if whole else 3
                raw = decompress(blob[head:], 1 << 20)
                assert blob[head:] == compress_one(raw, level), (kind, L, blob[:3])
                key = SHAPED_ZSTD_LEVEL if shaped else level
                seen[key] += 1
                if level != 3:
                    differ[key] += compress_one(raw, 3) != compress_one(raw, level)
    assert all(seen.values()) and all(differ.values()), (seen, differ)


def test_a_small_grids_store_holds_its_shaped_payloads_at_zstd_15(tmp_path):
    """Every writer passes vertexdata.shaped_zstd_level of the grid: a small grid's store
    (here 100 × 117 samples, geographic: level-0 normals rings as residuals, r centres
    guessed) holds its normals rings and shaped δ and r payloads at zstd 15, which here
    differ from level 11's bytes (the level would be 11 for a grid past 3 · 2^16)."""
    import geoterrain
    from geoterrain.bounds.vertexdata import CENTRES, PRED, RING, SLACK, VERSION_2
    from geoterrain.core.zstdsafe import compress_one, decompress
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.store.reader import StoreReader

    dem = write_geotiff(tmp_path / "g.tif", generate("fbm", 129, seed=3)[:100, :117].copy(),
                        crs="EPSG:4326", origin=(24.0, 61.0), spacing=1 / 1200)
    p = geoterrain.preprocess(dem, tmp_path / "g.geoterrain", tile_size=32)
    r = StoreReader(p)
    assert r.metadata["normals_ring_residual"] is True
    seen, differ = 0, 0
    for key in r.tiles():
        for kind in ("normals", "delta", "radius"):
            blob = r.get_blob(key, kind)
            if kind != "normals":  # the shaped δ and r payloads (not range-coded ones)
                if blob is None or blob[0] != VERSION_2 or not blob[1] & (CENTRES | PRED | RING) \
                        or blob[1] & SLACK or blob[1] & RING and blob[1] & PRED:
                    continue
                blob = blob[3 + 2 * (blob[1] & PRED and not blob[1] & CENTRES and key[0] > 0):]
                if not blob:  # schema 23: an r whose guessed centres are exact, no payload
                    continue
            raw = decompress(blob, 1 << 20)
            assert blob == compress_one(raw, 15), (key, kind)
            seen += 1
            differ += blob != compress_one(raw, 11)
    r.close()
    assert seen and differ, (seen, differ)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ed=st.integers(-40, 60), er=st.integers(-40, 60),
       t=st.integers(1, 4), top=st.integers(0, 2), ring=st.booleans())
def test_a_coding_of_codes_is_the_coding_of_their_values(seed, ed, er, t, top, ring):
    """``BoundsCoding.of_codes`` (an edit's codes taken as they are) holds the codes that
    coding their table values gives, and level_blobs makes the same blobs and maxima
    from it."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    dc = rng.integers(0, 256, (T, T)).astype(np.uint8)
    rc = rng.integers(0, 255, (T, T)).astype(np.uint8)
    a = BoundsCoding.of_codes(dc, ed, rc, er)
    b = BoundsCoding(log8_table(ed)[dc].astype(np.float64), None, ed, r_codes=(rc, er))
    assert np.array_equal(a.dc, b.dc) and np.array_equal(a.rc, b.rc)
    assert (a.ed, a.er, a.kr) == (b.ed, b.er, b.kr) and a.r16.shape == b.r16.shape
    nrm = np.zeros((T, T, 2), np.uint8)
    ring = ring and top > 0  # level 0 below the top: RING blobs, else PRED or CENTRES
    got = level_blobs(a, nrm, t, 0, top, [(0, 0)], ("delta", "radius"), ring=ring)
    want = level_blobs(b, nrm, t, 0, top, [(0, 0)], ("delta", "radius"), ring=ring)
    assert got[0] == want[0]
    assert np.array_equal(got[1], want[1]) and np.array_equal(got[2], want[2])

"""Level-0 δ and r, and the cell centres' r above level 0, derived on read from a tile's
heights (geoterrain.bounds.leafbounds).

A store written with ``derive_bounds`` keeps only the border ring's new vertices of each
level-0 δ and r blob, and (projected and pixel frames) no cell centre of an r blob above
level 0 (flag ``MIDS``); the reader must rebuild every other value exactly as the
whole-grid kernels computed and coded it. The oracle is the same DEM written with every value
stored, whose δ and r come from :func:`geoterrain.bounds.delta.vertex_errors` and
:func:`~geoterrain.bounds.radii.vertex_radii` over the whole grid.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.bounds.delta import saturate
from geoterrain.bounds.leafbounds import centre_radius, leaf_delta, leaf_radius
from geoterrain.bounds.log8codes import log8_table, mids_index, ring_new_index
from geoterrain.bounds.vertexdata import (
    CENTRES,
    DIFF,
    LOG8,
    MIDS,
    NEW_ONLY,
    PRED,
    RING,
    SLACK,
    VERSION_2,
    decode_bounds,
)
from geoterrain.exceptions import StoreCorruptError
from tests.conftest import real_dem, store_pair, write_tif


def _pair(tmp_path, z, **kw):
    """The same DEM preprocessed with every level-0 δ and r stored, and with the ring only."""
    return store_pair(tmp_path, z, "derive_bounds", **kw)


def _ring_flags(t) -> set:
    return {t._blob(k, kind)[1] & RING for k in t.tile_info for kind in ("delta", "radius")}


def _mids_flags(t) -> set:
    return {t._blob(k, "radius")[1] & MIDS for k in t.tile_info}


def _assert_same_bounds(full, ring):
    for key in full.tile_info:
        for get in ("tile_delta", "tile_radius", "tile_delta_edge"):
            a, b = getattr(full, get)(*key), getattr(ring, get)(*key)
            assert np.array_equal(a, b), (key, get, np.argwhere(a != b)[:5].tolist())


@settings(max_examples=14, deadline=None)
@given(seed=st.integers(0, 10_000), shape=st.sampled_from([(33, 33), (50, 37), (20, 65)]),
       tile=st.sampled_from([2, 4, 16]), holes=st.sampled_from([0.0, 0.03, 0.3]),
       lossy=st.booleans(), z_scale=st.sampled_from([1.0, 3.0]),
       z_units=st.sampled_from(["m", "ft"]))
def test_derived_level0_bounds_are_the_stored_ones(tmp_path_factory, seed, shape, tile, holes,
                                                   lossy, z_scale, z_units):
    """Every tile's δ, r and δ_edge decode to the same float32 values from a store that
    keeps only level 0's border rings as from one that keeps them all: rough random
    DEMs, sparse and dense nodata (mixed diamonds, +inf), padded shapes (δ_edge read
    through the δ blob), tiles of 3–17 samples (T = 3: the cells' diagonals alternate
    from tile to tile), lossless and ε = 2, heights exaggerated and in feet."""
    tmp = tmp_path_factory.mktemp("lb")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, shape).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, shape)
    if holes:
        z[rng.random(shape) < holes] = -9999.0
    full, ring = _pair(tmp, z.astype(np.float32), nodata=-9999.0, tile_size=tile,
                       codec_error=2.0 if lossy else None,
                       pre={"z_scale": z_scale, "z_units": z_units})
    assert _ring_flags(full) == {0} and _mids_flags(full) == {0}
    assert ring.grid.top_level == 0 or RING in _ring_flags(ring)
    assert ring.grid.top_level == 0 or MIDS in _mids_flags(ring)  # the centres above level 0
    _assert_same_bounds(full, ring)
    if tile >= 16:  # a 3- or 5-sample tile is nearly all ring: the sizes tie, ± a page
        assert ring.path.stat().st_size <= full.path.stat().st_size


@pytest.mark.fast
def test_only_level0_blobs_are_rings(tmp_path):
    """Coarser tiles' new vertices have diamonds beyond the tile: they stay stored, but
    for the cell centres of r (flag ``MIDS``), whose children are in the tile. (δ's
    ``PRED`` blobs carry ``SLACK`` instead: schema 20's range-coded payloads.)"""
    z = np.random.default_rng(4).normal(0, 5, (65, 65)).cumsum(0)
    _, ring = _pair(tmp_path, z)
    for key in ring.tile_info:
        for kind in ("delta", "radius"):
            flags = ring._blob(key, kind)[1]
            assert bool(flags & RING) == (key[0] == 0), (key, kind)
            assert bool(flags & MIDS) == (key[0] > 0 and kind == "radius"), (key, kind)
            if kind == "delta" and key[0] > 0:  # schema 20's range-coded PRED δ
                assert bool(flags & SLACK) == bool(flags & PRED), (key, kind)


@pytest.mark.fast
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.sampled_from([2, 3, 4]), s=st.sampled_from([1, 2, 4]),
       holes=st.sampled_from([0.0, 0.2]), relief=st.sampled_from([0.1, 10.0, 1000.0]))
def test_centre_radius_is_the_nested_code(seed, n, s, holes, relief):
    """A tile of stride s (a level-log2(s) tile) cut from a grid whose r codes are nested
    by ``radius_codes``: its cell centres rebuilt from its other samples' codes, heights,
    x, y and the stand-in height are the codes' values bit for bit; the positions scaled
    up change some."""
    from geoterrain.bounds.radii import stand_in_z
    from geoterrain.bounds.tileblobs import radius_codes

    rng = np.random.default_rng(seed)
    N = (1 << n) * s + 1
    ii, jj = np.indices((N, N)).astype(float)
    X, Y = 30.0 * jj + 5e5, -30.0 * ii + 4e6
    Z = rng.normal(0, relief, (N, N)).cumsum(0)
    v = rng.random((N, N)) >= holes
    codes, e = radius_codes(X, Y, np.where(v, Z, np.nan), v)
    want = log8_table(e)[codes[::s, ::s]]
    T = want.shape[0]
    mids = want.copy()
    mids[1::2, 1::2] = 0.0
    zi = stand_in_z(np.where(v, Z, np.nan), v)
    sub = (slice(None, None, s),) * 2
    got = centre_radius(X[sub], Y[sub], Z[sub], v[sub], zi, e, mids)
    assert np.array_equal(got, want)
    assert np.array_equal(got.ravel()[mids_index(T, False)], mids.ravel()[mids_index(T, False)])
    if (want[1::2, 1::2] > 0).any():  # a kernel that misplaces the positions fails
        # (scaled up 1000×: a centre's distances then pass its nested midpoints' radii;
        # halved, the nesting alone may decide every centre's code)
        far = centre_radius(X[sub] * 1e3, Y[sub] * 1e3, Z[sub] * 1e3, v[sub], zi * 1e3, e,
                            mids)
        assert not np.array_equal(far, want)


@pytest.mark.parametrize("name", ["fuji_terrain_rgb.png", "st_helens_terrain_rgb.png",
                                  "terrarium.png", "roi_epsg3089.tif"])
def test_real_dem_bounds_are_derived_exactly(tmp_path, name):
    """The shared DEMs in projected or pixel frames (padded grids: δ_edge too; roi in US
    feet with voids)."""
    p = real_dem(name)
    out = []
    for derive in (False, True):
        out.append(geoterrain.open(geoterrain.preprocess(
            p, tmp_path / f"s{int(derive)}.geoterrain", derive_bounds=derive,
            root_grid=False)))  # the square's arrays (root grids: test_root_curvature.py)
    _assert_same_bounds(*out)


def _delta_grid(t, get="tile_delta") -> tuple[np.ndarray, np.ndarray]:
    """The whole padded grid's decoded δ (or δ_edge), every tile at its level, and where
    a stored tile holds the vertex (an unstored tile's vertices are never read)."""
    g = t.grid
    T, out = g.tile_samples, np.zeros((g.size, g.size), np.float32)
    held = np.zeros(out.shape, bool)
    for L, x, y in sorted(t.tile_info, reverse=True):
        s = 1 << L
        r = y * (T - 1) * s + np.arange(T) * s
        c = x * (T - 1) * s + np.arange(T) * s
        out[np.ix_(r, c)] = getattr(t, get)(L, x, y)
        held[np.ix_(r, c)] = True
    return out, held


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), shape=st.sampled_from([(33, 33), (50, 37), (20, 65)]),
       tile=st.sampled_from([2, 4, 16]), holes=st.sampled_from([0.0, 0.05]),
       place=st.sampled_from([(139.0, 35.0, 1 / 3600), (-70.0, -33.0, 1 / 1200),
                              (20.0, 69.5, 1 / 120), (10.0, -89.5, 1 / 120)]))
def test_geographic_stores_derive_level0_delta_with_a_slack(tmp_path_factory, seed, shape,
                                                           tile, holes, place):
    """On a geographic frame δ carries a curvilinear term of pyproj's x, y, so a ring δ
    blob stores one slack per tile (``SLACK``) that the reader adds to the closed forms.
    Against the store that keeps every δ: each decoded δ and δ_edge is at least its
    value (still a bound) and above it by at most a code step and twice the largest
    slack; δ is nested over the whole decoded grid (saturating it changes nothing);
    r is stored whole and decodes to the same values. Places from 30 m SRTM tiles to
    1 km cells next to the south pole."""
    tmp = tmp_path_factory.mktemp("gl")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, shape).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, shape)
    if holes:
        z[rng.random(shape) < holes] = -9999.0
    lon, lat, step = place
    full, ring = _pair(tmp, z.astype(np.float32), nodata=-9999.0, tile_size=tile,
                       crs="EPSG:4326", spacing=step, origin=(lon, lat),
                       pre={"root_grid": False})  # _delta_grid: the square's arrays
    assert ring.frame.kind == "geographic"
    slacks = [float(np.frombuffer(ring._blob(k, "delta")[3:7], "<f4")[0])
              for k in ring.tile_info  # a ring's slack (a PRED δ's SLACK is schema 20's)
              if ring._blob(k, "delta")[1] & (SLACK | RING) == SLACK | RING]
    top = max(slacks, default=0.0)
    assert all(0 < s < np.inf for s in slacks), slacks
    assert {ring._blob(k, "radius")[1] & RING for k in ring.tile_info} == {0}
    # schema 17: level 0's r centres as differences from their guess from the heights
    both = CENTRES | PRED
    assert ring.grid.top_level == 0 or any(ring._blob(k, "radius")[1] & both == both
                                           for k in ring.tile_info if k[0] == 0)
    assert not any(full._blob(k, "radius")[1] & both == both for k in full.tile_info)
    # schema 20: above level 0 every r vertex as differences from its guess from the
    # heights (MIDS with PRED); the store that keeps every bound has none
    mp = MIDS | PRED
    above = [ring._blob(k, "radius")[1] for k in ring.tile_info
             if 0 < k[0] < ring.grid.top_level]
    assert all(f & mp == mp or f & CENTRES for f in above) and (not above or any(
        f & mp == mp for f in above))
    assert not any(full._blob(k, "radius")[1] & mp == mp for k in full.tile_info)
    assert (ring.grid.top_level == 0
            or {bool(ring._blob(k, "delta")[1] & RING) for k in ring.tile_info
                if k[0] == 0} == {True})
    step_up = 2 ** (1 / 16)
    for key in full.tile_info:
        assert np.array_equal(full.tile_radius(*key), ring.tile_radius(*key))
        for get in ("tile_delta", "tile_delta_edge"):
            a, b = getattr(full, get)(*key), getattr(ring, get)(*key)
            assert (b >= a).all(), (key, get)
            f = np.isfinite(a)
            assert np.array_equal(np.isinf(a), np.isinf(b)), (key, get)
            assert (b[f] <= a[f] * step_up * (1 + 1e-6) + 2 * top * step_up).all(), (key, get)
    for get in ("tile_delta", "tile_delta_edge"):
        d, held = _delta_grid(ring, get)  # nested: saturating changes no stored vertex
        assert np.array_equal(saturate(d.copy())[held], d[held]), get


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.sampled_from([3, 4, 5]), t=st.sampled_from([1, 2, 3]),
       holes=st.sampled_from([0.0, 0.1]))
def test_geographic_leaf_delta_raises_to_a_nested_bound(seed, n, t, holes):
    """The writer's half, on float values (no codes to hide an ulp): from a grid δ
    saturated over random metric terms δ_m at level-0 vertices, every value afterwards
    is at least the one before and at least max(closed form, δ_m) (so still a bound),
    the grid is nested again (saturating it changes nothing), and each tile's
    :func:`leaf_delta` with its slack reproduces its new vertices exactly (what a reader
    derives)."""
    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.bounds.leafbounds import geographic_leaf_delta
    from geoterrain.bounds.log8codes import new_mask

    rng = np.random.default_rng(seed)
    N = (1 << n) + 1
    t = min(t, n - 1)
    z = rng.normal(0, 3, (N, N)).cumsum(0)
    valid = rng.random((N, N)) >= holes
    dm = np.where(rng.random((N, N)) < 0.3, rng.exponential(0.5, (N, N)), 0.0)
    dm[~new_mask(N)] = 0.0  # (level 0's vertices only matter here)
    before = saturate(np.maximum(vertex_errors(z, valid), dm.astype(np.float32)))
    d = before.copy()
    slack = geographic_leaf_delta(d, z, valid, t, dm, np.zeros((N, N), bool))
    assert slack is not None
    assert (d >= before).all()
    assert np.array_equal(saturate(d.copy()), d)
    T = (1 << t) + 1
    rr, rc = ring_new_index(T)
    inner = new_mask(T)
    for (_, x, y), s in slack.items():
        sub = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]
        got = leaf_delta(z[sub], valid[sub], (y << t, x << t), rr, rc, d[sub][rr, rc], None, s)
        assert np.array_equal(got[inner], d[sub][inner]), (x, y)


@pytest.mark.fast
def test_a_geographic_slack_is_checked(tmp_path):
    """A stranger's slack: negative, NaN, or on a blob that is not a ring of log8 codes,
    is refused in one line; a valid one only raises the derived δ."""
    z = np.random.default_rng(1).normal(0, 5, (33, 33)).cumsum(0)
    _, ring = _pair(tmp_path, z, crs="EPSG:4326", spacing=1 / 3600, origin=(139.0, 35.0))
    key = next(k for k in ring.tile_info if k[0] == 0)
    blob = ring._blob
    good = blob(key, "delta")
    assert good[1] & RING
    body = good[7:] if good[1] & SLACK else good[3:]
    head = bytes([good[0], good[1] | SLACK, good[2]])
    want = ring.tile_delta(*key)
    for s, ok in ((-1.0, False), (float("nan"), False), (float("inf"), False), (0.5, True)):
        bad = head + np.float32(s).astype("<f4").tobytes() + body
        fresh = geoterrain.open(ring.path)
        fresh._blob = lambda k, kind, bad=bad: bad if (k, kind) == (key, "delta") else blob(
            k, kind)
        if ok:
            got = fresh.tile_delta(*key)
            assert (got >= want).all() and (got > want).any()
        else:
            with pytest.raises(StoreCorruptError, match="delta cannot be decoded"):
                fresh.tile_delta(*key)
    lvl1 = next(k for k in ring.tile_info if k[0] == 1)
    b1 = blob(lvl1, "delta")  # a slack on a blob that is not a ring
    bad1 = bytes([b1[0], b1[1] | SLACK, b1[2]]) + np.float32(0.1).tobytes() + b1[3:]
    fresh = geoterrain.open(ring.path)
    fresh._blob = lambda k, kind: bad1 if (k, kind) == (lvl1, "delta") else blob(k, kind)
    with pytest.raises(StoreCorruptError, match="delta cannot be decoded"):
        fresh.tile_delta(*lvl1)


@pytest.mark.fast
def test_a_damaged_or_misplaced_ring_is_refused_in_one_line(tmp_path):
    """A stranger's store: a ring at level 1, a δ blob flagged as differences, a ring of
    the wrong length, a ring δ coded as float16: each is a one-line StoreCorruptError."""
    import zstandard

    z = np.random.default_rng(2).normal(0, 5, (65, 65)).cumsum(1)
    _, ring = _pair(tmp_path, z)
    blob = ring._blob
    short = bytes([VERSION_2, NEW_ONLY | RING | 2, 0]) + zstandard.ZstdCompressor().compress(
        bytes(10))
    # (level 1 first: a level-0 read caches its parent)
    T = ring.grid.tile_samples  # a ring δ of float16 values: δ is only ever log8 codes
    f16 = bytes([VERSION_2, NEW_ONLY | RING, 0]) + zstandard.ZstdCompressor().compress(
        bytes(4 * (T - 1)))
    d110 = blob((1, 1, 0), "delta")
    diff = d110[:1] + bytes([d110[1] | DIFF]) + d110[2:]  # a δ "over" a δ it does not have
    for key, bad in [((1, 0, 0), blob((0, 0, 0), "delta")), ((1, 1, 0), diff),
                     ((0, 0, 0), short),
                     ((0, 1, 1), f16)]:
        ring._blob = lambda k, kind, key=key, bad=bad: (bad if (k, kind) == (key, "delta")
                                                        else blob(k, kind))
        with pytest.raises(StoreCorruptError, match="delta cannot be decoded"):
            ring.tile_delta(*key)


@pytest.mark.fast
def test_a_damaged_or_misplaced_mids_blob_is_refused_in_one_line(tmp_path):
    """A stranger's store: ``MIDS`` on a level-0 r, on a δ, beside ``CENTRES`` or
    ``RING``, without log8 codes, or a payload of the wrong length: each is a one-line
    StoreCorruptError; and a MIDS blob without the tile's heights (a geographic store's
    reader passes none) is a ValueError."""
    import zstandard

    z = np.random.default_rng(2).normal(0, 5, (65, 65)).cumsum(1)
    _, st_ = _pair(tmp_path, z)
    blob = st_._blob
    r110 = blob((1, 1, 0), "radius")
    assert r110[1] & MIDS

    def flagged(b, add=0, drop=0):
        return b[:1] + bytes([(b[1] | add) & ~drop]) + b[2:]

    T = st_.grid.tile_samples
    wrong = bytes([VERSION_2, NEW_ONLY | LOG8 | MIDS, 0]) + zstandard.ZstdCompressor().compress(
        bytes(len(mids_index(T, True)) + 1))
    # (a δ in r's schema-20 layout, MIDS with PRED: schema 20's range-coded δ is PRED
    # with SLACK)
    cases = [((0, 0, 0), "radius", r110), ((1, 1, 0), "delta", flagged(blob((1, 1, 0), "delta"),
                                                                       MIDS, SLACK)),
             ((1, 1, 0), "radius", flagged(r110, CENTRES)), ((1, 1, 0), "radius",
                                                             flagged(r110, RING)),
             ((1, 1, 0), "radius", flagged(r110, 0, LOG8)), ((1, 1, 0), "radius", wrong)]
    for key, kind, bad in cases:
        st_._blob = lambda k, kd, key=key, kind=kind, bad=bad: (bad if (k, kd) == (key, kind)
                                                                else blob(k, kd))
        st_.clear_cache()
        with pytest.raises(StoreCorruptError, match=f"{kind} cannot be decoded"):
            getattr(st_, f"tile_{kind}")(*key)
    with pytest.raises(ValueError, match="mids"):
        decode_bounds(r110, (T, T), np.zeros((T, T), np.float32), (1, 0))


@pytest.mark.fast
def test_a_forked_child_derives_the_same_bounds(tmp_path, parallel_always):
    """The derivation kernels are serial: a fork() child of a parent that ran the
    parallel preprocess kernels reads derived bounds (GNU OpenMP would abort a parallel
    launch there)."""
    from tests.conftest import in_fork

    z = np.random.default_rng(3).normal(0, 5, (65, 65)).cumsum(0)
    full, ring = _pair(tmp_path, z)
    want = full.tile_delta(0, 1, 1).tobytes() + full.tile_radius(0, 1, 1).tobytes()
    ring.tile_delta(0, 0, 0)
    got, status = in_fork(lambda: ring.tile_delta(0, 1, 1).tobytes()
                          + ring.tile_radius(0, 1, 1).tobytes() == want)
    assert got == b"same", (got, status)


@pytest.mark.fast
def test_leaf_kernels_by_hand():
    """Closed forms on one cell: the centre's δ is its distance to the midpoint of the
    cell's split diagonal (which flips with the cell's global parity), saturated with its
    edge midpoints; its radius is the farthest edge midpoint; edge midpoints are leaves."""
    from geoterrain.bounds.log8codes import log8_codes, log8_table

    z = np.array([[2.0, 1, 0], [1, 3, 1], [0, 1, 2]])  # the edge samples lie on the legs
    ok = np.ones((3, 3), bool)
    rr, rc = ring_new_index(3)
    ring = np.zeros(len(rr), np.float32)
    e = -4  # codes 2^-4 · 2^((k − 1)/16): powers of two are exact
    assert leaf_delta(z, ok, (0, 0), rr, rc, ring, e)[1, 1] == 1.0  # main: |3 − 2|
    three = log8_table(e)[log8_codes(np.array([3.0]), e)][0]  # anti: |3 − 0|, coded up
    assert leaf_delta(z, ok, (0, 2), rr, rc, ring, e)[1, 1] == three >= 3.0
    ring[0] = 2.0  # the ring's (0, 1), as stored, saturates the centre
    assert leaf_delta(z, ok, (0, 0), rr, rc, ring, e)[1, 1] == 2.0
    ii, jj = np.indices((3, 3)).astype(float)
    r = leaf_radius(jj * 3.0, -ii * 4.0, np.zeros((3, 3)), ok, 0.0, 0)
    assert r[1, 1] == 4.0 and (r[0, 1], r[1, 0]) == (0.0, 0.0)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), shape=st.sampled_from([(40, 33), (50, 37), (20, 65)]),
       tile=st.sampled_from([2, 4, 8]), holes=st.booleans())
def test_delta_edge_decodes_to_the_replicated_grids_delta(tmp_path_factory, seed, shape, tile,
                                                          holes):
    """Every stored tile's δ_edge (its own blob, stored as differences from its δ codes,
    or its δ blob over its parent's δ_edge) decodes to the δ of the grid whose padding
    replicates the data's edge, computed here from the decoded heights by
    :mod:`geoterrain.bounds.edgepad` and coded with the store's table."""
    from geoterrain.bounds.edgepad import edge_deltas, edge_support
    from geoterrain.bounds.log8codes import log8_codes, log8_table
    from geoterrain.bounds.vertexdata import DIFF, PRED

    tmp = tmp_path_factory.mktemp("de")
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, shape).cumsum(0).cumsum(1) / 5
    if holes:
        z[rng.random(shape) < 0.05] = -9999.0
    src = write_tif(tmp / "d.tif", z.astype(np.float32), nodata=-9999.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp / "d.geoterrain", tile_size=tile,
                                              root_grid=False))  # δ_edge: the square's
    g = t.grid
    h, v = t.level_heights(0)
    Zr, ok = edge_support(t.frame.z(np.where(v, h, np.nan)), v, g)
    e = np.int8(np.uint8(t._blob((g.top_level, 0, 0), "delta")[2]))
    want = log8_table(int(e))[log8_codes(edge_deltas(Zr, ok, g), int(e))]
    diffs = guessed = 0
    for L, x, y in t.tile_info:
        s = 1 << L
        rows = y * (g.tile_samples - 1) * s + np.arange(g.tile_samples) * s
        cols = x * (g.tile_samples - 1) * s + np.arange(g.tile_samples) * s
        got = t.tile_delta_edge(L, x, y)
        assert np.array_equal(got, want[np.ix_(rows, cols)]), (L, x, y)
        diffs += (L, x, y) in t.edge_max and bool(t._blob((L, x, y), "delta_edge")[1] & DIFF)
        # schema 23: guessed from the heights, the padding replicated
        guessed += (L, x, y) in t.edge_max and bool(t._blob((L, x, y), "delta_edge")[1] & PRED)
    assert diffs or not t.edge_max  # the difference blobs were exercised
    assert guessed or not t.edge_max

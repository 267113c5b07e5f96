"""The streaming preprocess's stages against their whole-grid twins: δ and δ_edge read in
row bands (geoterrain.preprocessing.bands.delta), the radius codes nested on per-level arrays
(geoterrain.preprocessing.bands.radii), the height blobs coded a super-tile at a time
(geoterrain.preprocessing.bands.codec), every level's normal codes from a row-band cascade
(geoterrain.preprocessing.bands.normals), the quantizer from band statistics
(geoterrain.preprocessing.bands.quantize), and the tile table's bounds
(geoterrain.preprocessing.bands.tiles).

The oracles are the whole-grid functions in memory:
:func:`geoterrain.bounds.delta.vertex_errors`, :func:`geoterrain.bounds.edgepad.edge_deltas`,
:func:`geoterrain.bounds.tileblobs.radius_codes`,
:func:`geoterrain.codec.pyramid.encode_pyramid`,
:func:`geoterrain.bounds.normals.level_normal_maps`,
:func:`geoterrain.codec.quantchoice.choose_quantizer` and
:func:`geoterrain.bounds.tilebounds.tile_and_block_errors`. The streamed values must be the
same bits for every band or super-tile size, with the per-level arrays in memory or in
scratch files. That equality is what makes a streaming preprocess give the same store
whatever its block size.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.edgepad import edge_deltas, edge_support
from geoterrain.bounds.normals import encode_octahedral, level_normal_maps
from geoterrain.bounds.radii import stand_in_z, valid_range
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.codec.pyramid import decoded_codes, encode_pyramid
from geoterrain.codec.quantchoice import choose_quantizer
from geoterrain.codec.quantize import Quantizer
from geoterrain.core.grid import Grid
from geoterrain.exceptions import UsageError
from geoterrain.preprocessing.bands.codec import band_encode_pyramid, super_level, window_of
from geoterrain.preprocessing.bands.delta import band_vertex_errors, edge_rows, rows_of
from geoterrain.preprocessing.bands.normals import band_normal_codes
from geoterrain.preprocessing.bands.radii import band_radius_codes
from geoterrain.preprocessing.bands.tiles import band_tile_bounds
from geoterrain.preprocessing.scratch import ScratchArrays
from tests.conftest import real_dem


def _grid(seed: int, n: int, holes: str) -> tuple[np.ndarray, np.ndarray]:
    N = (1 << n) + 1
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 5, (N, N)).cumsum(0).cumsum(1) / 4 + rng.normal(0, 2, (N, N))
    if seed % 3 == 0:
        z = np.round(z)  # ties on the planes, flat runs
    v = np.ones((N, N), bool)
    if holes == "sparse":
        v = rng.random((N, N)) > 0.03
    elif holes == "dense":
        v = rng.random((N, N)) > 0.4
    elif holes == "blocks":  # a void straddling band rows and coarse blocks
        i, j = rng.integers(0, N, 2)
        v[max(i - N // 3, 0):i + N // 4, max(j - N // 5, 0):j + N // 3] = False
    elif holes == "islands":  # mostly void, a few lone valid samples (tiles stored for them)
        v = rng.random((N, N)) < 0.004
        v[rng.integers(0, N), rng.integers(0, N)] = True
    elif holes == "nan":  # valid but not finite: treated as invalid
        z[rng.random((N, N)) < 0.05] = np.nan
    return z, v


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7),
       holes=st.sampled_from(["none", "sparse", "dense", "blocks", "islands", "nan"]),
       band=st.sampled_from([2, 4, 8, 16, 64, 256]), on_disk=st.booleans())
def test_banded_delta_is_the_whole_grid_delta(tmp_path_factory, seed, n, holes, band, on_disk):
    """Same bits as vertex_errors for every band (fine levels in a band, coarse levels
    across bands, the band's top row carried, mixed diamonds swept in pieces)."""
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    ref = vertex_errors(z, v)
    folder = tmp_path_factory.mktemp("sa") if on_disk else None
    with ScratchArrays(folder) as sa:
        lv = band_vertex_errors(rows_of(z, v), N, band=band, scratch=sa)
        d = lv.grid()
    assert lv.max_finite == float(np.max(ref, where=np.isfinite(ref), initial=0.0))
    bad = np.argwhere(d != ref)
    assert not len(bad), (len(bad), bad[:4].tolist(), d[tuple(bad[0])], ref[tuple(bad[0])])


@pytest.mark.parametrize("band", [2, 16, 128])
def test_banded_delta_on_a_real_dem(band):
    """A real DEM's window (integer metres, ties and flats) gives the same bits."""
    import rasterio
    from rasterio.windows import Window

    path = real_dem("srtm1_japan.tif")
    with rasterio.open(path) as ds:
        N = min(ds.height, ds.width, 513)
        N = (1 << (N - 1).bit_length() - 1) + 1
        z = ds.read(1, window=Window(0, 0, N, N)).astype(np.float64)
        nd = ds.nodata
    v = np.isfinite(z) if nd is None else z != nd
    ref = vertex_errors(z, v)
    assert np.array_equal(band_vertex_errors(rows_of(z, v), N, band=band).grid(), ref)


@pytest.mark.fast
def test_banded_delta_reads_rows_a_band_at_a_time():
    """No read is wider than the band's window (1.5·band + 1 rows)."""
    z, v = _grid(5, 7, "sparse")
    N = z.shape[0]
    spans = []

    def rows(i0, i1):
        spans.append(i1 - i0)
        return z[i0:i1], v[i0:i1]

    d = band_vertex_errors(rows, N, band=16)
    assert max(spans) <= 16 * 3 // 2 + 1
    assert np.array_equal(d.grid(), vertex_errors(z, v))


@pytest.mark.fast
def test_banded_delta_refuses_bad_arguments():
    z, v = _grid(1, 4, "none")
    with pytest.raises(ValueError, match="power of two"):
        band_vertex_errors(rows_of(z, v), 17, band=6)
    with pytest.raises(ValueError, match="2\\*\\*n"):
        band_vertex_errors(rows_of(z, v), 16, band=4)
    with pytest.raises(ValueError, match="rows"):
        band_vertex_errors(lambda i0, i1: (z[i0:i1, :5], v[i0:i1, :5]), 17, band=4)


@pytest.mark.fast
def test_scratch_arrays_round_trip_and_clean_up(tmp_path):
    with ScratchArrays(tmp_path) as sa:
        sa.create("a", (5, 3), np.float32)
        sa.write("a", 2, np.arange(6, dtype=np.float32).reshape(2, 3))
        assert sa.read("a", -1, 9).tolist() == [[0, 0, 0], [0, 0, 0], [0, 1, 2], [3, 4, 5],
                                                [0, 0, 0]]
        assert sa.read("a", 3, 3).shape == (0, 3)
        with pytest.raises(ValueError):
            sa.write("a", 4, np.zeros((2, 3), np.float32))
        assert len(os.listdir(tmp_path)) == 1
    assert os.listdir(tmp_path) == []


@pytest.mark.fast
@settings(deadline=None, max_examples=40)
@given(rows=st.integers(1, 9), cols=st.integers(1, 9), dtype=st.sampled_from(
    ["uint8", "int16", "float32", "float64"]), data=st.data(), on_disk=st.booleans())
def test_scratch_arrays_read_a_window_of_columns(tmp_path_factory, rows, cols, dtype, data,
                                                 on_disk):
    """read(name, r0, r1, c0, c1) is the array's [r0:r1, c0:c1], both ranges clipped,
    in memory and on disk (a row at a time there)."""
    a = np.arange(rows * cols).reshape(rows, cols).astype(dtype)
    r0, r1, c0, c1 = (data.draw(st.integers(-2, n + 2)) for n in (rows, rows, cols, cols))
    with ScratchArrays(tmp_path_factory.mktemp("w") if on_disk else None) as sa:
        sa.create("a", a.shape, a.dtype)
        sa.write("a", 0, a)
        got = sa.read("a", r0, r1, c0, c1)
    ref = a[max(r0, 0):max(r1, 0), max(c0, 0):max(c1, 0)]
    assert got.dtype == a.dtype and got.shape == (
        max(min(r1, rows) - max(r0, 0), 0), max(min(c1, cols) - max(c0, 0), 0))
    assert got.size == 0 or np.array_equal(got, ref)


@settings(deadline=None, max_examples=30)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 6), data=st.data(),
       top=st.booleans(), on_disk=st.booleans())
def test_a_level_lattice_window_is_the_lattice_s(tmp_path_factory, seed, n, data, top,
                                                 on_disk):
    """level_lattice on columns q0 … q1 − 1 (what the blobs stage codes a window of
    tiles at a time) is those columns of the whole lattice, at every level."""
    from geoterrain.preprocessing.bands.delta import level_lattice

    z, v = _grid(seed, n, "sparse")
    N = z.shape[0]
    folder = tmp_path_factory.mktemp("ll") if on_disk else None
    with ScratchArrays(folder) as sa:
        band_vertex_errors(rows_of(z, v), N, band=4, scratch=sa)
        L = data.draw(st.integers(0, n - 1))
        m = ((N - 1) >> L) + 1
        p0 = data.draw(st.integers(0, m - 1))
        p1 = data.draw(st.integers(p0 + 1, m))
        q0 = data.draw(st.integers(0, m - 1))
        q1 = data.draw(st.integers(q0 + 1, m))
        whole = level_lattice(sa, "", L, n, p0, p1, m, top, np.float32)
        got = level_lattice(sa, "", L, n, p0, p1, m, top, np.float32, q0, q1)
    assert np.array_equal(got, whole[:, q0:q1], equal_nan=True)


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7),
       holes=st.sampled_from(["none", "sparse", "blocks"]),
       band=st.sampled_from([2, 4, 16, 64]), budget=st.sampled_from([200, 5000, 1 << 20]),
       scale=st.sampled_from([0.01, 1.0, 300.0]))
def test_banded_radius_codes_are_the_whole_grid_codes(seed, n, holes, band, budget, scale):
    """The nested radius codes pulled level by level, a few rows at a time, are
    radius_codes' (radius=None) on the whole grid, exponent included."""
    z, v = _grid(seed, n, holes)
    z = z * scale
    z[~v] = np.nan
    N = z.shape[0]
    rng = np.random.default_rng(seed)
    xs = np.arange(N) * rng.uniform(0.1, 30) + rng.uniform(-1e6, 1e6)
    ys = -np.arange(N) * rng.uniform(0.1, 30) + rng.uniform(-1e6, 1e6)
    codes, e = radius_codes(np.broadcast_to(xs[None, :], (N, N)),
                            np.broadcast_to(ys[:, None], (N, N)), z, v, None)
    d = band_vertex_errors(rows_of(z, v), N, band=band, heights=True)
    assert d.valid_range == valid_range(z, v)
    assert d.stand_in == stand_in_z(z, v)
    sa = d.arrays
    assert band_radius_codes(sa, N, xs, ys, *d.valid_range[:2], budget=budget) == e
    g = np.zeros((N, N), np.uint8)
    for k in range(n):
        h, s = 1 << k, 2 << k
        g[h::s, h::s] = sa.read(f"rC{k}", 0, N)
        g[h::s, 0::s] = sa.read(f"rR{k}", 0, N)
        g[0::s, h::s] = sa.read(f"rK{k}", 0, N)
    assert np.array_equal(g, codes), np.argwhere(g != codes)[:4].tolist()


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(2, 8), t=st.integers(1, 4),
       holes=st.sampled_from(["none", "sparse", "dense", "blocks", "islands"]),
       mode=st.sampled_from(["int", "float", "quantized", "bins"]),
       predictor=st.sampled_from(["auto", "linear", "cubic"]), coarse=st.integers(0, 8))
def test_windowed_height_blobs_are_encode_pyramids(seed, n, t, holes, mode, predictor, coarse):
    """Every tile blob from super-tile windows (coarse grid first, then each super-tile
    under its decoded codes) is encode_pyramid's, byte for byte, and the same tiles are
    stored: integer, float and ε-quantised codes (pointwise and in residual bins), voids
    (filled from the coarse levels), all three predictor settings, every super-tile
    level. The decoded codes handed out per super-tile are decoded_codes'."""
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    q = {"int": Quantizer("int"), "float": Quantizer("float", 1.0, 0.0, 0.0, 32),
         "quantized": Quantizer("quantized", 0.7, 3.0, 0.35),
         "bins": Quantizer("quantized", 0.1, 3.0, 0.35, bins=7)}[mode]
    if mode == "float":
        z = z.astype(np.float32).astype(np.float64)
    elif mode == "int":
        z = np.round(z)
    k_max = super_level(N, t, 3)  # the deepest super-tile level there is
    cmax = ((N - 1) >> min(coarse, k_max)) + 1
    ref = encode_pyramid(z, v, t, q, predictor=predictor)
    got = band_encode_pyramid(window_of(z, v), N, t, q, predictor=predictor,
                              coarse_max=cmax)
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []
    parts: list[dict] = []  # handed out as made, none kept
    assert band_encode_pyramid(window_of(z, v), N, t, q, predictor=predictor,
                               coarse_max=cmax, sink=parts.append) == {}
    assert {k: b for p in parts for k, b in p.items()} == ref
    assert sum(map(len, parts)) == len(ref)  # each tile once
    dec = np.zeros((N, N), np.int64)
    seen = np.zeros((N, N), bool)

    def decoded(i0, j0, codes, valid):
        m = codes.shape[0]
        dec[i0:i0 + m, j0:j0 + m] = codes
        seen[i0:i0 + m, j0:j0 + m] |= valid

    band_encode_pyramid(window_of(z, v), N, t, q, predictor=predictor, coarse_max=cmax,
                        sink=lambda part: None, decoded=decoded)
    want = decoded_codes(z, v, t, q, predictor)
    assert seen[v].all() and np.array_equal(dec[v], want[v])


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7),
       holes=st.sampled_from(["none", "sparse", "dense", "islands"]),
       band=st.sampled_from([1, 2, 3, 7, 16, 256]), data=st.data())
def test_banded_normal_codes_are_the_whole_grid_maps(seed, n, holes, band, data):
    """Every level's octahedral codes from the row-band cascade are those of the
    whole-grid maps of each level's samples, for any band (odd ones too)."""
    z, v = _grid(seed, n, holes)
    z[~v] = np.nan
    N = z.shape[0]
    levels = data.draw(st.integers(1, n + 1))
    rng = np.random.default_rng(seed)
    xs = np.arange(N) * rng.uniform(0.1, 30)
    ys = -np.arange(N) * rng.uniform(0.1, 30)
    X, Y = np.broadcast_to(xs[None, :], (N, N)), np.broadcast_to(ys[:, None], (N, N))
    ref = [encode_octahedral(a, 8) for a in level_normal_maps(X, Y, z, v, levels)]
    sa = ScratchArrays()
    band_normal_codes(rows_of(z, v), N, xs, ys, levels, sa, band=band)
    for L, r in enumerate(ref):
        m = r.shape[0]
        assert np.array_equal(sa.read(f"n{L}", 0, m).reshape(m, m, 2), r), L


@pytest.mark.fast
@settings(deadline=None)
@given(seed=st.integers(0, 100_000), rows=st.integers(1, 200),
       kind=st.sampled_from(["normal", "integers", "flat", "tiny", "few", "tenths",
                             "late_tenths", "eighths", "huge_then_half",
                             "odd_then_f32_tenths"]),
       eps=st.sampled_from([None, 0.3, 0.5, 2.0]), terrain_rgb=st.booleans(),
       dtype=st.sampled_from(["float32", "float64", "int16"]), band=st.integers(1, 40),
       sort_max=st.sampled_from([1, 5, 1 << 22]), bins=st.sampled_from([2, 16, 1 << 16]))
def test_banded_quantizer_is_choose_quantizer(seed, rows, kind, eps, terrain_rgb, dtype,
                                             band, sort_max, bins):
    """The quantizer from statistics gathered over bands (the exact median by narrowing
    histograms, forced through many rounds by a small sort limit and few bins) is
    choose_quantizer's on the whole array, errors included."""
    import geoterrain.preprocessing.bands.quantize as bq

    rng = np.random.default_rng(seed)
    shape = (rows, 7)
    z = {"normal": lambda: rng.normal(100, 30, shape),
         "integers": lambda: np.round(rng.normal(100, 30, shape)),
         "flat": lambda: np.where(rng.random(shape) < 0.8, 5.25, rng.normal(size=shape)),
         "tiny": lambda: rng.normal(0, 1e-3, shape).astype(np.float32).astype(float),
         "few": lambda: rng.choice([1.0, 2.0, 2.5, 1e6], shape),
         "tenths": lambda: np.rint(rng.normal(1000, 30, shape) * 10) / 10,
         # integers until the last row: the bands are checked for finer grids only
         # once the heights leave the integers
         "late_tenths": lambda: np.vstack([np.round(rng.normal(100, 30, shape))[:-1],
                                           np.rint(rng.normal(100, 30, (1, 7)) * 10) / 10]),
         "eighths": lambda: np.rint(rng.normal(100, 30, shape) * 8) / 8,
         # integers too large for some finer grids' codes, then halves and tenths: the
         # integer bands count through their largest |x|
         "huge_then_half": lambda: np.vstack([
             rng.choice([2.0**51, 4336280868294623.0, 1e15 + 1, 7.0], (rows - 1, 7)),
             rng.choice([0.5, 0.1, 0.0001], (1, 7))]),
         # integers float32 cannot hold (odd, above 2^24; the largest even, so a float32),
         # then float32 tenths widened to float64: no float32-rounded decimal may pass
         "odd_then_f32_tenths": lambda: np.vstack([
             np.hstack([2.0**24 + 1 + 2 * rng.integers(0, 1000, (rows - 1, 6)),
                        np.full((rows - 1, 1), 2.0**25)]),
             (np.rint(rng.normal(1000, 30, (1, 7)) * 10) / 10).astype(np.float32)])}[kind]()
    z[rng.random(shape) < 0.2] = np.nan
    sc, off = (0.1, -10000.0) if terrain_rgb else (None, None)

    def outcome(f):
        try:
            return f()
        except (ValueError, UsageError) as e:  # UsageError: a codec error too fine
            return str(e)

    import geoterrain.core.orderstat as order  # the exact median's histograms

    ref = outcome(lambda: choose_quantizer(z, dtype, eps, sc, off))
    saved = order.SORT_MAX, order.BINS
    order.SORT_MAX, order.BINS = sort_max, bins
    try:
        got = outcome(lambda: bq.band_quantizer(
            lambda: (z[i:i + band] for i in range(0, rows, band)), dtype, eps, sc, off))
    finally:
        order.SORT_MAX, order.BINS = saved
    assert got == ref


@pytest.mark.fast
@pytest.mark.parametrize("bands", [
    [[[2.0**51]], [[0.5]]],
    [[[4336280868294623.0]], [[0.1]]],
    [[[1e15 + 1]], [[0.0001]]],
    [[[3.0], [2.0**52]], [[0.25]]],
    [[[16777217.0, 16777218.0]], [[float(np.float32(1238.6))]]],
])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_banded_finer_grids_count_the_integer_bands_before(bands, dtype):
    """Integer bands then a band off the integers: the integers' codes under a finer step
    can pass 2^52, so the bands must choose what the whole array chooses (here: no finer
    step, float codes), never a step that would round the large integers."""
    import geoterrain.preprocessing.bands.quantize as bq

    arrays = [np.array(b, np.float64) for b in bands]
    whole = choose_quantizer(np.concatenate([a.ravel() for a in arrays]), dtype)
    assert bq.band_quantizer(lambda: iter(arrays), dtype) == whole
    assert whole.mode == "float"


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7), t=st.integers(1, 4),
       holes=st.sampled_from(["none", "sparse", "dense", "blocks", "islands", "nan"]),
       band=st.sampled_from([2, 4, 8, 32, 256]))
def test_banded_tile_bounds_are_the_whole_grid_table(seed, n, t, holes, band):
    """The tile table (counts, boxes, errors, border errors, monotone up the quadtree)
    and every block's δ_n, from row bands, are tile_and_block_errors' on the whole grid:
    fine levels counted in the band's window, coarse ones from the first pass; as a dict
    and as the arrays of a TileTable."""
    z, v = _grid(seed, n, holes)
    N = z.shape[0]
    rng = np.random.default_rng(seed)
    xs = np.arange(N) * rng.uniform(0.1, 30) + rng.uniform(-1e6, 1e6)
    ys = -np.arange(N) * rng.uniform(0.1, 30) + rng.uniform(-1e6, 1e6)
    X, Y = np.broadcast_to(xs[None, :], (N, N)), np.broadcast_to(ys[:, None], (N, N))
    ref, ref_blocks = tile_and_block_errors(z, v, X, Y, t)
    got, blocks = band_tile_bounds(rows_of(z, v), N, t, xs, ys, band=band)
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []
    assert np.array_equal(blocks, ref_blocks)
    # the streaming preprocess's form: the same tiles and numbers as arrays, keys sorted
    table, table_blocks = band_tile_bounds(rows_of(z, v), N, t, xs, ys, band=band, table=True)
    assert table.keys.tolist() == [list(k) for k in sorted(ref)]
    assert table.to_dict() == ref
    assert all(type(b.nvalid) is int for b in table.to_dict().values())
    assert np.array_equal(table_blocks, ref_blocks)


@settings(deadline=None)
@given(seed=st.integers(0, 100_000), rows=st.integers(2, 90), cols=st.integers(2, 90),
       tile=st.sampled_from([2, 4, 16]), holes=st.sampled_from(["none", "sparse", "islands"]),
       band=st.sampled_from([2, 4, 16, 64]))
def test_banded_edge_delta_is_edge_deltas(seed, rows, cols, tile, holes, band):
    """δ_edge (the padding replicated from the data's last row and column, vertices whose
    diamond misses the data zeroed before saturation) from row bands is edge_deltas'."""
    g = Grid.for_shape(rows, cols, tile_size=tile)
    z, v = _grid(seed, 7, holes)
    z, v = z[:rows, :cols], v[:rows, :cols]
    Z, V = g.pad(np.where(v, z, np.nan), np.nan), g.pad(v, False)
    ref = edge_deltas(*edge_support(Z, V, g), g)
    d = band_vertex_errors(edge_rows(rows_of(Z, V), (g.rows, g.cols)), g.size, band=band,
                           data=(g.rows, g.cols))
    assert np.array_equal(d.grid(), ref)

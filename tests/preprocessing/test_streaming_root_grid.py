"""The streamed preprocess of a rectangular root grid (issue 45): the store the whole-grid
preprocess writes with ``root_grid=True``, blob for blob, tile row for tile row and
metadata for metadata, whatever the band, on every scheduler, from a mosaic too, and
after a killed driver is resumed. Projected frames here; a geographic one's in
``test_streaming_geographic_root_grid.py``.

The oracle is :func:`geoterrain.preprocessing.pipeline.preprocess` with ``root_grid``
(itself checked against brute forces in ``test_root_grid.py``); each stage is also
compared with its whole-grid twin on the roots' extent.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.edgepad import edge_deltas, edge_support
from geoterrain.bounds.normals import encode_octahedral, level_normal_maps
from geoterrain.bounds.tileblobs import radius_codes
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.codec.pyramid import decoded_codes, encode_pyramid
from geoterrain.codec.quantize import Quantizer
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.bands.codec import band_encode_pyramid, window_of
from geoterrain.preprocessing.bands.delta import band_vertex_errors, edge_rows, rows_of
from geoterrain.preprocessing.bands.normals import band_normal_codes
from geoterrain.preprocessing.bands.radii import band_radius_codes
from geoterrain.preprocessing.bands.tiles import band_tile_bounds
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.scratch import ScratchArrays
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.preprocessing.test_streaming import _assert_same_store, _tif

ROOTS = [(2, 1), (1, 2), (3, 1), (1, 3), (2, 2), (1, 1)]


def _surface(seed: int, R: int, C: int, holes: float, data: tuple[int, int]):
    # a rough surface on an extent, invalid beyond the data's rows × cols and at holes
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 3, (R, C)).cumsum(0).cumsum(1) / 4
    v = rng.random((R, C)) >= holes
    v[data[0]:] = False
    v[:, data[1]:] = False
    return z, v


def _levels(sa: ScratchArrays, pre: str, n: int, shape: tuple[int, int], dtype):
    # the per-level arrays C{k}, R{k}, K{k} back on the extent
    g = np.zeros(shape, dtype)
    for k in range(n):
        h = 1 << k
        s = 2 * h
        for x, sl in (("C", (slice(h, None, s), slice(h, None, s))),
                      ("R", (slice(h, None, s), slice(0, None, s))),
                      ("K", (slice(0, None, s), slice(h, None, s)))):
            g[sl] = sa.read(f"{pre}{x}{k}", 0, sa.shape(f"{pre}{x}{k}")[0])
    return g


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 6), roots=st.sampled_from(ROOTS),
       t=st.integers(1, 4), holes=st.sampled_from([0.0, 0.05, 0.5]),
       band=st.sampled_from([2, 4, 8, 64]), cut=st.tuples(st.floats(0.3, 1), st.floats(0.3, 1)))
def test_each_stage_on_the_extent_is_its_whole_grid_twin(seed, n, roots, t, holes, band, cut):
    """δ (and δ_edge), the radius codes, the tile bounds and blocks, every level's
    normals and the height blobs, read in bands of the roots' extent, equal the
    whole-grid functions with ``span`` / ``roots`` on it; a data rectangle short of the
    extent both ways, voids, bands of 2 rows to wider than a root."""
    S = 1 << n
    rx, ry = roots
    R, C = ry * S + 1, rx * S + 1
    data = (max(2, int(R * cut[0])), max(2, int(C * cut[1])))
    z, v = _surface(seed, R, C, holes, data)
    assume(v.any())
    d = band_vertex_errors(rows_of(z, v), (R, C), band=band, span=S, heights=True)
    assert np.array_equal(d.grid(), vertex_errors(z, v, span=S))
    xs, ys = np.arange(C) * 10.0, -np.arange(R) * 10.0
    X, Y = np.meshgrid(xs, ys)
    e = band_radius_codes(d.arrays, (R, C), xs, ys, *d.valid_range[:2], span=S)
    codes, e2 = radius_codes(X, Y, z, v, span=S)
    corner = np.zeros((R, C), bool)
    corner[::S, ::S] = True  # no level's vertices (their codes: the whole grid's own)
    got = _levels(d.arrays, "r", n, (R, C), np.uint8)
    assert e == e2 and np.array_equal(got[~corner], codes[~corner])
    # δ_edge: the data's edge replicated into the padding
    g = Grid(data[0], data[1], n, min(t, n), "roots")
    zz = np.where(v, z, np.nan)
    de = band_vertex_errors(edge_rows(rows_of(zz, v), data), (R, C), band=band, span=S,
                            data=data)
    Zr, ok = edge_support(zz, v, g)
    assert np.array_equal(de.grid(), edge_deltas(Zr, ok, g))
    a = band_tile_bounds(rows_of(z, v), (R, C), t, xs, ys, band=band, span=S)
    b = tile_and_block_errors(z, v, X, Y, t, span=S)
    assert a[0] == b[0] and np.array_equal(a[1], b[1])
    levels = n - min(t, n) + 1
    sa = ScratchArrays()
    band_normal_codes(rows_of(z, v), (R, C), xs, ys, levels, sa, band=band)
    for L, m in enumerate(level_normal_maps(X, Y, z, v, levels)):
        want = encode_octahedral(m, 8)
        assert np.array_equal(sa.read(f"n{L}", 0, want.shape[0]).reshape(want.shape), want)


@pytest.mark.parametrize("rows", [95, 96, 97, 98, 160, 161])
def test_delta_edge_skips_the_fine_levels_of_bands_past_the_data(monkeypatch, rows):
    """δ_edge read in bands (the data's edge replicated into a 1 × 2 root grid's lower
    root) computes no fine level in a band from row r0 with r0 − B/2 ≥ the data's rows
    (each of its fine vertices' diamonds misses them: zeroed before saturation), and is
    the whole grid's :func:`edge_deltas` bit for bit; the rows put a band's first-row
    edge midpoints of half-span B/2 just inside the data (97: r0 − B/2 = rows − 1,
    161) or just past it (96, 160), where a skip one band early would lose them."""
    from geoterrain.preprocessing.bands import delta as bd

    S, B, t = 128, 64, 3
    R, C = 2 * S + 1, S + 1
    data = (rows, C - 7)
    z, v = _surface(rows, R, C, 0.0, data)  # no voids: no +inf to hide a lost value
    zz = np.where(v, z, np.nan)
    ran = []
    kernel = bd._fine_level_nb
    monkeypatch.setattr(bd, "_fine_level_nb",
                        lambda band, *a: (ran.append(band.r0), kernel(band, *a))[1])
    de = band_vertex_errors(edge_rows(rows_of(zz, v), data), (R, C), band=B, span=S,
                            data=data)
    g = Grid(data[0], data[1], 7, t, "roots")
    Zr, ok = edge_support(zz, v, g)
    assert np.array_equal(de.grid(), edge_deltas(Zr, ok, g))
    computed = sorted(set(ran))
    assert computed == [r0 for r0 in range(0, R - 1, B) if r0 - B // 2 < rows]
    assert (len(computed) < (R - 1) // B) == (rows <= 160)  # 160: the last band skipped


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(3, 6), roots=st.sampled_from(ROOTS),
       t=st.integers(1, 3), holes=st.sampled_from([0.0, 0.05, 0.5]),
       predictor=st.sampled_from(["auto", "linear", "cubic"]),
       coarse_max=st.sampled_from([3, 5, 9, 1025]),
       mode=st.sampled_from(["int", "float", "bins"]))
def test_the_height_blobs_of_every_root_come_from_super_tiles(seed, n, roots, t, holes,
                                                              predictor, coarse_max, mode):
    """The coarse grid's top level fills each root's edges first, as the whole extent's
    does: every blob equals encode_pyramid's with ``roots`` (integer, float and residual
    bins, every super-tile level), and the decoded codes handed out per super-tile are
    decoded_codes'."""
    S = 1 << n
    R, C = roots[1] * S + 1, roots[0] * S + 1
    z, v = _surface(seed, R, C, holes, (R - S // 3, C - S // 5))
    q = {"int": Quantizer("int"), "float": Quantizer("float", 1.0, 0.0, 0.0, 32),
         "bins": Quantizer("quantized", 0.1, 3.0, 0.35, bins=7)}[mode]
    z = np.round(z * 10) if mode == "int" else z.astype(np.float32).astype(np.float64)
    a = band_encode_pyramid(window_of(z, v), (R, C), t, q, predictor=predictor,
                            coarse_max=coarse_max, roots=roots)
    want = encode_pyramid(z, v, t, q, predictor=predictor, roots=roots)
    assert a.keys() == want.keys() and [k for k in want if a[k] != want[k]] == []
    dec = np.zeros((R, C), np.int64)
    seen = np.zeros((R, C), bool)

    def decoded(i0, j0, codes, valid):
        m = codes.shape[0]
        dec[i0:i0 + m, j0:j0 + codes.shape[1]] = codes
        seen[i0:i0 + m, j0:j0 + codes.shape[1]] |= valid

    band_encode_pyramid(window_of(z, v), (R, C), t, q, predictor=predictor,
                        coarse_max=coarse_max, roots=roots, sink=lambda part: None,
                        decoded=decoded)
    d = decoded_codes(z, v, t, q, predictor, roots=roots)
    assert seen[v].all() and np.array_equal(dec[v], d[v])


def _wide_tif(tmp, seed: int, rows: int, cols: int, holes: float, dtype="float32") -> str:
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 5 + rng.normal(0, 3, (rows, cols))
    z = z.astype(dtype)
    nodata = None
    if holes:
        z[rng.random(z.shape) < holes] = -9999
        nodata = -9999
    return _tif(tmp / "dem.tif", z, nodata)


def _root_grid(rows: int, cols: int, tile: int) -> Grid:
    return Grid.for_shape(rows, cols, tile, roots=True)


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(5, 100), wide=st.floats(1.3, 4.0),
       tall=st.booleans(), tile=st.sampled_from([2, 4, 8, 16, 64]),
       holes=st.sampled_from([0.0, 0.05, 0.6]), dtype=st.sampled_from(["float32", "int16"]),
       eps=st.sampled_from([None, 0.5, 2.0]), band=st.sampled_from([2, 8, 64]))
@example(seed=1, rows=50, wide=2.42, tall=False, tile=8, holes=0.05, dtype="float32", eps=None,
         band=4)
def test_the_streamed_root_grid_store_is_the_whole_grid_one(tmp_path_factory, seed, rows, wide,
                                                            tall, tile, holes, dtype, eps,
                                                            band):
    """Wide and tall rasters on 2 × 1 / 1 × 2 roots (a lattice short of the extent, a
    root over fewer tiles than the square's), voids, lossless and ε, bands of 2 rows to
    a root's side and more."""
    cols = max(5, int(rows * wide))
    if tall:
        rows, cols = cols, rows
    assume(not _root_grid(rows, cols, tile).square)
    tmp = tmp_path_factory.mktemp("rs")
    src = _wide_tif(tmp, seed, rows, cols, holes, dtype)
    a = preprocess(src, tmp / "a.gt", tile_size=tile, codec_error=eps, root_grid=True)
    b = preprocess_streaming(src, tmp / "b.gt", tile_size=tile, codec_error=eps, band=band,
                             root_grid=True)
    assert not geoterrain.open(b).grid.square
    _assert_same_store(a, b)


def test_a_memory_limit_streams_a_root_grid_to_the_same_file(tmp_path):
    """``preprocess(root_grid=True)`` over its memory limit streams (2-row bands here)
    and writes the whole-grid store byte for byte; the square stays the square's."""
    src = _wide_tif(tmp_path, 4, 70, 200, 0.05)
    timings: dict = {}
    a = preprocess(src, tmp_path / "a.gt", tile_size=16, root_grid=True)
    b = preprocess(src, tmp_path / "b.gt", tile_size=16, root_grid=True,
                   memory_limit=1 << 18, timings=timings)
    assert "blobs" in timings  # the streamed run's stages (the whole grid has no "blobs")
    assert geoterrain.open(b).grid.roots == (2, 1)
    assert a.read_bytes() == b.read_bytes()
    c = preprocess(src, tmp_path / "c.gt", tile_size=16, memory_limit=1 << 18,
                   root_grid=False)
    assert geoterrain.open(c).grid.square


@pytest.mark.parametrize("spec", [
    "sync",
    # worker pools and a LocalCluster: 40-60 s at load 12 (their start and compiles)
    pytest.param("processes:2", marks=pytest.mark.slow),
    pytest.param("dask:local:2", marks=pytest.mark.slow)])
def test_the_root_grid_store_is_the_same_on_every_scheduler(tmp_path, spec):
    """A tall raster with voids and ε (the height pass first, its decoded heights read by
    the others) on worker processes and on a dask LocalCluster of 2 workers."""
    if spec.startswith("dask"):
        pytest.importorskip("distributed")
    src = _wide_tif(tmp_path, 7, 150, 60, 0.05)
    for eps in (None, 1.0):
        a = preprocess(src, tmp_path / "a.gt", tile_size=16, codec_error=eps, root_grid=True,
                       overwrite=True)
        b = preprocess_streaming(src, tmp_path / "b.gt", tile_size=16, band=8,
                                 codec_error=eps, scheduler=spec, root_grid=True,
                                 overwrite=True)
        assert geoterrain.open(b).grid.roots == (1, 2)
        _assert_same_store(a, b)


def test_a_mosaic_streams_to_the_root_grid_store(tmp_path):
    """A wide raster cut into four tiles (sharing a row and a column, one with its own
    nodata value): the list and its VRT stream to their whole-grid stores."""
    from geoterrain.ingest.mosaic import build_vrt
    from tests.ingest.test_mosaic import split

    rng = np.random.default_rng(9)
    z = (rng.normal(0, 20, (61, 190)).cumsum(0).cumsum(1) / 5 + 5000).astype(np.int16)
    z[rng.random(z.shape) < 0.05] = -32768
    merged = _tif(tmp_path / "m.tif", z, -32768)
    paths = split(Path(merged), tmp_path / "tiles", overlap=1,
                  nodatas=(-32768, -9999, -32768, -32768))
    tiles = [str(p) for p in paths]
    vrt = tmp_path / "mosaic.vrt"
    vrt.write_text(build_vrt(paths))
    for k, src in enumerate((tiles, str(vrt))):
        a = preprocess(src, tmp_path / f"a{k}.gt", tile_size=16, root_grid=True)
        b = preprocess_streaming(src, tmp_path / f"b{k}.gt", tile_size=16, band=4,
                                 root_grid=True)
        assert geoterrain.open(b).grid.roots == (2, 1)
        _assert_same_store(a, b)


def _killed_after_first_pass(src, dst, band, eps=None, first="bounds"):
    # a streamed root-grid run into dst, SIGKILLed once its first pass is recorded
    import subprocess
    import sys
    import time

    code = ("from geoterrain.preprocessing.streaming import preprocess_streaming; "
            f"preprocess_streaming({src!r}, {str(dst)!r}, band={band}, codec_error={eps}, "
            "root_grid=True)")
    p = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.monotonic() + 180
    while not list(dst.parent.glob(f".{dst.name}.scratch.partial-*/done-{first}")) \
            and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    p.kill()
    p.wait()
    assert not dst.exists(), "the run ended before it could be killed"


@pytest.mark.slow  # a subprocess and a 300 × 1000 raster: 10-20 s at load 5
def test_a_killed_root_grid_run_resumes_to_the_same_store(tmp_path, caplog):
    """SIGKILL of the driver once its first pass is recorded; ``resume`` reuses it and
    writes the uninterrupted run's root-grid store."""
    import logging

    src = _wide_tif(tmp_path, 5, 300, 1000, 0.02)
    ref = preprocess(src, tmp_path / "ref.gt", root_grid=True)
    out = tmp_path / "out"
    out.mkdir()
    dst = out / "s.gt"
    _killed_after_first_pass(src, dst, 4)
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        preprocess_streaming(src, dst, band=4, resume=True, root_grid=True)
    assert "resuming a killed run; passes done: bounds" in caplog.text
    _assert_same_store(ref, dst)
    assert [x.name for x in out.iterdir()] == ["s.gt"]


@pytest.mark.fast
def test_a_streamed_geographic_raster_gets_its_root_grid_by_default(tmp_path, caplog):
    """The default layout is the root grid on every path: a geographic raster that
    streams, by ``preprocess_streaming`` or over ``preprocess``'s memory limit, writes the
    store its whole-grid preprocess writes, quietly; ``root_grid=False`` the square."""
    import logging

    z = np.random.default_rng(2).normal(100, 5, (33, 65)).astype(np.float32)
    src = _tif(tmp_path / "g.tif", z, crs="EPSG:4326")
    whole = preprocess(src, tmp_path / "w.gt", tile_size=16)
    with caplog.at_level(logging.INFO, logger="geoterrain"):
        a = preprocess_streaming(src, tmp_path / "a.gt", tile_size=16, band=8)
        b = preprocess(src, tmp_path / "b.gt", tile_size=16, memory_limit=1 << 18)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    w = geoterrain.open(whole)
    assert (w.frame.kind, w.grid.roots) == ("geographic", (2, 1))
    for p in (a, b):
        _assert_same_store(whole, p)
    sq = preprocess_streaming(src, tmp_path / "sq.gt", tile_size=16, band=8, root_grid=False)
    assert geoterrain.open(sq).grid.square

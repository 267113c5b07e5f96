"""viewshed against the cell-by-cell reference sweep and gdal_viewshed; line_of_sight
against a dense sampling of the bilinear surface."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import real_dem, write_tif
from geoterrain.analysis import line_of_sight, viewshed, write_viewshed
from geoterrain.exceptions import InputError, UsageError
from geoterrain.testing.analysisref import bilinear_reference, viewshed_reference
from tests.analysis.stores import read_source, store_of

GDAL = shutil.which("gdal_viewshed")
needs_gdal = pytest.mark.skipif(GDAL is None, reason="gdal_viewshed absent (make gdal)")
A84 = 6378137.0


def _dem(tmp_path, n=150, seed=4, voids=True, **kw):
    from geoterrain.ingest.synth import generate

    z = generate("fbm", 257, seed=seed)[:n, : n + 17].astype(np.float32) * 0.3
    if voids:
        z[60:70, 30:45] = -9999.0  # a lake of voids
    return write_tif(tmp_path / f"v{seed}.tif", z, nodata=-9999.0 if voids else None, **kw)


def _reference(src, vs, cc=0.85714, mode="edge", target=0.0):
    """The reference sweep over the whole source raster, cut to the viewshed's window."""
    z, valid, tr = read_source(src)
    z = np.where(valid, z, np.nan)
    H, W = z.shape
    r0, c0, wr, wc = vs.stats["window"]
    orow, ocol = vs.observer_cell[0] + r0, vs.observer_cell[1] + c0
    rr, cc_ = np.meshgrid(np.arange(H) - orow, np.arange(W) - ocol, indexing="ij")
    r2 = (rr * tr[4]) ** 2 + (cc_ * tr[0]) ** 2
    radius2 = vs.stats["radius"] ** 2
    ref = viewshed_reference(z, r2, orow, ocol, vs.observer[3], target, cc / (2 * A84),
                             radius2, mode)
    assert (ref[:r0] == 254).all() and (ref[r0 + wr:] == 254).all()
    assert (ref[:, :c0] == 254).all() and (ref[:, c0 + wc:] == 254).all()
    return ref[r0:r0 + wr, c0:c0 + wc]


@pytest.fixture(scope="module")
def voids(tmp_path_factory):
    src = _dem(tmp_path_factory.mktemp("vs"))
    t = geoterrain.open(geoterrain.preprocess(src, src.with_suffix(".geoterrain"),
                                              tile_size=16))
    return t, src


@pytest.mark.fast
@pytest.mark.parametrize("mode", ["edge", "diagonal", "max", "min"])
def test_viewshed_is_the_reference_sweep_on_every_cell(voids, mode):
    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    obs = (c + a * 80.5, f + e * 90.5)
    vs = viewshed(t, obs, radius=700.0, height=3.0, target_height=1.0, mode=mode)
    assert np.array_equal(vs.codes, _reference(src, vs, mode=mode, target=1.0))
    assert vs.stats["uncertain"] == 0 and vs.stats["hidden"] > 0 and vs.stats["visible"] > 0


@settings(max_examples=20, deadline=None)
@given(i=st.integers(0, 149), j=st.integers(0, 166), height=st.floats(0, 40),
       radius=st.floats(15, 2500), cc=st.sampled_from([0.0, 0.85714, 1.0]))
def test_viewshed_anywhere(voids, i, j, height, radius, cc):
    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    obs = (c + a * (j + 0.5), f + e * (i + 0.5))
    z, valid, _ = read_source(src)
    if not valid[i, j]:
        with pytest.raises(InputError, match="nodata"):
            viewshed(t, obs, radius, height, curvature=cc)
        return
    vs = viewshed(t, obs, radius, height, curvature=cc)
    assert np.array_equal(vs.codes, _reference(src, vs, cc=cc))


@pytest.mark.fast
def test_hidden_tiles_are_not_decoded(voids):
    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    t.clear_cache()
    vs = viewshed(t, (c + a * 80.5, f + e * 90.5), radius=2000.0, height=1.0)
    s = vs.stats
    assert s["tiles_skipped"] > 0 and s["tiles_read"] + s["tiles_skipped"] == s["tiles_in_window"]
    assert np.array_equal(vs.codes, _reference(src, vs))


@pytest.mark.fast
@pytest.mark.parametrize("level", [0, 1])
def test_two_threads_give_the_one_thread_viewshed(voids, monkeypatch, level):
    from geoterrain.analysis import visibility

    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    got = []
    for threads in (True, False):  # the halves north and south at once, then in turn
        monkeypatch.setattr(visibility, "_two_threads", lambda on=threads: on)
        t.clear_cache()
        got.append(viewshed(t, (c + a * 80.5, f + e * 60.5), radius=2000.0, height=1.0,
                            level=level))
    two, one = got
    assert np.array_equal(two.codes, one.codes)
    keep = ("tiles_read", "tiles_skipped", "tiles_bounded", "tiles_decoded", "waits",
            "visible", "hidden", "uncertain", "cells")
    assert {k: two.stats[k] for k in keep} == {k: one.stats[k] for k in keep}
    if level == 0:
        assert np.array_equal(one.codes, _reference(src, one))


@pytest.mark.fast
@pytest.mark.parametrize("threads", [True, False])
def test_height_blocks_go_back_only_when_no_sweep_reads_them(voids, monkeypatch, threads):
    """The window's height blocks come from a pool of three tile rows and go back to it
    as each half leaves a tile row: a block given back is poisoned (NaN, which the sweep
    would take for nodata), and the viewshed is still the reference sweep."""
    from geoterrain.analysis import visibility, window

    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    give_back, back = window.Window.give_back, []

    def poisoned(self, ty):
        row = self.tiles.slot[ty]
        self.tiles.z[row[row >= 0]] = np.nan
        back.append(int((row >= 0).sum()))
        give_back(self, ty)

    monkeypatch.setattr(window.Window, "give_back", poisoned)
    monkeypatch.setattr(visibility, "_two_threads", lambda: threads)
    t.clear_cache()
    vs = viewshed(t, (c + a * 80.5, f + e * 60.5), radius=2000.0, height=1.0)
    assert np.array_equal(vs.codes, _reference(src, vs))
    assert len(back) >= 3 and sum(back) > 0  # tile rows given back, blocks poisoned


@pytest.mark.fast
def test_the_asking_cell_probe_changes_nothing_read(voids, monkeypatch):
    """A tile's level-1 bound is skipped when it cannot hide the cell that asked for the
    tile: the same tiles are read and bounded as when the bound is always computed."""
    from geoterrain.analysis import window

    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    read = window.Half.read
    got = []
    for probe in (True, False):
        monkeypatch.setattr(window.Half, "read", read if probe else
                            lambda self, ty, tx, at=None, probe=None: read(self, ty, tx, at))
        t.clear_cache()
        got.append(viewshed(t, (c + a * 80.5, f + e * 60.5), radius=2000.0, height=1.0))
    fast, full = got
    assert np.array_equal(fast.codes, full.codes)
    keep = ("tiles_read", "tiles_skipped", "tiles_bounded", "tiles_decoded", "visible",
            "hidden", "uncertain")
    assert {k: fast.stats[k] for k in keep} == {k: full.stats[k] for k in keep}
    assert fast.stats["tiles_bounded"] > 0 and fast.stats["waits"] < full.stats["waits"]


@pytest.mark.fast
@pytest.mark.parametrize("rows, cols", [(3, 5), (1024, 700)])
def test_window_scratch_is_a_writable_float_grid(rows, cols):
    """The window's heights (ordinary pages from 4 MiB up) hold what is written."""
    from geoterrain.analysis.window import _scratch

    z = _scratch(rows, cols)
    assert z.shape == (rows, cols) and z.dtype == np.float64 and z.flags.writeable
    z[-1, -1], z[0, 0] = 1.5, -2.0
    z[rows // 2] = np.arange(cols)
    assert z[-1, -1] == 1.5 and z[0, 0] == -2.0 and (z[rows // 2] == np.arange(cols)).all()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 3), st.sampled_from([1.0, 0.3048, 0.1]))
def test_level_bound_is_the_union_jack_surface(seed, level, zm):
    """The bound written into the window (compiled) and the asking cell's (Python) are
    level_surface's union-jack surface × z_to_m + lift, bit for bit."""
    from geoterrain.analysis.window import _union_jack_block, _union_jack_into, _union_jack_one

    rng = np.random.default_rng(seed)
    h = rng.normal(0.0, 500.0, (17, 17))  # a tile of 16 cells at level L
    a_org, b_org = (int(v) * 16 for v in rng.integers(0, 5, 2))
    a0 = (a_org << level) + int(rng.integers(0, 16 << level))
    b0 = (b_org << level) + int(rng.integers(0, 16 << level))
    n_r = int(rng.integers(1, (16 << level) + 1 - (a0 - (a_org << level))))
    n_c = int(rng.integers(1, (16 << level) + 1 - (b0 - (b_org << level))))
    lift = float(rng.random())
    out = np.empty((n_r, n_c))
    _union_jack_into(h, level, a_org, b_org, a0, b0, zm, lift, out)
    ref = np.empty((n_r, n_c))
    _union_jack_block(h, level, a_org, b_org, np.arange(a0, a0 + n_r), np.arange(b0, b0 + n_c),
                      ref)
    assert np.array_equal(out, ref * zm + lift)
    k, m = int(rng.integers(0, n_r)), int(rng.integers(0, n_c))
    assert _union_jack_one(h, level, a_org, b_org, a0 + k, b0 + m) * zm + lift == out[k, m]


@pytest.mark.fast
@pytest.mark.parametrize("level", [1, 2])
def test_coarse_level_marks_the_cells_it_cannot_decide(voids, level):
    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    vs = viewshed(t, (c + a * 80.5, f + e * 90.5), radius=2000.0, height=5.0, level=level)
    ref = _reference(src, vs)
    sure = vs.codes != 255
    assert np.array_equal(vs.codes[sure], ref[sure])
    assert 0 < vs.stats["uncertain"] < 0.5 * vs.stats["cells"]


@pytest.mark.fast
def test_lossy_store_marks_uncertain_cells(tmp_path):
    src = _dem(tmp_path, voids=False)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "l.geoterrain", tile_size=16,
                                              codec_error=0.5))
    a, _, c, _, e, f = t.frame.transform[:6]
    vs = viewshed(t, (c + a * 70.5, f + e * 75.5), radius=1500.0, height=2.0)
    ref = _reference(src, vs)  # the source's own heights, not the store's
    sure = vs.codes != 255
    assert np.array_equal(vs.codes[sure], ref[sure])
    assert vs.stats["uncertain"] > 0


@pytest.mark.fast
def test_geographic_grid(tmp_path_factory):
    src = real_dem("srtm3_pysheds.tif")
    t = store_of(tmp_path_factory, src)
    z, valid, tr = read_source(src)
    z = np.where(valid, z, np.nan)
    lon, lat = tr[2] + tr[0] * 180.5, tr[5] + tr[4] * 170.5
    vs = viewshed(t, (lon, lat), radius=6000.0, height=10.0)
    from pyproj import Geod

    geod = Geod(ellps="WGS84")
    H, W = z.shape
    orow, ocol = 170, 180
    lats = tr[5] + tr[4] * (np.arange(H) + 0.5)
    _, _, mx = geod.inv(np.full(H, lon), lats, np.full(H, lon + tr[0]), lats)
    _, _, ny = geod.inv(np.full(H, lon), np.full(H, lat), np.full(H, lon), lats)
    dc = (np.arange(W) - ocol)[None, :]
    r2 = (dc * mx[:, None]) ** 2 + (ny ** 2)[:, None]
    r2r = (dc * mx[orow]) ** 2 + (ny ** 2)[:, None]
    ref = viewshed_reference(z, r2, orow, ocol, vs.observer[3], 0.0, 0.85714 / (2 * A84),
                             6000.0 ** 2, r2_range=r2r)
    r0, c0, wr, wc = vs.stats["window"]
    assert np.array_equal(vs.codes, ref[r0:r0 + wr, c0:c0 + wc])


def _gdal(src, out, x, y, height, md, cc):
    subprocess.run([GDAL, "-q", "-ox", repr(x), "-oy", repr(y), "-oz", repr(height), "-md",
                    repr(md), "-cc", repr(cc), "-ov", "2", str(src), str(out)], check=True)
    import rasterio

    with rasterio.open(out) as r:
        return r.read(1), r.transform


def _agreement(vs, g, gt):
    """Fraction of the cells both answer (and not uncertain here) on which they agree."""
    dr = int(round((vs.transform.f - gt.f) / gt.e))
    dc = int(round((vs.transform.c - gt.c) / gt.a))
    H, W = vs.codes.shape
    theirs = np.full(vs.codes.shape, 2, np.uint8)
    rs, cs = slice(max(dr, 0), min(dr + H, g.shape[0])), slice(max(dc, 0), min(dc + W, g.shape[1]))
    theirs[rs.start - dr:rs.stop - dr, cs.start - dc:cs.stop - dc] = g[rs, cs]
    both = (vs.codes < 2) & (theirs != 2)
    return ((theirs == 255) == (vs.codes == 1))[both].mean(), int(both.sum())


@needs_gdal
@pytest.mark.parametrize("obs,height", [((139.2286, 35.3675), 2.0), ((139.3, 35.4), 30.0),
                                        ((139.15, 35.25), 10.0)])
def test_gdal_viewshed_on_srtm1_japan(tmp_path_factory, tmp_path, obs, height):
    src = real_dem("srtm1_japan.tif")
    t = store_of(tmp_path_factory, src)
    # gdal_viewshed measures in the CRS's units (degrees here): no curvature, and a -md that
    # covers the 10 km disc; the cells both answer are compared
    md = 10000.0 / (111320.0 * math.cos(math.radians(obs[1]))) * 1.05
    g, gt = _gdal(src, tmp_path / "g.tif", *obs, height, md, 0.0)
    vs = viewshed(t, obs, 10000.0, height, curvature=0.0)
    agree, n = _agreement(vs, g, gt)
    assert n > 0.9 * vs.stats["cells"]
    assert agree == 1.0


@needs_gdal
@pytest.mark.fast
def test_gdal_viewshed_projected_with_curvature(voids, tmp_path):
    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    x, y = c + a * 80.3, f + e * 90.7
    g, gt = _gdal(src, tmp_path / "g.tif", x, y, 3.0, 900.0, 0.85714)
    vs = viewshed(t, (x, y), 900.0, 3.0)
    agree, n = _agreement(vs, g, gt)
    # gdal reads the voids' -9999 as heights: compare where the DEM has data
    assert n > 0.9 * vs.stats["cells"] and agree == 1.0


@needs_gdal
@pytest.mark.slow
def test_gdal_viewshed_on_4097_fbm(tmp_path):
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "fbm.tif", generate("fbm", 4097, seed=7), spacing=10.0)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "fbm.geoterrain"))
    x, y = t.frame.transform[2] + 20485.0, t.frame.transform[5] - 20485.0
    radius = math.sqrt(0.25 * 40970.0 ** 2 / math.pi)  # a quarter of the DEM
    g, gt = _gdal(src, tmp_path / "g.tif", x, y, 2.0, radius, 0.85714)
    vs = viewshed(t, (x, y), radius, 2.0)
    agree, n = _agreement(vs, g, gt)
    assert n == vs.stats["cells"] and agree == 1.0
    assert vs.stats["tiles_read"] < 0.5 * vs.stats["tiles_in_window"]


@pytest.mark.fast
def test_viewshed_errors_are_one_line(voids):
    t, _ = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    inside = (c + a * 80.5, f + e * 90.5)
    cases = [((c - 50 * a, f), {}, InputError, "outside the data"),
             ((c + a * 35.5, f + e * 65.5), {}, InputError, "nodata"),
             (inside, {"radius": -1.0}, UsageError, "radius"),
             (inside, {"mode": "bogus"}, UsageError, "mode"),
             (inside, {"crs": "EPSG:0"}, UsageError, "CRS")]
    for obs, kw, exc, word in cases:
        kw = {"radius": 100.0, **kw}
        with pytest.raises(exc, match=word) as info:
            viewshed(t, obs, **kw)
        assert "\n" not in str(info.value)


@pytest.mark.fast
def test_write_viewshed(voids, tmp_path):
    import rasterio

    t, _ = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    vs = viewshed(t, (c + a * 80.5, f + e * 90.5), radius=500.0)
    p = write_viewshed(vs, tmp_path / "vs.tif")
    with rasterio.open(p) as r:
        assert r.nodata == 254 and r.crs is not None and r.res == (abs(a), abs(e))
        assert np.array_equal(r.read(1), vs.codes)
        # on the source grid: the window's corner is a source pixel's corner
        col = (r.transform.c - c) / a
        assert col == round(col)
    with pytest.raises(UsageError, match="exists"):
        write_viewshed(vs, p)
    assert not list(tmp_path.glob(".*partial*"))


def _los_reference(t, src, pa, pb, ha, hb, cc=0.85714, n=20001):
    """Clearance of the sight line over the bilinear source surface, sampled densely."""
    z, valid, tr = read_source(src)
    s = np.linspace(0, 1, n)
    pts = np.column_stack([pa[0] + (pb[0] - pa[0]) * s, pa[1] + (pb[1] - pa[1]) * s])
    ground = bilinear_reference(z, valid, tr, pts)
    D = math.hypot(pb[0] - pa[0], pb[1] - pa[1])
    k = cc / (2 * A84)
    eye, tgt = ground[0] + ha, ground[-1] + hb - k * D * D
    sight = eye + (tgt - eye) * s
    terrain = ground - k * (s * D) ** 2
    return np.nanmin(sight - terrain)


@settings(max_examples=30, deadline=None)
@given(a=st.tuples(st.floats(1, 148), st.floats(1, 165)),
       b=st.tuples(st.floats(1, 148), st.floats(1, 165)), ha=st.floats(0, 30),
       hb=st.floats(0, 10))
def test_line_of_sight_over_the_bilinear_surface(voids, a, b, ha, hb):
    t, src = voids
    A, _, c, _, e, f = t.frame.transform[:6]
    pa = (c + A * a[1], f + e * a[0])
    pb = (c + A * b[1], f + e * b[0])
    z, valid, tr = read_source(src)
    g = bilinear_reference(z, valid, tr, np.array([pa, pb]))
    if np.isnan(g).any() or pa == pb:
        return
    los = line_of_sight(t, pa, pb, ha, hb)
    ref = _los_reference(t, src, pa, pb, ha, hb)
    # the dense sampling can only miss a dip: its minimum is at least the exact one
    assert los.clearance <= ref + 1e-6
    assert los.clearance >= ref - 0.05 * (1 + abs(ref))  # a 20 001-sample grid's gap
    if ref < -0.05:
        assert not los.visible and los.obstruction is not None
    if ref > 1e-6:
        assert los.visible


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, 40))
def test_code_counts_are_numpys(seed, rows, cols):
    from geoterrain.analysis.sweep import count_codes

    rng = np.random.default_rng(seed)
    codes = rng.choice(np.array([0, 1, 254, 255, 7], np.uint8), (rows, cols))
    assert count_codes(codes) == tuple(int(np.count_nonzero(codes == k))
                                       for k in (0, 1, 255, 254))


@pytest.mark.fast
def test_sweep_called_past_the_dispatcher(voids, monkeypatch):
    """After the first viewshed, the sweep's compiled code is called directly (numba's
    dispatcher typed each named-tuple field in Python at every call); the answer is the
    one the dispatcher gives."""
    from geoterrain.analysis import visibility
    from geoterrain.analysis.sweep import sweep_rows

    t, src = voids
    a, _, c, _, e, f = t.frame.transform[:6]
    obs = (c + a * 80.5, f + e * 60.5)
    viewshed(t, obs, radius=2000.0, height=1.0)
    entries = []
    entry = visibility._entry
    monkeypatch.setattr(visibility, "_entry",
                        lambda fn, *args: entries.append(entry(fn, *args)) or entries[-1])
    direct = viewshed(t, obs, radius=2000.0, height=1.0)
    assert entries and all(e is not sweep_rows for e in entries)
    monkeypatch.setattr(visibility, "_entry", lambda fn, *args: fn)
    assert np.array_equal(direct.codes, viewshed(t, obs, radius=2000.0, height=1.0).codes)

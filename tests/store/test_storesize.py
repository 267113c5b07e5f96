"""`info`'s size report: bytes per component, and the DEFLATE + predictor GeoTIFF reference."""

from __future__ import annotations

import json
import os
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

import geoterrain
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.store.size import component_bytes, size_report
from tests.conftest import write_tif
from tests.store.storesql import read_table, update_blob

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def _int_dem(tmp_path):
    rng = np.random.default_rng(5)
    z = np.cumsum(rng.integers(-3, 4, (90, 77)), axis=1) + 300
    z[:4, :9] = -32768
    return write_tif(tmp_path / "d.tif", z.astype(np.int16), nodata=-32768)


# The store format's blob kinds by their number (a blob key's low 3 bits; stores hold the
# numbers, geoterrain/store/keys.py never renumbers them), and the size report's component
# of each, written out here so that the check below borrows nothing from the code it checks.
_KIND_OF_CODE = {0: "heights", 1: "delta", 2: "radius", 3: "normals", 4: "delta_edge",
                 5: "block_delta"}
_COMPONENT_OF_KIND = {"heights": "heights", "delta": "delta", "delta_edge": "delta",
                      "block_delta": "delta", "radius": "radius", "normals": "normals"}


def _component_bytes_by_sql(store) -> tuple[dict[str, int], dict[str, int]]:
    """Bytes per component read from the store's SQLite file (read-only): each blob row's
    ``LENGTH(data)`` summed by the kind its key in the tile table names; ``index/other`` is
    the file (page size × page count) less every blob row, whatever its key. Also the bytes
    per blob kind, to show which kinds the store holds."""
    con = sqlite3.connect(f"{Path(store).resolve().as_uri()}?mode=ro", uri=True)
    try:
        sizes = dict(con.execute("SELECT id, LENGTH(data) FROM blobs"))
        (blob_total,) = con.execute("SELECT SUM(LENGTH(data)) FROM blobs").fetchone()
        (page_size,) = con.execute("PRAGMA page_size").fetchone()
        (page_count,) = con.execute("PRAGMA page_count").fetchone()
        (catalog_bytes,) = con.execute("SELECT SUM(LENGTH(data)) FROM catalog").fetchone()
        table = read_table(con)
    finally:
        con.close()
    by_kind: dict[str, int] = {}
    ids = table.ids.tolist()
    for key, rowid in zip(table.blobs.tolist(), ids, strict=True):
        kind = _KIND_OF_CODE[key & 7]
        by_kind[kind] = by_kind.get(kind, 0) + sizes[rowid]
    # every blob row is one key's, counted once
    assert sorted(ids) == sorted(sizes) and len(set(ids)) == len(ids)
    file_bytes = page_size * page_count
    assert file_bytes == os.path.getsize(store)
    out = dict.fromkeys(("heights", "delta", "radius", "normals"), 0)
    for kind, n in by_kind.items():
        out[_COMPONENT_OF_KIND[kind]] += n
    out["index/other"] = file_bytes - blob_total
    assert out["index/other"] > catalog_bytes > 0  # the catalog's rows are index/other's
    return out, by_kind


def test_components_are_the_blob_bytes_of_their_kinds(tmp_path):
    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    want, by_kind = _component_bytes_by_sql(store)
    # the store holds every kind (the padded 90×77 grid has second δs; block δ_n always),
    # so that each kind's attribution is checked
    assert set(by_kind) == set(_KIND_OF_CODE.values()), by_kind
    assert all(v > 0 for v in by_kind.values()), by_kind
    with geoterrain.open(store) as t:
        got = component_bytes(t)
        report = size_report(t)
    assert got == want and all(v > 0 for v in got.values()), (got, want)
    assert report["components"] == want
    assert report["store_bytes"] == sum(want.values()) == os.path.getsize(store)


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_reference_is_the_source_written_with_deflate_and_predictor(tmp_path):
    dem = _int_dem(tmp_path)
    store = preprocess(dem, tmp_path / "d.geoterrain")
    # the same heights written here independently: same bytes as the report's reference
    with rasterio.open(dem) as s:
        data = s.read(1)
    prof = dict(driver="GTiff", height=90, width=77, count=1, dtype="int16", nodata=-32768,
                compress="deflate", predictor=2)
    with rasterio.open(tmp_path / "ref.tif", "w", **prof) as d:
        d.write(data, 1)
    with geoterrain.open(store) as t:
        r = size_report(t)
    assert r["geotiff_dtype"] == "int16"
    assert r["geotiff_deflate_bytes"] == os.path.getsize(tmp_path / "ref.tif")
    assert r["ratio"] == r["store_bytes"] / r["geotiff_deflate_bytes"]


def test_info_prints_the_size_line(tmp_path):
    from geoterrain.cli.main import cli

    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    res = CliRunner().invoke(cli, ["info", str(store), "--reference"])
    assert res.exit_code == 0, res.output
    line = next(ln for ln in res.output.splitlines() if ln.startswith("size "))
    assert "heights" in line and "normals" in line and "× the DEFLATE+predictor GeoTIFF" in line
    # by default info decodes no tile (it answers at once: issue 51) and says how to compare
    for args in ([], ["--no-reference"]):
        res = CliRunner().invoke(cli, ["info", str(store), *args])
        line = next(ln for ln in res.output.splitlines() if ln.startswith("size "))
        assert res.exit_code == 0 and "--reference compares" in line, res.output
    res = CliRunner().invoke(cli, ["info", str(store), "--json"])
    i = json.loads(res.output)
    assert "ratio" not in i["size"] and sum(i["size"]["components"].values()) == i["size_bytes"]


def _rewrite_bounds_v1(store, tmp_path):
    """A copy of ``store`` whose δ and r blobs use version 1 (all samples, float16):
    the layout stores written before the size levers hold."""
    import shutil
    import sqlite3

    import zstandard

    from geoterrain.bounds.vertexdata import encode_bounds
    from geoterrain.store.schema import blob_crc

    old = tmp_path / "old.geoterrain"
    shutil.copy(store, old)
    with geoterrain.open(store) as t:
        vals = {(k, kind): (t.tile_delta if kind == "delta" else t.tile_radius)(*k)
                for k in t.tile_info for kind in ("delta", "radius")}
    cctx = zstandard.ZstdCompressor(level=3)
    con = sqlite3.connect(old)
    for (k, kind), a in vals.items():
        blob = encode_bounds(a, cctx)
        update_blob(con, (*k, kind), data=blob, crc32=blob_crc(k, kind, blob))
    con.commit()
    con.close()
    return old, vals


def test_stores_with_version_1_bounds_stay_readable(tmp_path):
    from geoterrain.core.view import View

    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    old, vals = _rewrite_bounds_v1(store, tmp_path)
    with geoterrain.open(old) as t:
        for (k, kind), a in vals.items():
            b = (t.tile_delta if kind == "delta" else t.tile_radius)(*k)
            assert (b >= a).all() and (b <= a * (1 + 2.0**-10) + 1e-30).all()
        lo, hi = t.scene_box()
        view = View(tuple(hi + (hi - lo)), tuple((lo + hi) / 2), size=(640, 360))
        assert t.select(view, 1.0).stats["triangles"] > 0


def test_new_vertices_only_blobs_are_smaller_and_exact(tmp_path):
    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain")
    old, vals = _rewrite_bounds_v1(store, tmp_path)
    with geoterrain.open(store) as t, geoterrain.open(old) as o:
        new, before = component_bytes(t), component_bytes(o)
        # a level's shared vertices read from the parent equal the parent's own values
        g = t.grid
        for (L, x, y) in t.tile_info:
            if L < g.top_level:
                p = t.tile_delta(L + 1, x // 2, y // 2)
                h = (g.tile_samples - 1) // 2
                sub = p[(y % 2) * h:(y % 2) * h + h + 1, (x % 2) * h:(x % 2) * h + h + 1]
                assert np.array_equal(t.tile_delta(L, x, y)[::2, ::2], sub)
    assert new["delta"] < 0.75 * before["delta"] and new["radius"] < before["radius"]


def test_stored_bounds_are_never_below_the_exact_ones(tmp_path):
    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.bounds.log8codes import LOG_STEPS
    from geoterrain.bounds.radii import vertex_radii

    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain", tile_size=16,
                       root_grid=False)  # the square's arrays (root grids: test_root_grid.py)
    with geoterrain.open(store) as t:
        g = t.grid
        X, Y = t.frame.grid_xy(g.size)
        h, v = t.level_heights(0)
        Z = np.where(v, t.frame.z(h), np.nan)
        D, R = vertex_errors(Z, v), vertex_radii(X, Y, Z, v)
        for (L, x, y) in t.tile_info:
            ix = np.ix_(g.tile_rows(L, y), g.tile_cols(L, x))
            d, r = t.tile_delta(L, x, y), t.tile_radius(L, x, y)
            assert (d >= D[ix]).all() and (r >= R[ix]).all(), (L, x, y)
            fin = np.isfinite(D[ix])
            # 8-bit log codes: at most one step (2^(1/16)) above, plus the smallest code
            assert (d[fin] <= D[ix][fin] * 2 ** (1 / LOG_STEPS) * (1 + 1e-6) + 2e-4).all()
            info = t.tile_info[(L, x, y)]
            new = np.ones(d.shape, bool)
            if L < g.top_level:
                new[::2, ::2] = False
            assert info["delta_max"] == d[new].max() and info["radius_max"] == r[new].max()
        # r's codes are the smallest that hold both bounds: r ≥ the exact radius, and
        # nesting on the coded values, r(v) ≥ |p_v − p_c| + r(c)
        _assert_minimal_radius_codes(t, X, Y, Z, v, R)


def _assert_minimal_radius_codes(t, X, Y, Z, valid, R):
    """The stored r of every tile against the coded nesting recomputed here in numpy,
    group by group fine to coarse: code(v) = the smallest code ≥ |p_v − p_c| +
    table[code(c)] for each child c (positions as vertex_radii's)."""
    from geoterrain.bounds.log8codes import log8_codes, log8_table
    from geoterrain.bounds.radii import _proxy_positions
    from geoterrain.core.bintree import vertex_children, vertex_depth

    g = t.grid
    e = int(np.int8(np.uint8(t._blob((g.top_level, 0, 0), "radius")[2])))
    table = log8_table(e).astype(np.float64)
    xp, yp, zp = _proxy_positions(np.asarray(X, float), np.asarray(Y, float), Z, valid)
    # a projected frame nests from leaves of radius 0 (the exact radii are no input);
    # a geographic one also covers the radii raised by the curvilinear terms
    R = R if t.frame.kind == "geographic" else np.zeros_like(R)
    code = log8_codes(R, e)  # leaves and corners: their own radius
    i, j = (a.ravel() for a in np.indices((g.size, g.size)))
    keep = vertex_depth(i, j, g.n) >= 0
    i, j = i[keep], j[keep]
    h = np.bitwise_and(i | j, -(i | j))
    centre = ((i // h) % 2 == 1) & ((j // h) % 2 == 1)
    for hh in 1 << np.arange(g.n):
        for grp in (~centre, centre):  # edge midpoints of h first, then its centres
            m = grp & (h == hh)
            vi, vj = i[m], j[m]
            need = R[vi, vj].astype(np.float64)
            ch = vertex_children(vi, vj, g.n)
            for c in range(4):
                ci, cj = ch[:, c, 0], ch[:, c, 1]
                ok = ci >= 0
                a, b = (vi[ok], vj[ok]), (ci[ok], cj[ok])
                d = np.sqrt((xp[a] - xp[b]) ** 2 + (yp[a] - yp[b]) ** 2 + (zp[a] - zp[b]) ** 2)
                need[ok] = np.maximum(need[ok], d + table[code[b]])
            code[vi, vj] = log8_codes(need, e)
    want = log8_table(e)[code]
    for L, x, y in t.tile_info:
        ix = np.ix_(g.tile_rows(L, y), g.tile_cols(L, x))
        assert np.array_equal(t.tile_radius(L, x, y), want[ix]), (L, x, y)


def test_stored_normals_are_each_level_s_normal_map(tmp_path):
    """Normals read back through the store's layout (rings and derived interiors) equal
    the normal map of each level's own samples, octahedral-coded."""
    from geoterrain.bounds.normals import decode_octahedral, encode_octahedral, normal_map
    from geoterrain.core.grid import level_tiles

    store = preprocess(_int_dem(tmp_path), tmp_path / "d.geoterrain", tile_size=16,
                       root_grid=False)  # the square's arrays
    with geoterrain.open(store) as t:
        g = t.grid
        assert t.meta["normals_layout"] == 2
        X, Y = t.frame.grid_xy(g.size)
        h, v = t.level_heights(0)
        Z = np.where(v, t.frame.z(h), np.nan)
        levels = [normal_map(X[::1 << L, ::1 << L], Y[::1 << L, ::1 << L],
                             Z[::1 << L, ::1 << L], v[::1 << L, ::1 << L])
                  for L in range(g.top_level + 1)]
        for (L, x, y) in t.tile_info:
            want = level_tiles(encode_octahedral(levels[L], 8), g.t, 0)[y, x]
            assert np.array_equal(t.tile_normals(L, x, y), decode_octahedral(want, 8))

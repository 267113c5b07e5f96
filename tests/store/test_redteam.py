"""The red-team list of issue "a store from a stranger is safe to open", rerun as tests.

Each case: exactly one `Error:` line, the right exit code, no traceback, no
"internal error", and no file left behind in the folder.
"""

from __future__ import annotations

import json
import shutil
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from geoterrain.cli.main import cli
from geoterrain.ingest.synth import generate, write_geotiff

sys.path.insert(0, str(Path(__file__).parent))
from storefuzz import _meta_rewrite, zstd_bomb  # noqa: E402
from storesql import all_tiles, blob_keys, delete_blob, delete_tile, read_blob, update_blob  # noqa: E402

from geoterrain.store.schema import blob_crc  # noqa: E402

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("red")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 65, seed=7))
    return dem, geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16)


def _sql(store, *stmts):
    con = sqlite3.connect(store)
    for s in stmts:
        con.execute(s)
    con.commit()
    con.close()


def _meta(field, value, group=None):
    def f(store):
        con = sqlite3.connect(store)

        def edit(m):
            (m if group is None else m[group])[field] = value
        _meta_rewrite(con, edit)
        con.commit()
        con.close()
    return f


def _bomb(store, magic=True):
    con = sqlite3.connect(store)
    k = max(blob_keys(con, "heights"))  # the top tile's
    old = read_blob(con, k)[0]
    data = old[:3] + zstd_bomb(16 << 30, 8, magic)  # the 3-byte header, then a frame
    update_blob(con, k, data=data, crc32=blob_crc(k[:3], "heights", data))
    con.commit()
    con.close()


def _swap_heights(store):
    con = sqlite3.connect(store)
    a, b = [k for k in blob_keys(con, "heights") if k[0] == 0][:2]
    update_blob(con, a, data=read_blob(con, b)[0])
    con.commit()
    con.close()


def _south_up(store):
    """A south-up transform in the metadata (checksums recomputed): every reader would
    draw the terrain mirrored, so it is refused."""
    con = sqlite3.connect(store)

    def edit(m):
        a, b, c, d, e, f = m["frame"]["transform"]
        m["frame"]["transform"] = [a, b, c, d, -e, f + e * m["frame"]["rows"]]
    _meta_rewrite(con, edit)
    con.commit()
    con.close()


def _swap_delta(level):
    """Two tiles' δ blobs of one level swapped, their checksums recomputed for their new
    places: the bound would be wrong for both tiles."""
    def f(store):
        con = sqlite3.connect(store)
        a, b = [k for k in blob_keys(con, "delta") if k[0] == level][:2]
        da, db = read_blob(con, a)[0], read_blob(con, b)[0]
        update_blob(con, a, data=db, crc32=blob_crc(a[:3], "delta", db))
        update_blob(con, b, data=da, crc32=blob_crc(b[:3], "delta", da))
        con.commit()
        con.close()
    return f


def _delete(store, blob=None, tiles=None):
    con = sqlite3.connect(store)
    if blob is not None:
        delete_blob(con, blob)
    for k in list(all_tiles(con)) if tiles else ():
        if tiles(k):
            delete_tile(con, k)
    con.commit()
    con.close()


# (id, how to damage a copy of the store or None, argv with {store} {dem} {d}, exit code)
STORE_CASES = [
    ("missing-blob", lambda s: _delete(s, blob=(0, 1, 1, "delta")), ["info", "{store}"], 1),
    ("deleted-tile-rows", lambda s: _delete(s, tiles=lambda k: k[0] == 0 and sum(k) % 2 == 0),
     ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("swapped-heights", _swap_heights, ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("z-scale-0", _meta("z_scale", 0, "frame"), ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("z-scale-neg", _meta("z_scale", -1, "frame"), ["info", "{store}"], 1),
    ("frame-kind", _meta("kind", "warped", "frame"), ["info", "{store}"], 1),
    ("step-x10", _meta("step", 10.0, "quantizer"), ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("grid-n-16", _meta("n", 16, "grid"), ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("recursive-catalog-view", lambda s: _sql(
        s, "ALTER TABLE catalog RENAME TO c0",
        "CREATE VIEW catalog AS WITH RECURSIVE c(n) AS (SELECT 1 UNION ALL SELECT n+1 FROM c) "
        "SELECT n AS id, x'00' AS data, 0 AS crc32 FROM c"), ["info", "{store}"], 1),
    ("endless-blobs-view", lambda s: _sql(
        s, "ALTER TABLE blobs RENAME TO b0",
        "CREATE VIEW blobs AS WITH RECURSIVE c(n) AS (SELECT 1 UNION ALL SELECT n+1 FROM c) "
        "SELECT x'00' AS data, 0 AS crc32 FROM c"),
     ["render", "{store}", "-o", "{d}/r.png"], 1),
    ("trigger", lambda s: _sql(s, "CREATE TRIGGER t AFTER INSERT ON catalog BEGIN SELECT 1; END"),
     ["info", "{store}"], 1),
    ("zstd-bomb", _bomb, ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("zstd-bomb-magicless", lambda s: _bomb(s, magic=False),
     ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("escape-in-metadata", _meta("schema_version", "\x1b[31mred"), ["info", "{store}"], 1),
    ("old-schema", _meta("schema_version", 1), ["info", "{store}"], 1),
    ("schema-8-frames-with-magic", _meta("schema_version", 8), ["info", "{store}"], 1),
    ("schema-9-frames-with-magic", _meta("schema_version", 9), ["info", "{store}"], 1),
    ("schema-10-r-centres-stored", _meta("schema_version", 10), ["info", "{store}"], 1),
    ("schema-11-r-centres-stored", _meta("schema_version", 11), ["info", "{store}"], 1),
    ("schema-12-bounds-not-predicted", _meta("schema_version", 12), ["info", "{store}"], 1),
    ("schema-13-bounds-not-predicted", _meta("schema_version", 13), ["info", "{store}"], 1),
    ("schema-14-tile-table-unpredicted", _meta("schema_version", 14), ["info", "{store}"], 1),
    ("schema-15-tile-table-unpredicted", _meta("schema_version", 15), ["info", "{store}"], 1),
    ("schema-16-tile-table-unpredicted", _meta("schema_version", 16), ["info", "{store}"], 1),
    ("schema-17-r-and-delta-not-guessed", _meta("schema_version", 17),
     ["info", "{store}"], 1),
    ("schema-18-r-and-delta-not-guessed", _meta("schema_version", 18),
     ["info", "{store}"], 1),
    ("schema-19-r-and-delta-not-guessed", _meta("schema_version", 19),
     ["info", "{store}"], 1),
    ("schema-20-frame-with-aeqd", _meta("schema_version", 20), ["info", "{store}"], 1),
    ("schema-21-frame-with-aeqd", _meta("schema_version", 21), ["info", "{store}"], 1),
    ("schema-22-frame-with-aeqd", _meta("schema_version", 22), ["info", "{store}"], 1),
    ("schema-26-a-newer-store", _meta("schema_version", 26), ["info", "{store}"], 1),
    ("frame-holds-aeqd-wkt", _meta("aeqd_wkt", "PROJCRS[\"x\"]", "frame"), ["info", "{store}"],
     1),
    ("ring-residual-not-true", _meta("normals_ring_residual", 1), ["info", "{store}"], 1),
    ("south-up", _south_up, ["info", "{store}"], 1),
    ("unit-to-m-1e-300", _meta("unit_to_m", 1e-300, "frame"), ["info", "{store}"], 1),
    ("z-to-m-unknown", _meta("z_to_m", 0.5, "frame"), ["info", "{store}"], 1),
    ("swapped-delta-level-1", _swap_delta(1), ["mesh", "{store}", "-o", "{d}/m.ply"], 1),
    ("swapped-delta-level-0-rings", _swap_delta(0),
     ["mesh", "{store}", "-o", "{d}/m.ply", "--max-error", "0"], 1),
    ("swapped-delta-view", _swap_delta(1),
     ["render", "{store}", "-o", "{d}/r.png", "--size", "64x48"], 1),
]

ARG_CASES = [
    ("pixel-error-nan", ["mesh", "{store}", "-o", "{d}/m.ply", "--look-from", "0,-90,60",
                         "--look-at", "0,0,0", "--pixel-error", "nan"], 2),
    ("max-error-nan", ["mesh", "{store}", "-o", "{d}/m.ply", "--max-error", "nan"], 2),
    ("tile-size-2^70", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--tile-size",
                        str(2**70)], 2),
    ("pixel-size-nan", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--pixel-size",
                        "nan"], 2),
    ("pixel-size-0", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--pixel-size", "0"], 2),
    # values that used to write stores no reader accepts, or end in an internal error
    ("pixel-size-1e308", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--pixel-size",
                          "1e308"], 2),
    ("z-scale-1e308", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--z-scale", "1e308"],
     2),
    ("codec-error-1e-300", ["preprocess", "{dem}", "-o", "{d}/x.geoterrain", "--codec-error",
                            "1e-300"], 2),
    ("mesh-missing-dir", ["mesh", "{store}", "-o", "{d}/no/such/m.ply"], 2),
    ("render-missing-dir", ["render", "{store}", "-o", "{d}/no/such/r.png"], 2),
    ("render-exists", ["render", "{store}", "-o", "{d}/exists.png"], 2),
    ("fps-0", ["render", "{store}", "-o", "{d}/o.gif", "--orbit", "3", "--fps", "0"], 2),
    ("fps-nan", ["render", "{store}", "-o", "{d}/o.gif", "--orbit", "3", "--fps", "nan"], 2),
    ("webm", ["render", "{store}", "-o", "{d}/o.webm", "--orbit", "3"], 2),
]


def _run(argv, d: Path, code: int) -> None:
    before = set(d.iterdir())
    r = CliRunner().invoke(cli, ["-q", *argv])
    out = r.output
    assert r.exit_code == code, out
    errors = [ln for ln in out.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1, out  # (click prefixes usage errors with its Usage: line)
    assert "Traceback" not in out and "internal error" not in out
    assert all(c.isprintable() for c in errors[0]), errors[0]
    assert set(d.iterdir()) == before, set(d.iterdir()) - before


@pytest.mark.parametrize("damage,argv,code", [c[1:] for c in STORE_CASES],
                         ids=[c[0] for c in STORE_CASES])
def test_damaged_store(base, tmp_path, damage, argv, code):
    store = tmp_path / "s.geoterrain"
    shutil.copyfile(base[1], store)
    damage(store)
    _run([a.format(store=store, dem=base[0], d=tmp_path) for a in argv], tmp_path, code)


@pytest.mark.parametrize("argv,code", [c[1:] for c in ARG_CASES], ids=[c[0] for c in ARG_CASES])
def test_bad_request(base, tmp_path, argv, code):
    store = tmp_path / "s.geoterrain"
    shutil.copyfile(base[1], store)
    dem = tmp_path / "dem.tif"
    shutil.copyfile(base[0], dem)
    (tmp_path / "exists.png").write_bytes(b"keep")
    _run([a.format(store=store, dem=dem, d=tmp_path) for a in argv], tmp_path, code)
    assert (tmp_path / "exists.png").read_bytes() == b"keep"


def test_bad_cameras(base, tmp_path):
    store = tmp_path / "s.geoterrain"
    shutil.copyfile(base[1], store)
    for cams in ([{"look_from": [0, -90, 60], "look_at": [0, 0, 0], "up": [0, 0, 0]}],
                 [{"look_from": [0, -90, 60], "look_at": [0, 0, 0], "fov": "wide"}]):
        p = tmp_path / "c.json"
        p.write_text(json.dumps(cams))
        _run(["render", str(store), "-o", str(tmp_path / "f.gif"), "--path", str(p)],
             tmp_path, 1)  # a bad cameras file is bad input (exit 1)


def test_south_up_matches_north_up(tmp_path):
    """A south-up raster (positive row step) gives the same mesh as its north-up twin."""
    import rasterio
    from rasterio.transform import from_origin

    z = generate("fbm", 33, seed=2).astype(np.float32)
    north = tmp_path / "n.tif"
    south = tmp_path / "s.tif"
    kw = dict(driver="GTiff", height=33, width=33, count=1, dtype="float32", crs="EPSG:32633")
    tn = from_origin(500000, 4000000, 30, 30)
    with rasterio.open(north, "w", transform=tn, **kw) as f:
        f.write(z, 1)
    ts = rasterio.Affine(30, 0, 500000, 0, 30, 4000000 - 33 * 30)
    with rasterio.open(south, "w", transform=ts, **kw) as f:
        f.write(z[::-1], 1)
    a = geoterrain.open(geoterrain.preprocess(north))
    b = geoterrain.open(geoterrain.preprocess(south))
    ma, mb = a.mesh(0.0), b.mesh(0.0)
    assert np.array_equal(ma.points, mb.points) and np.array_equal(ma.faces, mb.faces)
    nz = ma.compute_normals(cell_normals=True, point_normals=False).cell_data["Normals"][:, 2]
    assert (nz > 0).all()  # every triangle faces up


def test_random_rgb_png_is_refused(tmp_path):
    import imageio.v3 as iio

    png = tmp_path / "noise.png"
    iio.imwrite(png, np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8))
    _run(["preprocess", str(png), "-o", str(tmp_path / "n.geoterrain")], tmp_path, 1)


def test_undeclared_voids_become_nodata(tmp_path, caplog):
    import rasterio
    from rasterio.transform import from_origin

    z = (generate("fbm", 33, seed=4) + 100).astype(np.int16)
    z[5:9, 5:12] = -32768
    p = tmp_path / "v.tif"
    with rasterio.open(p, "w", driver="GTiff", height=33, width=33, count=1, dtype="int16",
                       crs="EPSG:32633", transform=from_origin(0, 0, 30, 30)) as f:
        f.write(z, 1)
    with caplog.at_level("WARNING", logger="geoterrain"):
        t = geoterrain.open(geoterrain.preprocess(p))
    assert "--nodata" in caplog.text
    assert t.meta["valid_samples"] == 33 * 33 - 28 and t.meta["height_range"][0] > -1000
    t2 = geoterrain.open(geoterrain.preprocess(p, tmp_path / "keep.geoterrain", nodata=float("nan"),
                                               z_scale=1.0))
    assert t2.meta["valid_samples"] == 33 * 33  # --nodata nan keeps them as heights


def test_latitudes_beyond_90_are_refused(tmp_path):
    import rasterio
    from rasterio.transform import from_origin

    p = tmp_path / "geo.tif"
    with rasterio.open(p, "w", driver="GTiff", height=33, width=33, count=1, dtype="float32",
                       crs="EPSG:4326", transform=from_origin(10, 95, 0.01, 0.01)) as f:
        f.write(generate("fbm", 33, seed=1).astype(np.float32), 1)
    _run(["preprocess", str(p), "-o", str(tmp_path / "g.geoterrain")], tmp_path, 1)

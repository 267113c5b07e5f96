"""The command line: bad input gets one line and the right exit code, never a traceback."""

import json
import os
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

import geoterrain.store.writer
from tests.conftest import write_tif

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def run(*args):
    # imported here: geoterrain.cli is the top-level cli/ folder, mapped into the package
    # on install, so import sorters disagree on where it belongs among the imports
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def assert_one_line_error(res, code):
    assert res.exit_code == code, res.output
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("Error:"), res.stderr
    assert "Traceback" not in res.output


def test_help_and_version():
    res = run("--help")
    assert res.exit_code == 0 and "preprocess" in res.output and "info" in res.output
    assert run("--version").output.strip().endswith("0.1.0")
    assert "Examples" in run("preprocess", "--help").output


def test_preprocess_and_info(fbm_tif, tmp_path):
    out = tmp_path / "a.geoterrain"
    res = run("-q", "preprocess", fbm_tif, "-o", out)
    assert res.exit_code == 0 and out.exists()
    res = run("info", out)
    assert res.exit_code == 0, res.output
    assert "EPSG" in res.output or "UTM" in res.output
    res = run("info", out, "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["grid"] == [129, 129]


@pytest.mark.parametrize("whole", [False, True])
def test_info_gives_a_geographic_store_in_degrees_and_names_the_globe(tmp_path, whole):
    """A geographic store's extent is its box in degrees (a whole globe is 360° × 180°, not
    metres on a plane), and one that the flat scene cannot show says to use --globe."""
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", 65, seed=1)[:32, :64] * 0.1).astype(np.float32)
    spacing, origin = (5.625, (-180.0, 90.0)) if whole else (1 / 1200, (139.0, 36.0))
    dem = write_tif(tmp_path / "g.tif", z, crs="EPSG:4326", origin=origin, spacing=spacing)
    out = tmp_path / "g.geoterrain"
    assert run("-q", "preprocess", dem, "-o", out).exit_code == 0
    info = json.loads(run("info", out, "--json").output)
    lon, lat = (360.0, 180.0) if whole else (64 / 1200, 32 / 1200)
    assert info["extent_deg"]["lon"][1] - info["extent_deg"]["lon"][0] == pytest.approx(lon)
    assert info["extent_deg"]["lat"][1] - info["extent_deg"]["lat"][0] == pytest.approx(lat)
    assert (info["flat_problem"] is not None) == whole
    text = run("info", out).output
    assert (f"{lon:.6g}° × {lat:.6g}°" in text) and (("--globe" in text) == whole), text


def test_stored_normals_keeps_every_normal_map_whole(fbm_tif, tmp_path):
    """`preprocess --stored-normals` writes full normal maps (no derived levels) with the
    codes the default store derives, and a larger file."""
    import geoterrain

    a, b = tmp_path / "ring.geoterrain", tmp_path / "whole.geoterrain"
    assert run("-q", "preprocess", fbm_tif, "-o", a).exit_code == 0
    assert run("-q", "preprocess", fbm_tif, "-o", b, "--stored-normals").exit_code == 0
    with geoterrain.open(a) as ring, geoterrain.open(b) as whole:
        assert ring.meta["normals_derived"] == list(range(ring.grid.top_level + 1))
        assert "normals_derived" not in whole.meta
        for key in whole.tile_info:
            assert np.array_equal(ring.tile_normal_codes(*key), whole.tile_normal_codes(*key))
    assert b.stat().st_size > a.stat().st_size


def test_default_output_name(tmp_path, fbm_tif):
    res = run("-q", "preprocess", fbm_tif)
    assert res.exit_code == 0
    assert fbm_tif.with_suffix(".geoterrain").exists()


@pytest.mark.parametrize("case,code", [
    ("missing", 1), ("directory", 1), ("text", 1), ("multiband", 2), ("1x1", 1), ("1xN", 1),
    ("all-nodata", 1), ("all-nan", 1), ("inf", 1), ("absurd", 1), ("exists", 2),
    ("read-only", 1), ("bad-tile-size", 2), ("bad-band", 2), ("bad-codec-error", 2),
    ("old-max-error", 2),
])
def test_bad_input(case, code, tmp_path, fbm_tif):
    src, extra = tmp_path / "in.tif", []
    out = tmp_path / "out.geoterrain"
    if case == "missing":
        src = tmp_path / "nope.tif"
    elif case == "directory":  # a folder is a mosaic of its rasters: this one has none
        src = tmp_path / "folder"
        src.mkdir()
        (src / "notes.txt").write_text("no DEM here")
    elif case == "text":
        src.write_text("not a raster\n")
    elif case == "multiband":
        with rasterio.open(src, "w", driver="GTiff", width=4, height=4, count=2,
                           dtype="int16") as d:
            d.write(np.zeros((2, 4, 4), np.int16))
    elif case == "1x1":
        write_tif(src, np.zeros((1, 1), np.int16))
    elif case == "1xN":
        write_tif(src, np.zeros((1, 50), np.int16))
    elif case == "all-nodata":
        write_tif(src, np.full((5, 5), -1, np.int16), nodata=-1)
    elif case == "all-nan":
        write_tif(src, np.full((5, 5), np.nan, np.float32))
    elif case == "inf":
        z = np.zeros((5, 5), np.float32)
        z[1, 1] = np.inf
        write_tif(src, z)
    elif case == "absurd":
        write_tif(src, np.full((5, 5), 3e5, np.float32))
    elif case == "exists":
        src = fbm_tif
        out.write_text("x")
    elif case == "read-only":
        src = fbm_tif
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        # a read-only directory, or /proc where permissions do not bind (root)
        out = ro / "out.geoterrain" if not os.access(ro, os.W_OK) else \
            Path("/proc/geoterrain-test.geoterrain")
    elif case == "bad-tile-size":
        src, extra = fbm_tif, ["--tile-size", "48"]
    elif case == "bad-band":
        src, extra = fbm_tif, ["--band", "3"]
    elif case == "bad-codec-error":
        src, extra = fbm_tif, ["--codec-error", "-1"]
    elif case == "old-max-error":  # renamed: the message says so
        src, extra = fbm_tif, ["--max-error", "0.5"]
    res = run("-q", "preprocess", src, "-o", out, *extra)
    if case in ("bad-tile-size",):
        assert res.exit_code == 2 and "Traceback" not in res.output
    else:
        assert_one_line_error(res, code)
    if case == "old-max-error":
        assert "--codec-error" in res.output
    out = Path(out)
    if case == "exists":
        assert out.read_text() == "x"  # left as it was
    else:
        assert not out.exists()
    # and nothing else was left behind: no partial store next to the output, no store
    # (partial or not) anywhere else, e.g. at the default path next to the DEM
    assert not [p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]
    assert not [p.name for p in tmp_path.rglob("*") if p != out and "geoterrain" in p.name]


def test_absurd_heights_pass_with_z_scale(tmp_path):
    src = write_tif(tmp_path / "in.tif", np.full((5, 5), 3e5, np.float32))
    assert run("-q", "preprocess", src, "--z-scale", "1").exit_code == 0


def test_disk_full_is_one_line(tmp_path, fbm_tif, monkeypatch):
    def full(self):
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(geoterrain.store.writer.StoreWriter, "_init", full)
    res = run("-q", "preprocess", fbm_tif, "-o", tmp_path / "o.geoterrain")
    assert_one_line_error(res, 1)
    assert "disk full" in res.stderr
    assert list(tmp_path.glob("*geoterrain*")) == []


def test_info_on_damaged_or_missing_store(tmp_path):
    assert_one_line_error(run("info", tmp_path / "none.geoterrain"), 1)
    p = tmp_path / "x.geoterrain"
    p.write_bytes(b"\0" * 100)
    assert_one_line_error(run("info", p), 1)


def test_synth_writes_deterministic_geotiff(tmp_path):
    a, b = tmp_path / "a.tif", tmp_path / "b.tif"
    assert run("synth", "ridged", "--size", "33", "--seed", "4", "-o", a).exit_code == 0
    assert run("synth", "ridged", "--size", "33", "--seed", "4", "-o", b).exit_code == 0
    with rasterio.open(a) as da, rasterio.open(b) as db:
        assert da.crs is not None
        np.testing.assert_array_equal(da.read(1), db.read(1))
    assert_one_line_error(run("synth", "fbm", "--size", "9", "-o", a), 2)


def test_mesh_command(tmp_path, fbm_tif):
    import pyvista as pv

    store = tmp_path / "s.geoterrain"
    assert run("-q", "preprocess", fbm_tif, "-o", store).exit_code == 0
    ply = tmp_path / "m.ply"
    res = run("mesh", store, "-o", ply, "--max-error", "5")
    assert res.exit_code == 0, res.output
    assert "triangles" in res.output and "height error ≤ 5 m" in res.output
    assert not res.output.lstrip().startswith("{")  # words, not JSON
    res = run("mesh", store, "-o", ply, "--max-error", "5", "--overwrite", "--json")
    assert json.loads(res.stdout)["triangles"] > 2
    assert pv.read(ply).n_cells > 2
    vtp = tmp_path / "v.vtp"
    res = run("mesh", store, "-o", vtp, "--look-from", "0,-1500,1500", "--look-at", "0,0,500",
              "--pixel-error", "2", "--strategy", "chunked")
    assert res.exit_code == 0, res.output
    m = pv.read(vtp)
    assert "grid_ij" in m.point_data and "skirt" in m.cell_data
    assert_one_line_error(run("mesh", store, "-o", tmp_path / "x.abc"), 2)
    assert_one_line_error(run("mesh", store, "-o", ply, "--max-error", "1"), 2)  # exists
    assert_one_line_error(run("mesh", store, "-o", tmp_path / "y.ply", "--look-from", "1,2,3"), 2)
    assert run("mesh", store, "-o", tmp_path / "z.ply", "--look-from", "1,2").exit_code == 2


def test_view_without_display_is_one_line(tmp_path, fbm_tif, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    store = tmp_path / "s.geoterrain"
    assert run("-q", "preprocess", fbm_tif, "-o", store).exit_code == 0
    res = run("view", store)
    assert_one_line_error(res, 1)
    assert "geoterrain render" in res.stderr


def test_the_occlusion_option_reaches_the_selection(tmp_path, fbm_tif, monkeypatch):
    """`mesh --no-occlusion` selects without horizon culling, `--occlusion` with it: the
    choice is the selection's argument, nothing left behind in the process."""
    from geoterrain.lod import rtin

    store = tmp_path / "s.geoterrain"
    assert run("-q", "preprocess", fbm_tif, "-o", store).exit_code == 0
    seen = []
    real = rtin.select

    def spy(*a, **k):
        seen.append(k["occlusion"])
        return real(*a, **k)

    monkeypatch.setattr(rtin, "select", spy)
    look = ["--look-from", "0,-1500,1500", "--look-at", "0,0,500", "--pixel-error", "2"]
    for k, flag in enumerate(("--no-occlusion", "--occlusion")):
        res = run("mesh", store, "-o", tmp_path / f"{k}.vtp", *look, flag)
        assert res.exit_code == 0, res.output
    assert seen == [False, True]


# values that ended in an internal error, wrote stores no reader accepts, or were taken
# silently (issue 49): each is one line and exit 2 now, before any work
BAD_VALUES = [
    ("preprocess", "--codec-error", "1e-300"),
    ("preprocess", "--pixel-size", "1e308"),
    ("preprocess", "--z-scale", "1e308"),
    ("preprocess", "--nodata", "inf"),
    ("preprocess", "--tile-size", "3"),
    ("render", "--azimuth", "nan"),
    ("render", "--distance", "0"),
    ("render", "--distance", "nan"),
    ("render", "--distance", "1e308"),
    ("render", "--distance", "-1"),
    ("render", "--fov", "nan"),
    ("render", "-z", "1e308"),
    ("render", "--drape-opacity", "nan"),
    ("render", "--sun", "400,50"),
    ("render", "--pixel-error", "1e9"),
    ("render", "--look-from", "nan,0,0"),
    ("render", "--title", "a\x1b[31mred"),
    ("render", "--fps", "inf"),
    ("mesh", "--max-error", "-1"),
    ("export", "--print-size", "nan"),
    ("tiles", "--max-error", "inf"),
]


@pytest.mark.parametrize("command,option,value", BAD_VALUES,
                         ids=[f"{c}{o}={v}" for c, o, v in BAD_VALUES])
def test_every_value_is_checked(tmp_path, fbm_tif, command, option, value):
    store = tmp_path / "s.geoterrain"
    store.write_bytes(b"")  # never read: the value is refused first
    out = {"preprocess": "x.geoterrain", "render": "v.png", "mesh": "m.ply",
           "export": "e.stl", "tiles": "t"}[command]
    src = fbm_tif if command == "preprocess" else store
    res = run("-q", command, src, "-o", tmp_path / out, option, value)
    assert_one_line_error(res, 2)
    assert not (tmp_path / out).exists()


def test_long_and_undecodable_names_are_one_line(tmp_path, fbm_tif):
    long_name = tmp_path / ("n" * 300 + ".geoterrain")
    assert_one_line_error(run("-q", "preprocess", fbm_tif, "-o", long_name), 2)
    deep = tmp_path / "/".join(["d" * 200] * 25) / "x.geoterrain"
    assert_one_line_error(run("-q", "preprocess", fbm_tif, "-o", deep), 2)
    # names that are not UTF-8 (as Python hands them over: surrogate escapes), which GDAL
    # and SQLite cannot take: refused in one line, as input and as output
    raw = os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xff\xfe.tif")
    Path(raw).write_bytes(fbm_tif.read_bytes())
    res = run("-q", "preprocess", raw, "-o", tmp_path / "u.geoterrain")
    assert_one_line_error(res, 1)
    assert "UTF-8" in res.stderr and not (tmp_path / "u.geoterrain").exists()
    res = run("-q", "preprocess", fbm_tif, "-o",
              os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xfa.geoterrain"))
    assert_one_line_error(res, 2)
    assert_one_line_error(run("-q", "info", os.fsdecode(b"/nonexistent/\xff.geoterrain")), 1)


def test_a_photo_is_not_a_dem_unless_named_raw(tmp_path):
    from PIL import Image

    photo = tmp_path / "holiday.jpg"
    rgb = (np.random.default_rng(0).random((64, 80, 3)) * 255).astype(np.uint8)
    Image.fromarray(rgb).save(photo, quality=90)
    res = run("-q", "preprocess", photo, "-o", tmp_path / "p.geoterrain", "--band", "1")
    assert_one_line_error(res, 1)
    assert "picture" in res.stderr and "--encoding raw" in res.stderr
    res = run("-q", "preprocess", photo, "-o", tmp_path / "p.geoterrain", "--band", "1",
              "--encoding", "raw", "--pixel-size", "1")
    assert res.exit_code == 0, res.output


def test_library_warnings_are_one_line(tmp_path):
    """A PNG without georeference says so in geoterrain's words, not rasterio's
    NotGeoreferencedWarning with a site-packages path."""
    from PIL import Image

    png = tmp_path / "h.png"
    Image.fromarray((np.arange(64 * 64).reshape(64, 64) % 251).astype(np.uint8)).save(png)
    res = run("preprocess", png, "-o", tmp_path / "h.geoterrain")
    assert res.exit_code == 0, res.output
    assert "site-packages" not in res.stderr and "NotGeoreferenced" not in res.stderr


def test_bench_inputs_are_checked_before_any_work(tmp_path, fbm_tif):
    """Found by the CLI fuzzer: bench --path FIFO blocked forever, and an over-long
    SOURCE or --cache-dir name ended in an internal error."""
    os.mkfifo(tmp_path / "fifo")
    res = run("-q", "bench", fbm_tif, "--path", tmp_path / "fifo",
              "--cache-dir", tmp_path / "c")
    assert_one_line_error(res, 2)
    assert "FIFO" in res.stderr
    long_name = tmp_path / ("n" * 300)
    assert_one_line_error(run("-q", "bench", long_name), 2)
    assert_one_line_error(run("-q", "bench", fbm_tif, "--cache-dir", long_name), 2)
    assert not (tmp_path / "c").exists()
@pytest.mark.fast
def test_edit_command(tmp_path):
    """`geoterrain edit`: a patch placed by its georeference or --at, the summary line,
    the edit in `info`, and one-line errors (exit 2 for the command line, 1 for data)."""
    import numpy as np

    from geoterrain.ingest.synth import generate, write_geotiff

    z = np.rint(generate("fbm", 65, seed=3))
    dem = write_geotiff(tmp_path / "d.tif", z, spacing=10.0)
    assert run("-q", "preprocess", dem, "--tile-size", "16").exit_code == 0
    store = tmp_path / "d.geoterrain"
    # a cut of 5 × 6 samples whose top-left corner is row 10, column 20 of the DEM
    cut = write_geotiff(tmp_path / "cut.tif", np.full((5, 6), -12.0),
                        origin=(500000.0 + 20 * 10, 5000000.0 - 10 * 10), spacing=10.0)
    res = run("edit", store, "--patch", cut, "--mode", "add")
    assert res.exit_code == 0 and "changed 30 samples in rows 10 … 14, columns 20 … 25" \
        in res.output, res.output
    with geoterrain.open(store) as t:
        assert t.tile(0, 1, 0).heights[10 - 0, 20 - 16] == z[10, 20] - 12
    assert "edits        1" in run("info", store).output
    res = run("edit", store, "--patch", cut, "--mode", "add", "--at", "0,0")
    assert res.exit_code == 0 and "rows 0 … 4, columns 0 … 5" in res.output
    frac = write_geotiff(tmp_path / "frac.tif", np.full((2, 2), 0.25), spacing=10.0)
    assert_one_line_error(run("edit", store, "--patch", frac, "--at", "1,1"), 1)
    assert run("edit", store, "--patch", frac, "--at", "1,1", "--round").exit_code == 0
    assert_one_line_error(run("edit", store, "--patch", cut, "--at", "900,900"), 1)
    # a name the system cannot look up (ENAMETOOLONG): one line, not an internal error
    res = run("edit", store, "--patch", str(tmp_path / ("a" * 300 + ".tif")))
    assert_one_line_error(res, 1)
    assert "internal error" not in res.stderr
    res = run("edit", store, "--patch", cut, "--at", "x")  # click's usage error
    assert res.exit_code == 2 and "ROW,COL" in res.output and "Traceback" not in res.output
    assert_one_line_error(run("edit", tmp_path / "none.geoterrain", "--patch", cut), 1)


def test_help_texts_are_in_a_users_words():
    """No --help names a seed document (their numbers belong to the strategy docs), `view
    --help` says where the cached store goes and lists every key, and the level-of-detail
    option speaks of pixels, not τ."""
    import re

    from geoterrain.cli.main import COMMANDS

    texts = {c: run(c, "--help").output for c in COMMANDS}
    texts["geoterrain"] = run("--help").output
    for name, text in texts.items():
        assert not re.search(r"seed\s*\d{3}|seed 0|HAM\b|\bLP\b", text), name
        assert "δ" not in text and "τ" not in text, name
    view = " ".join(texts["view"].split())
    assert "~/.cache/geoterrain" in view and "next to it" not in view
    for key in ("m ", "+ / -", "g ", "x ", "c ", "space", "s ", "t ", "h ", "q "):
        assert f"  {key}" in texts["view"], key
    assert "pixels" in texts["render"] and "TAU" not in texts["render"]


def test_mesh_and_export_with_the_tin_mesher(fbm_tif, tmp_path):
    """`--mesher tin`: a whole-terrain TIN (fewer triangles than rtin's at the same
    --max-error); with a view, or an unknown mesher, one line and exit 2."""
    import pyvista as pv

    fbm_store = tmp_path / "f.geoterrain"
    assert run("-q", "preprocess", fbm_tif, "-o", fbm_store).exit_code == 0
    a, b = tmp_path / "rtin.ply", tmp_path / "tin.ply"
    assert run("-q", "mesh", fbm_store, "-o", a, "--max-error", "2").exit_code == 0
    res = run("mesh", fbm_store, "-o", b, "--max-error", "2", "--mesher", "tin", "--json")
    assert res.exit_code == 0, res.output
    stats = json.loads(res.output)
    assert stats["mesher"] == "tin" and stats["triangles"] == pv.read(b).n_cells
    assert pv.read(b).n_cells < pv.read(a).n_cells
    c = tmp_path / "tinfull.ply"
    res = run("mesh", fbm_store, "-o", c, "--max-error", "2", "--mesher", "tin-full", "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["mesher"] == "tin-full"
    assert pv.read(c).n_cells < pv.read(b).n_cells  # every point tried: fewer triangles
    glb = tmp_path / "tin.glb"
    assert run("-q", "export", fbm_store, "-o", glb, "--max-error", "2", "--mesher",
               "tin").exit_code == 0 and glb.stat().st_size > 0
    assert_one_line_error(run("mesh", fbm_store, "-o", tmp_path / "v.ply", "--mesher", "tin",
                              "--look-from", "0,-900,500", "--look-at", "0,0,0"), 2)
    assert_one_line_error(run("mesh", fbm_store, "-o", tmp_path / "x.ply", "--max-error", "1",
                              "--mesher", "delaunay"), 2)
    assert not (tmp_path / "v.ply").exists() and not (tmp_path / "x.ply").exists()

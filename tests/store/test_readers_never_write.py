"""Readers never write beside a store: every reading command leaves the store's folder
byte-identical (names, bytes and modification times), a store in SQLite's WAL mode
included; a store whose hot journal or write-ahead log holds changes is refused in one
line (reading it right would need to write)."""

from __future__ import annotations

import os
import shutil
import sqlite3

import pytest

import geoterrain
from geoterrain.exceptions import StoreError
from geoterrain.ingest.synth import generate, write_geotiff
from tests.test_cli import assert_one_line_error, run

pytestmark = pytest.mark.fast


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    d = tmp_path_factory.mktemp("ro")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 33, seed=4))
    return geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16)


def _folder(d) -> dict:
    return {p.name: (p.read_bytes(), os.stat(p).st_mtime_ns, os.stat(p).st_mode)
            for p in sorted(d.iterdir())}


READERS = [
    ["info", "{s}"],
    ["info", "{s}", "--json"],
    ["mesh", "{s}", "-o", "{o}/m.ply"],
    ["mesh", "{s}", "-o", "{o}/v.vtp", "--look-from", "0,-400,300", "--look-at", "0,0,0"],
    ["export", "{s}", "-o", "{o}/e.glb", "--texture-size", "16"],
    ["export-raster", "{s}", "--what", "hillshade", "-o", "{o}/h.tif"],
    ["tiles", "{s}", "-o", "{o}/tiles", "--max-zoom", "2"],
    ["render", "{s}", "-o", "{o}/r.png", "--size", "64x48"],
]


@pytest.mark.parametrize("mode", ["plain", "wal", "read-only folder"])
def test_readers_leave_the_folder_as_it_was(pristine, tmp_path, mode):
    d, out = tmp_path / "stores", tmp_path / "out"
    d.mkdir()
    out.mkdir()
    s = d / "s.geoterrain"
    shutil.copyfile(pristine, s)
    if mode == "wal":  # converted by SQLite itself; closing removes the -wal and -shm
        con = sqlite3.connect(s)
        assert con.execute("PRAGMA journal_mode=WAL").fetchone()[0] == "wal"
        con.close()
        assert s.read_bytes()[18:20] == b"\x02\x02"  # the header says WAL
    before = _folder(d)
    if mode == "read-only folder":
        d.chmod(0o555)
    try:
        for argv in READERS:
            res = run("-q", *[a.format(s=s, o=out) for a in argv])
            assert res.exit_code == 0, (argv, res.output)
        with geoterrain.open(s) as t:
            t.select(geoterrain.View((0, -400, 300), (0, 0, 0), size=(64, 48)), 2.0)
    finally:
        d.chmod(0o755)
    assert _folder(d) == before


@pytest.mark.parametrize("side", ["-wal", "-journal"])
def test_a_store_with_pending_changes_is_refused(pristine, tmp_path, side):
    s = tmp_path / "s.geoterrain"
    shutil.copyfile(pristine, s)
    (tmp_path / f"s.geoterrain{side}").write_bytes(b"\0" * 4096)
    before = _folder(tmp_path)
    res = run("-q", "info", s)
    assert_one_line_error(res, 1)
    assert side in res.stderr
    with pytest.raises(StoreError, match="changes"):
        geoterrain.open(s)
    assert _folder(tmp_path) == before
    (tmp_path / f"s.geoterrain{side}").write_bytes(b"")  # an empty one holds nothing
    assert run("-q", "info", s).exit_code == 0


@pytest.mark.parametrize("what", ["fifo", "device", "directory", "loop"])
def test_a_store_that_is_not_a_file_is_named_so(tmp_path, what):
    p = tmp_path / "s.geoterrain"
    if what == "fifo":
        os.mkfifo(p)
    elif what == "device":
        p = "/dev/zero"
    elif what == "directory":
        p.mkdir()
    else:
        p.symlink_to(tmp_path / "s2.geoterrain")
        (tmp_path / "s2.geoterrain").symlink_to(p)
    res = run("-q", "info", p)
    assert_one_line_error(res, 2 if what == "directory" else 1)  # Click's Path type: usage
    assert {"fifo": "FIFO", "device": "character device", "directory": "directory",
            "loop": "symbolic link loop"}[what] in res.stderr

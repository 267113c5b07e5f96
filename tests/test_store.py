"""The store is complete and valid, or absent; damage gives a clear error."""

import os
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest

import geoterrain
from geoterrain.exceptions import StoreCorruptError, StoreError, UsageError, WriteError
from geoterrain.store import StoreReader, StoreWriter


def test_incomplete_temp_file_is_never_a_valid_store(tmp_path):
    dst = tmp_path / "a.geoterrain"
    w = StoreWriter(dst)
    w.put_blob((0, 0, 0), "heights", b"abc")
    w.con.execute("COMMIT")  # as if killed after data but before commit()
    assert not dst.exists()
    with pytest.raises(StoreError, match="incomplete"):
        StoreReader(w.tmp)


def test_failure_mid_write_leaves_nothing(tmp_path, fbm_tif, monkeypatch):
    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(StoreWriter, "put_tiles", boom)
    dst = tmp_path / "s.geoterrain"
    with pytest.raises(OSError):
        geoterrain.preprocess(fbm_tif, dst)
    assert not dst.exists()
    assert list(tmp_path.glob(".*partial*")) == []


def test_kill_mid_write_leaves_no_valid_store(tmp_path):
    from geoterrain.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "big.tif", generate("fbm", 1025, seed=2))
    dst = tmp_path / "k.geoterrain"
    code = ("import geoterrain, geoterrain.store as s, time\n"
            "orig = s.StoreWriter.put_blobs\n"
            "def slow(self, *a):\n    orig(self, *a); time.sleep(30)\n"
            "s.StoreWriter.put_blobs = slow\n"
            f"geoterrain.preprocess({str(src)!r}, {str(dst)!r})\n")
    p = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.time() + 120
    while time.time() < deadline and not list(tmp_path.glob(".*partial*")):
        time.sleep(0.2)
    time.sleep(1.0)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert not dst.exists()
    for f in tmp_path.glob(".*partial*"):  # a leftover temp file must not open as a store
        with pytest.raises(StoreError):
            StoreReader(f)


def test_flipped_byte_in_blob_gives_clear_error(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    con = sqlite3.connect(dst)
    data, = con.execute("SELECT data FROM blobs WHERE level=0 AND x=0 AND y=0 "
                        "AND kind='heights'").fetchone()
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0x10
    con.execute("UPDATE blobs SET data=? WHERE level=0 AND x=0 AND y=0 AND kind='heights'",
                (bytes(bad),))
    con.commit()
    con.close()
    t = geoterrain.open(dst)
    with pytest.raises(StoreCorruptError, match="damaged"):
        t.tile(0, 0, 0)


def test_flipped_byte_anywhere_never_gives_wrong_heights(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    good = geoterrain.open(dst).scene_xyz()[2]
    raw = bytearray(dst.read_bytes())
    rng = np.random.default_rng(0)
    for pos in rng.integers(100, len(raw), 25):
        bad = bytearray(raw)
        bad[pos] ^= 0xFF
        p = tmp_path / f"bad{pos}.geoterrain"
        p.write_bytes(bytes(bad))
        try:
            z = geoterrain.open(p).scene_xyz()[2]
        except StoreError:
            continue
        np.testing.assert_array_equal(z, good)  # either an error or the right heights


def test_existing_destination_needs_overwrite(tmp_path, fbm_tif):
    dst = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with pytest.raises(UsageError, match="overwrite=True") as exc:
        geoterrain.preprocess(fbm_tif, dst)
    assert "--overwrite" in exc.value.cli  # the command line's words, for the CLI
    geoterrain.preprocess(fbm_tif, dst, overwrite=True)


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_read_only_directory(tmp_path, fbm_tif):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(WriteError):
        geoterrain.preprocess(fbm_tif, ro / "s.geoterrain")


def test_not_a_store(tmp_path):
    p = tmp_path / "x.geoterrain"
    p.write_text("hello")
    with pytest.raises(StoreError, match="not a geoterrain store"):
        StoreReader(p)


def test_missing_tile_is_a_clear_store_error(tmp_path, fbm_tif):
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    with geoterrain.open(store) as t:
        with pytest.raises(StoreError, match="not stored"):
            t.tile(0, 999, 999)
        key = t.tile_keys(0)[0]
    con = sqlite3.connect(store)  # a blob row lost from a store that lists the tile
    con.execute("DELETE FROM blobs WHERE level=? AND x=? AND y=? AND kind='heights'", key)
    con.commit()
    con.close()
    with pytest.raises(StoreCorruptError, match="missing"):  # caught on open
        geoterrain.open(store)

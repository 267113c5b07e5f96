"""Helpers of the edit tests: small DEMs, their edits done by hand, and the oracle, a
store preprocessed from the edited DEM, compared with the edited store.

Two stores are the same when every blob, tile row and metadata entry is (but the
timings, the edit log and the source's name); the height blobs may differ in bytes where
a preprocess of the edited DEM chose the other predictor (the edit keeps the store's,
``preprocessing/edit/whole.py``), and then their valid masks and the decoded codes of
their valid samples must be the same (an invalid sample holds its predictor's guess).
"""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rasterio

import geoterrain
from geoterrain.codec.pyramid.layout import _parse
from tests.store.storesql import all_blobs, all_tiles, read_meta

IGNORED = ("edits",)  # a fresh preprocess has no edit log


def write_dem(path: Path, z: np.ndarray, nodata: float | None = None,
              geographic: bool = False) -> Path:
    """A UTM GeoTIFF of ``z`` (float32), 10 m pixels, or with ``geographic`` an EPSG:4326
    one of 3″ pixels near 35.5° N; NaN cells become ``nodata``."""
    H, W = z.shape
    tr = (rasterio.transform.from_origin(138.5, 35.5, 1 / 1200, 1 / 1200) if geographic
          else rasterio.transform.from_origin(500000, 5000000, 10, 10))
    z = np.asarray(z, np.float32)
    if nodata is not None:
        z = np.where(np.isnan(z), np.float32(nodata), z)
    with rasterio.open(path, "w", driver="GTiff", height=H, width=W, count=1, dtype="float32",
                       crs="EPSG:4326" if geographic else "EPSG:32633", transform=tr,
                       nodata=nodata) as ds:
        ds.write(z, 1)
    return Path(path)


def integer_dem(seed: int, rows: int, cols: int, holes: float = 0.0) -> np.ndarray:
    """A rough integer-valued DEM (the integer quantizer, whatever the edit), NaN voids."""
    rng = np.random.default_rng(seed)
    z = rng.normal(0, 20, (rows, cols)).cumsum(0).cumsum(1) / 8 + rng.normal(0, 3, (rows, cols))
    z = np.rint(z + 500.0)
    if holes:
        blob = rng.random((rows, cols)) < holes
        # voids in runs, as real ones are
        blob |= np.roll(blob, 1, 0) | np.roll(blob, 1, 1)
        z[blob] = np.nan
    return z


def apply_by_hand(z: np.ndarray, row: int, col: int, patch: np.ndarray, mode: str
                  ) -> np.ndarray:
    """The edited DEM, computed plainly (the oracle's input)."""
    out = z.copy()
    H, W = z.shape
    for i in range(patch.shape[0]):
        for j in range(patch.shape[1]):
            r, c = row + i, col + j
            if not (0 <= r < H and 0 <= c < W) or np.isnan(patch[i, j]):
                continue
            old = z[r, c]
            if mode == "replace":
                out[r, c] = patch[i, j]
            elif np.isnan(old):
                continue
            elif mode == "add":
                out[r, c] = old + patch[i, j]
            elif mode == "min":
                out[r, c] = min(old, patch[i, j])
            else:
                out[r, c] = max(old, patch[i, j])
    return out


def _content(path) -> tuple[dict, dict, dict]:
    con = sqlite3.connect(path)
    try:
        return all_blobs(con), all_tiles(con), read_meta(con)
    finally:
        con.close()


def assert_same_store(edited: Path, fresh: Path) -> None:
    """``edited`` holds what ``fresh`` holds (module docstring)."""
    (ba, ta, ma), (bb, tb, mb) = _content(edited), _content(fresh)
    assert ba.keys() == bb.keys(), sorted(set(ba) ^ set(bb))
    differ = sorted(k for k in ba if ba[k] != bb[k])
    heights = [k for k in differ if k[3] == "heights"]
    assert [k for k in differ if k[3] != "heights"] == [], \
        [k for k in differ if k[3] != "heights"][:8]
    if heights:  # only where the fresh store chose the other predictor: same codes
        top = max(k for k in ba if k[3] == "heights")
        assert _parse(ba[top])[3] != _parse(bb[top])[3], heights[:5]
        with geoterrain.open(edited) as a, geoterrain.open(fresh) as b:
            for L, x, y, _ in heights:
                one, two = a.tile(L, x, y), b.tile(L, x, y)
                assert np.array_equal(one.valid, two.valid)
                # an invalid sample keeps its predictor's prediction: only valid ones
                assert np.array_equal(one.codes[one.valid], two.codes[two.valid])
    assert ta == tb, sorted(k for k in ta if ta[k] != tb.get(k))[:5]
    for k in IGNORED:
        ma.pop(k, None)
        mb.pop(k, None)
    assert ma == mb, {k: (ma.get(k), mb.get(k)) for k in set(ma) | set(mb)
                      if ma.get(k) != mb.get(k)}


@contextmanager
def paused_at_commit(script: str, ready: Path, *args: str) -> Iterator[None]:
    """Run ``script`` (an edit that writes ``ready`` and sleeps at its commit) in a child
    process with ``args``; inside the block the child is paused there, its pages in the
    file; on leaving it is SIGKILLed."""
    proc = subprocess.Popen([sys.executable, "-c", script, *args], cwd=os.getcwd())
    try:
        for _ in range(600):
            if ready.exists() or proc.poll() is not None:
                break
            time.sleep(0.1)
        assert ready.exists(), "the edit never reached its commit"
        yield
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()


#: The start of a child script for :func:`paused_at_commit`: the store editor's connection
#: spills every page it changes to the file (a one-page cache) and, at its commit, writes
#: ``sys.argv[2]`` and sleeps; the script goes on with its own patches and edit.
SLOW_COMMIT = """\
import sys, time, numpy as np, geoterrain
import geoterrain.store.editor as E
real = E.StoreEditor._apply
class Slow:  # the editor's connection, pausing at its commit
    def __init__(self, con):
        self.con = con
    def execute(self, sql, *a):
        if sql == "COMMIT":
            open(sys.argv[2], "w").close()
            time.sleep(60)
        return self.con.execute(sql, *a)
    def executemany(self, sql, *a):
        return self.con.executemany(sql, *a)
    def close(self):
        self.con.close()
def apply(self, *a):
    # every page the edit changes goes to the file before the commit (a small cache
    # spills them): the store is damaged until the journal is rolled back
    self.con.execute("PRAGMA cache_size=1")
    self.con = Slow(self.con)
    return real(self, *a)
E.StoreEditor._apply = apply
"""


def random_patch(kind: str, h: int, w: int, seed: int, mode: str) -> np.ndarray:
    """An (h, w) patch for ``mode``: ``const`` (one height, below the data for add/min,
    above it otherwise), ``rough`` (normal noise, rounded), ``holes`` (rough with 30 %
    NaN: samples the patch leaves alone)."""
    rng = np.random.default_rng(seed)
    if kind == "const":
        p = np.full((h, w), -37.0 if mode in ("add", "min") else 640.0)
    else:
        p = np.rint(rng.normal(0 if mode == "add" else 500, 40, (h, w)))
    if kind == "holes":
        p[rng.random((h, w)) < 0.3] = np.nan
    return p

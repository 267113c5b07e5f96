"""Opening a store reads O(1) pages besides its catalog, and ``bytes_read`` is every byte
read from the store file, as the operating system counts them."""

import math
import os
import shutil
import sqlite3
import subprocess
import sys
import textwrap

import pytest

import geoterrain
from geoterrain import lod
from geoterrain.core import osreads
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.store.schema import PAGE_SIZE, SMALL_PAGE_SIZE

needs_counters = pytest.mark.skipif(not osreads.EXACT, reason="no per-thread I/O counters")


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    d = tmp_path_factory.mktemp("openreads")
    return {n: geoterrain.preprocess(write_geotiff(d / f"f{n}.tif", generate("fbm", n, seed=1)),
                                     d / f"f{n}.geoterrain") for n in (129, 513)}


def _process_rchar() -> tuple[int, int]:
    # the whole process's count, and what this look itself read (counted after it)
    with open("/proc/self/io", "rb", buffering=0) as fh:
        text = fh.read()
    return int(text.split(b"\n")[0].split()[1]), len(text)


def _page_size(path) -> int:
    con = sqlite3.connect(path)
    try:
        return con.execute("PRAGMA page_size").fetchone()[0]
    finally:
        con.close()


def _catalog_pages(path) -> int:
    # pages that hold the catalog's two rows (a row's first page and its overflow pages,
    # each overflow page holding page size - 4 bytes of it), by the file's own numbers
    con = sqlite3.connect(path)
    try:
        sizes = [n for (n,) in con.execute("SELECT LENGTH(data) FROM catalog")]
    finally:
        con.close()
    return sum(1 + math.ceil(n / (_page_size(path) - 4)) for n in sizes)


def test_small_grids_get_small_pages(stores):
    """The 129² store (16 641 samples) is written with 512-byte pages, the 513² one with
    1 kB pages (database.page_size_for)."""
    assert (_page_size(stores[129]), _page_size(stores[513])) == (SMALL_PAGE_SIZE, PAGE_SIZE)


def test_the_small_page_threshold_takes_srtm3_not_fuji():
    """512-byte pages up to 3 · 2^16 samples: srtm3's 359 × 367 grid (72 704 → 72 192 B)
    gets them, Fuji's 512 × 512 (356 352 B; 361 984 at 512 B) does not
    (docs/lab/store-size.md, re-priced 2026-12-07)."""
    from geoterrain.store.schema import SMALL_GRID, page_size_for

    assert page_size_for(359, 367) == page_size_for(1, SMALL_GRID) == SMALL_PAGE_SIZE
    assert page_size_for(512, 512) == page_size_for(1, SMALL_GRID + 1) == PAGE_SIZE


@needs_counters
def test_opening_reads_a_constant_number_of_pages_besides_the_catalog(stores):
    """Both stores' openings read the catalog and the same few pages (the schema, the
    header, one root-to-leaf path per rowid bound); the whole blob table's leaf pages (a
    scan of the rowids, 130 kB on the 513² store) would fail this."""
    extra = {}
    for n, path in stores.items():
        t = geoterrain.open(path)
        try:
            assert t.bytes_read == t.open_bytes > 0
            extra[n] = t.open_bytes - _page_size(path) * _catalog_pages(path)
        finally:
            t.close()
    # bytes: the 129² store's 512-byte pages make its B-tree a level deeper (11 of its
    # pages, 5.8 kB, against the 513² store's 7 pages of 1 kB)
    assert max(extra.values()) <= 8 * PAGE_SIZE, extra
    assert os.path.getsize(stores[513]) > 10 * os.path.getsize(stores[129])


@needs_counters
def test_bytes_read_is_what_the_process_read(stores):
    """Over a selection that reads tiles, the process's own count (``/proc/self/io``) grows
    by the terrain's ``bytes_read`` and the counters' looks, nothing else."""
    path = stores[513]
    lo, hi = geoterrain.open(path).scene_box()
    c = 0.5 * (lo + hi)
    view = View((float(lo[0]), float(lo[1]), float(hi[2]) + 2000.0),
                (float(c[0]), float(c[1]), float(c[2])), size=(320, 200))
    with geoterrain.open(path) as warm:  # kernels loaded, modules imported
        lod.select(warm, view, 1.0)
        warm.tile(0, 0, 0)
    t = geoterrain.open(path)
    try:
        b0, p0 = t.bytes_read, t.reader.meter.probes
        r0 = _process_rchar()
        sel = lod.select(t, view, 1.0)
        tiles = [t.tile(*k) for k in t.tile_keys(0)[:5]]
        r1 = _process_rchar()
        read, probes = t.bytes_read - b0, t.reader.meter.probes - p0
        assert sel.stats["triangles"] > 0 and len(tiles) == 5 and read > 0
        assert r1[0] - r0[0] - r0[1] == read + probes
    finally:
        t.close()


@needs_counters
def test_a_frame_counts_the_opening_and_then_its_own_reads(stores, tmp_path):
    from geoterrain.rendering.scene import TerrainScene, default_view
    from geoterrain.rendering.window import pyvista_plotter

    t = geoterrain.open(stores[129])
    p = pyvista_plotter((160, 100))
    try:
        scene = TerrainScene(p, t)
        lo, hi = t.scene_box()
        eye = (float(hi[0]) + 50.0, 0.0, float(hi[2]) + 100.0)
        away = View(eye, (eye[0] + 1000.0, 0.0, eye[2] + 200.0), size=(160, 100))
        _, s1 = scene.frame(away)
        assert s1["tiles_decoded"] == 0 and s1["bytes_read"] == t.bytes_read >= t.open_bytes
        _, s2 = scene.frame(default_view(t, (160, 100)))
        assert s2["tiles_decoded"] > 0 and s1["bytes_read"] + s2["bytes_read"] == t.bytes_read
    finally:
        p.close()
        t.close()


_TRACED = textwrap.dedent("""
    import sys, geoterrain
    from geoterrain import lod
    from geoterrain.core.view import View
    t = geoterrain.open(sys.argv[1])
    lo, hi = t.scene_box()
    lod.select(t, View((float(lo[0]), float(lo[1]), float(hi[2]) + 2000.0),
                       tuple(float(v) for v in 0.5 * (lo + hi)), size=(320, 200)), 1.0)
    print(t.bytes_read)
""")


@needs_counters
@pytest.mark.skipif(shutil.which("strace") is None, reason="no strace")
def test_bytes_read_equals_what_strace_counts(stores, tmp_path):
    """The independent count: every read of the store file's descriptor, summed by strace,
    in a process that opens the store and selects a view."""
    path = str(stores[513])
    log = tmp_path / "trace"
    r = subprocess.run(["strace", "-f", "-y", "-e", "trace=read,pread64,readv,preadv",
                        "-o", str(log), sys.executable, "-c", _TRACED, path],
                       capture_output=True, text=True, timeout=600)
    if r.returncode != 0 and "ptrace" in r.stderr:
        pytest.skip("ptrace not permitted here")
    assert r.returncode == 0, r.stderr[-2000:]
    reads = [line for line in log.read_text().splitlines() if f"<{path}>" in line]
    counted = sum(int(line.rsplit("=", 1)[1]) for line in reads)
    assert counted == int(r.stdout.split()[-1]) > 0


def test_opening_and_info_load_no_compiler(stores):
    """`geoterrain info` answers at once: opening a store and its summary import neither
    numba nor VTK (the decoders load where a tile is read)."""
    code = ("import sys, geoterrain\n"
            "t = geoterrain.open(sys.argv[1]); t.info()\n"
            "print(*(m in sys.modules for m in ('numba', 'vtkmodules', 'pyvista')))\n"
            "t.tile(0, 0, 0)\n"
            "print('numba' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code, str(stores[129])], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["False", "False", "False", "True"]

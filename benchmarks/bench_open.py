"""Time opening a store and checking its tile table (what every command does first), and
count the bytes opening and a render read from the store file.

    python benchmarks/bench_open.py STORE [--repeat N] [--reads] [--size W H]

Prints the median and the fastest of N runs in this process of
``StoreReader(STORE).tiles()`` (the schema and metadata checks, the tile table parsed,
every tile's numbers, and the blob keys checked against the tiles and the rowid range)
and of ``storecheck.check_store`` (the metadata's and every tile's rules), which
``geoterrain.open`` runs next.

``--reads`` adds, in the same run:

- the bytes read (as the operating system counts them, ``/proc/thread-self/io``) and the
  time of the blob table's rowid range as one query ``SELECT MIN(rowid), MAX(rowid)``
  (before issue 51: SQLite scans the whole table for it) and as two (now), on fresh
  connections, medians of N;
- a child process, traced by ``strace`` (every ``read``/``pread`` of the store file's
  descriptor summed), that opens the store and renders one W × H picture looking away
  from the terrain; it prints the terrain's ``open_bytes``, the frame's ``bytes_read`` and
  the terrain's ``bytes_read``, which must equal what strace counted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time

from geoterrain.core.osreads import EXACT, ReadMeter
from geoterrain.store.check import check_store
from geoterrain.store.reader import StoreReader

# the child: open, one picture looking away from the terrain (out past its +x side)
_CHILD = """
import json, sys, geoterrain
from geoterrain.core.view import View
from geoterrain.rendering.scene import render
t = geoterrain.open(sys.argv[1])
lo, hi = t.scene_box()
eye = (float(hi[0]) + 50.0, 0.5 * float(lo[1] + hi[1]), float(hi[2]) + 100.0)
away = View(eye, (eye[0] + 1000.0, eye[1], eye[2] + 200.0), size=(int(sys.argv[3]),
            int(sys.argv[4])))
s = render(t, away, sys.argv[2], colorbar=False, scale_bar=False, north_arrow=False)
print(json.dumps({"open_bytes": t.open_bytes, "frame_bytes_read": s["bytes_read"],
                  "bytes_read": t.bytes_read, "triangles": s["triangles"],
                  "tiles_decoded": s["tiles_decoded"]}))
"""


def rowid_range(store: str, repeat: int) -> None:
    """The rowid range's cost as one query and as two, on fresh connections."""
    queries = {"one query (before)": ["SELECT MIN(rowid), MAX(rowid) FROM blobs"],
               "two queries (now)": ["SELECT MIN(rowid) FROM blobs",
                                     "SELECT MAX(rowid) FROM blobs"]}
    print("| rowid range | bytes read | ms (median) |\n|---|---|---|")
    for name, sqls in queries.items():
        got, times = [], []
        for _ in range(repeat):
            con = sqlite3.connect(f"file:{store}?mode=ro", uri=True)
            con.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()  # header, schema
            m = ReadMeter()
            t0 = time.perf_counter()
            m.call(lambda: [con.execute(q).fetchone() for q in sqls])  # noqa: B023
            times.append(time.perf_counter() - t0)
            got.append(m.bytes)
            con.close()
        print(f"| {name} | {statistics.median(got):,.0f} | "
              f"{1e3 * statistics.median(times):.2f} |")


def traced_render(store: str, size: tuple[int, int]) -> None:
    """A child that opens the store and renders a view looking away, under strace."""
    if shutil.which("strace") is None:
        print("strace not found: the child's reads are not counted")
        return
    store = os.path.realpath(store)
    with tempfile.TemporaryDirectory() as d:
        log = os.path.join(d, "trace")
        r = subprocess.run(["strace", "-f", "-y", "-e", "trace=read,pread64,readv,preadv",
                            "-o", log, sys.executable, "-c", _CHILD, store,
                            os.path.join(d, "away.png"), str(size[0]), str(size[1])],
                           capture_output=True, text=True)
        if r.returncode != 0:
            print(f"the traced render failed: {r.stderr[-500:]}")
            return
        reads = [line for line in open(log).read().splitlines() if f"<{store}>" in line]
    counted = sum(int(line.rsplit("=", 1)[1]) for line in reads)
    got = json.loads(r.stdout.strip().splitlines()[-1])
    total = os.path.getsize(store)
    print(f"\nrender looking away, {size[0]}×{size[1]}: store {total:,} bytes; strace counted "
          f"{counted:,} bytes ({100 * counted / total:.3f} %) in {len(reads)} reads")
    print(f"opening {got['open_bytes']:,}; frame bytes_read {got['frame_bytes_read']:,}; "
          f"terrain bytes_read {got['bytes_read']:,}; equal to strace's count: "
          f"{got['frame_bytes_read'] == got['bytes_read'] == counted}; triangles "
          f"{got['triangles']}, tiles decoded {got['tiles_decoded']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--reads", action="store_true",
                    help="also count the bytes opening and a render looking away read")
    ap.add_argument("--size", type=int, nargs=2, default=(1280, 720), metavar=("W", "H"))
    a = ap.parse_args()
    times, checks, opened = [], [], []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        r = StoreReader(a.store)
        tiles = r.tiles()
        t1 = time.perf_counter()
        check_store(a.store, r.metadata, tiles)
        times.append(t1 - t0)
        checks.append(time.perf_counter() - t1)
        opened.append(r.bytes_read)
        r.close()
    print(f"{a.store}: {len(tiles)} tiles, open + tiles() median {statistics.median(times):.3f} s, "
          f"fastest {min(times):.3f} s; check_store median {statistics.median(checks):.3f} s, "
          f"fastest {min(checks):.3f} s ({a.repeat} runs); open + tiles() read "
          f"{statistics.median(opened):,.0f} bytes of {os.path.getsize(a.store):,}"
          + ("" if EXACT else " (blob bytes only: no per-thread I/O counters here)"))
    if a.reads:
        print()
        rowid_range(a.store, a.repeat)
        traced_render(a.store, tuple(a.size))


if __name__ == "__main__":
    main()

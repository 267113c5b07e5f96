"""Every input through the streaming preprocess (issue 45): time and peak memory against
the whole-grid preprocess, and peak memory against the raster's size.

Usage:
    python benchmarks/bench_streaming_inputs.py compare [--sizes 513,1025,2049] [--runs 3]
        [--frames projected,geographic] [--limit 1G]
    python benchmarks/bench_streaming_inputs.py mosaic [--runs 3] [--limit 1G]
        [--big 4097x2049] [--small 1025x513] [--tiles 4x2] [--passes] [--root-grid]

``compare``: a synthetic fBm GeoTIFF of each size, in a projected frame (UTM, 10 m) and
a geographic one (EPSG:4326, 1 arc-second at 47° N), preprocessed whole
(``preprocess`` with memory to spare) and streamed (``preprocess_streaming`` with the
band ``--limit`` gives, :func:`geoterrain.preprocessing.streaming.band_rows`); the two
alternate, each run a fresh process. Prints medians of the wall time and of the peak RSS
(VmHWM) and the streamed/whole ratios, and checks that the stores are the same.

``mosaic``: a geographic mosaic of ``--tiles`` SRTM-like tiles (EPSG:4326, 3 arc-seconds,
neighbours sharing their edge row or column), ``--big`` and ``--small`` in all, each
streamed under the same ``--limit`` (as a list of files), the two alternating, each run
a fresh process; prints each one's medians and the big/small ratio of the peaks (issue
45's target: within 10 %, at most 1.5 GB), and the load with every run.
``--root-grid``: each on its rectangular root grid (``root_grid=True``; the band the
limit gives the roots' extent), not on the (2^n + 1)² square.
``--passes``: each run also prints the peak RSS of each pass (VmHWM reset as the pass
starts, ``/proc/self/clear_refs``; the passes run in turn, ``sync``), the last figure
the rest of the run (the height pass and the store's writing); "before" is the RSS as
the first pass starts (imports, kernels, scan and quantizer).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

RUN = """
import json, sys, time
from geoterrain.core.memory import peak_rss
mode, dst, band = sys.argv[1], sys.argv[2], int(sys.argv[3])
src = json.loads(sys.argv[4])
roots = len(sys.argv) > 5 and sys.argv[5] == "roots"
from geoterrain.preprocessing import streaming
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.streaming import preprocess_streaming
passes, top = {}, [0.0]

def kib(field):
    with open("/proc/self/status") as fh:
        return next(int(ln.split()[1]) for ln in fh if ln.startswith(field))

def each(spec, tasks, retries=2):  # the passes in turn, the peak of each
    out = []
    for fn, args in tasks:
        passes.setdefault("before", kib("VmRSS:") / 1024)
        top[0] = max(top[0], kib("VmHWM:") / 1024)
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")  # VmHWM back to VmRSS
        out.append(fn(*args))
        passes[args[1]] = kib("VmHWM:") / 1024
    return out

if mode == "passes":
    streaming.run_tasks = each
t0 = time.perf_counter()
if mode == "whole":
    preprocess(src, dst, overwrite=True, memory_limit=1 << 50, root_grid=roots)
else:
    preprocess_streaming(src, dst, overwrite=True, band=band, root_grid=roots)
wall = time.perf_counter() - t0
if passes:
    passes["rest"] = kib("VmHWM:") / 1024
print(json.dumps({"wall": wall, "peak_mb": max(peak_rss() / 2**20, top[0], *passes.values()),
                  "passes": passes}))
"""


def load() -> str:
    with open("/proc/loadavg") as fh:
        return " ".join(fh.read().split()[:3])


def _bytes(s: str) -> int:
    units = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
    return int(float(s[:-1]) * units[s[-1].upper()]) if s[-1].upper() in units else int(s)


def child(mode: str, dst: str, band: int, src, roots: bool = False) -> dict:
    out = subprocess.run([sys.executable, "-c", RUN, mode, dst, str(band), json.dumps(src),
                          "roots" if roots else "square"],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def write(path: str, z, frame: str, origin=None, spacing=None) -> str:
    from geoterrain.ingest.synth import write_geotiff

    if frame == "geographic":
        write_geotiff(path, z, crs="EPSG:4326", origin=origin or (8.0, 47.0),
                      spacing=spacing or 1 / 3600)
    else:
        write_geotiff(path, z)
    return path


def same_store(a: str, b: str) -> bool:
    import sqlite3

    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from tests.store.storesql import all_blobs, all_tiles, read_meta

    def content(p):
        con = sqlite3.connect(p)
        try:
            m = read_meta(con)
            m.pop("preprocess_seconds", None)  # stores before issue 49 held timings
            return all_blobs(con), all_tiles(con), m
        finally:
            con.close()

    return content(a) == content(b)


def compare(a: argparse.Namespace) -> None:
    from geoterrain.ingest.synth import generate
    from geoterrain.preprocessing.streaming import band_rows

    limit = _bytes(a.limit)
    print("| frame | size | band | whole s | streamed s | ratio | whole MB | streamed MB | "
          "ratio | same store |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for frame in a.frames.split(","):
            for n in map(int, a.sizes.split(",")):
                src = write(os.path.join(d, f"{frame}{n}.tif"), generate("fbm", n, seed=7),
                            frame)
                band = band_rows(n, limit, frame == "geographic")
                runs = {"whole": [], "stream": []}
                for _ in range(a.runs):
                    for mode in runs:
                        runs[mode].append(child(mode, os.path.join(d, f"{mode}.gt"), band,
                                                src))
                ok = same_store(os.path.join(d, "whole.gt"), os.path.join(d, "stream.gt"))
                med = {m: {k: statistics.median(r[k] for r in rs) for k in ("wall", "peak_mb")}
                       for m, rs in runs.items()}
                w, s = med["whole"], med["stream"]
                print(f"| {frame} | {n}² | {band} | {w['wall']:.2f} | {s['wall']:.2f} | "
                      f"{s['wall'] / w['wall']:.2f} | {w['peak_mb']:.0f} | {s['peak_mb']:.0f} | "
                      f"{s['peak_mb'] / w['peak_mb']:.2f} | {ok} |", flush=True)


def mosaic(a: argparse.Namespace) -> None:
    from geoterrain.core.grid import Grid
    from geoterrain.ingest.synth import generate
    from geoterrain.preprocessing.streaming import band_rows

    limit = _bytes(a.limit)
    tx, ty = map(int, a.tiles.split("x"))
    deg = 3 / 3600
    peaks = {}
    mosaics, bands, dims = {}, {}, {}
    with tempfile.TemporaryDirectory() as d:
        for name in ("small", "big"):
            W, H = map(int, getattr(a, name).split("x"))
            # tx × ty tiles sharing their edges, as SRTM's: (W − 1)/tx + 1 samples a side
            tw, th = (W - 1) // tx + 1, (H - 1) // ty + 1
            files = []
            for y in range(ty):
                for x in range(tx):
                    z = generate("fbm", (th, tw), seed=10 * y + x) * 0.2 + 40 * (x + y)
                    origin = (8.0 + x * (tw - 1) * deg - deg / 2, 47.0 - y * (th - 1) * deg
                              + deg / 2)
                    files.append(write(os.path.join(d, f"{name}_{y}_{x}.tif"), z,
                                       "geographic", origin, deg))
            grid = Grid.for_shape(H, W, roots=a.root_grid)
            bands[name] = band_rows(grid.extent[1], limit, True)
            mosaics[name] = files
            dims[name] = (W, H, grid.extent)
        print(f"load before: {load()}; root grid: {a.root_grid}", flush=True)
        runs: dict[str, list[dict]] = {"small": [], "big": []}
        for r in range(a.runs):  # alternating, the order swapped every run
            for name in (("small", "big") if r % 2 == 0 else ("big", "small")):
                res = child("passes" if a.passes else "stream", os.path.join(d, f"{name}.gt"),
                            bands[name], mosaics[name], a.root_grid)
                runs[name].append(res)
                print(f"run {r} {name}: {res['wall']:.1f} s, {res['peak_mb']:.0f} MB, "
                      f"load {load()}", flush=True)
        print(f"load after: {load()}\n")
        print("| mosaic | tiles | extent | band | wall s (median) | peak MB (median) | runs |")
        print("|---|---|---|---|---|---|---|")
        for name in ("small", "big"):
            rs, band = runs[name], bands[name]
            W, H, ext = dims[name]
            wall = statistics.median(r["wall"] for r in rs)
            peak = statistics.median(r["peak_mb"] for r in rs)
            peaks[name] = peak
            each = ", ".join(f"{r['peak_mb']:.0f}" for r in rs)
            print(f"| {W}×{H} | {tx}×{ty} | {ext[0]} × {ext[1]} | {band} | {wall:.1f} "
                  f"| {peak:.0f} | {each} |", flush=True)
            for r in rs if a.passes else ():
                print("  peak MB per pass: " + ", ".join(f"{k} {v:.0f}"
                                                         for k, v in r["passes"].items()))
    print(f"\nbig/small peak: {peaks['big'] / peaks['small']:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["compare", "mosaic"])
    ap.add_argument("--sizes", default="513,1025,2049")
    ap.add_argument("--frames", default="projected,geographic")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--limit", default="1G")
    ap.add_argument("--big", default="4097x2049")
    ap.add_argument("--small", default="1025x513")
    ap.add_argument("--tiles", default="4x2")
    ap.add_argument("--passes", action="store_true",
                    help="mosaic: the peak RSS of each pass too")
    ap.add_argument("--root-grid", action="store_true",
                    help="mosaic: each on its rectangular root grid")
    a = ap.parse_args()
    compare(a) if a.what == "compare" else mosaic(a)


if __name__ == "__main__":
    main()

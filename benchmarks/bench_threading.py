"""numba's threading layers for geoterrain's compiled kernels: single-process cost, and
what a forked pool worker costs with each.

Usage:
    python benchmarks/bench_threading.py [--size 1025] [--rounds 3] [--frames 4]

Each measurement is a fresh process with ``NUMBA_THREADING_LAYER`` set (``omp``: GNU
OpenMP, numba's default here; ``workqueue``; ``tbb`` when the ``tbb`` wheel is installed,
its library put on the loader path), the layers taking turns round after round on the
same machine. A process preprocesses a ``size``² fBm DEM (after one warm-up run:
compiled kernels come from numba's cache) and renders ``frames`` views (1280×720,
--anti-aliasing fxaa, a parallel kernel of its own; the median frame), then with
``--fork`` a multiprocessing Pool(2) of the fork start method preprocesses two DEMs after
the parent's run (what aborted under GNU OpenMP before the kernels had serial twins).
Prints medians and ratios against omp.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = r"""
import json, os, sys, time
import multiprocessing as mp
import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff

d, size, frames = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
dem = os.path.join(d, f"fbm{size}.tif")
if not os.path.exists(dem):
    write_geotiff(dem, generate("fbm", size, seed=11))
out = os.path.join(d, f"s-{os.getpid()}.geoterrain")
geoterrain.preprocess(dem, out, overwrite=True)  # warm-up: kernels from the cache
runs = []
for _ in range(3):
    t0 = time.perf_counter()
    geoterrain.preprocess(dem, out, overwrite=True)
    runs.append(time.perf_counter() - t0)
import numba
layer = numba.threading_layer()
ms = []
with geoterrain.open(out) as t:
    span = 10.0 * size
    for k in range(frames + 1):
        az = 0.6 + 0.9 * k
        eye = (0.7 * span * __import__("math").cos(az), 0.7 * span * __import__("math").sin(az),
               0.35 * span)
        st = geoterrain.render(t, View(eye, (0, 0, 0), size=(1280, 720)),
                               os.path.join(d, f"f-{os.getpid()}.png"), overwrite=True,
                               anti_aliasing="fxaa")
        if k:  # the first frame compiles nothing new but warms VTK
            ms.append(st["frame_ms"])

def job(a):
    return str(geoterrain.preprocess(a[0], a[1], overwrite=True))

fork_s = None
if os.environ.get("BENCH_FORK") == "1":
    t0 = time.perf_counter()
    with mp.get_context("fork").Pool(2) as pool:
        r = pool.map_async(job, [(dem, out + f".{i}") for i in range(2)])
        r.get(timeout=600)
    fork_s = time.perf_counter() - t0
print(json.dumps({"layer": layer, "preprocess_s": sorted(runs)[1],
                  "frame_ms": sorted(ms)[len(ms) // 2], "fork_pool_s": fork_s}))
"""


def _env(layer: str) -> dict:
    env = dict(os.environ, NUMBA_THREADING_LAYER=layer)
    if layer == "tbb":  # the pip wheel puts libtbb in <prefix>/lib, off the loader path
        env["LD_LIBRARY_PATH"] = os.path.join(sys.prefix, "lib") + os.pathsep + env.get(
            "LD_LIBRARY_PATH", "")
    return env


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1025)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--layers", default="omp,workqueue,tbb")
    ap.add_argument("--fork", action="store_true",
                    help="also time a fork Pool(2) after the parent's preprocess (its "
                         "workers run the kernels' serial twins, on every layer)")
    a = ap.parse_args()
    layers = a.layers.split(",")
    res: dict[str, list[dict]] = {k: [] for k in layers}
    with tempfile.TemporaryDirectory() as d:
        for r in range(a.rounds):
            for layer in layers:
                env = _env(layer)
                if a.fork:
                    env["BENCH_FORK"] = "1"
                p = subprocess.run([sys.executable, "-c", CHILD, d, str(a.size), str(a.frames)],
                                   env=env, capture_output=True, text=True, timeout=3600)
                if p.returncode != 0:
                    print(f"{layer}: failed ({p.stderr.strip().splitlines()[-1:]})",
                          file=sys.stderr)
                    continue
                res[layer].append(json.loads(p.stdout.strip().splitlines()[-1]))
                print(f"round {r + 1} {layer}: {res[layer][-1]}", file=sys.stderr, flush=True)
    base = res.get("omp") or []
    med = {k: {f: statistics.median(x[f] for x in v) if v and v[0][f] is not None else None
               for f in ("preprocess_s", "frame_ms", "fork_pool_s")} for k, v in res.items()}
    print(f"| layer (actual) | preprocess {a.size}² (s) | × omp | frame 1280×720 fxaa (ms) "
          f"| × omp | fork Pool(2) of 2 (s) |")
    print("|---|---|---|---|---|---|")
    for k, v in res.items():
        if not v:
            print(f"| {k} | unavailable | | | | |")
            continue
        m = med[k]
        rp = m["preprocess_s"] / med["omp"]["preprocess_s"] if base else float("nan")
        rf = m["frame_ms"] / med["omp"]["frame_ms"] if base else float("nan")
        fk = f"{m['fork_pool_s']:.2f}" if m["fork_pool_s"] else "-"
        print(f"| {k} ({v[0]['layer']}) | {m['preprocess_s']:.3f} | {rp:.2f} | "
              f"{m['frame_ms']:.0f} | {rf:.2f} | {fk} |")


if __name__ == "__main__":
    main()

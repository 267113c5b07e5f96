"""The streamed geographic preprocess stage by stage (issue 45): the wide 1024 × 4096
raster on its 2 × 1 roots against the 2048² square, each pass's and each bounds stage's
CPU time, optionally with another checkout's tree alternating in the same run.

Usage:
    python benchmarks/bench_streamed_stages.py [--runs 2] [--baseline CHECKOUT]
                                               [--memory-limit 1G]

Each case is preprocessed by ``preprocess_streaming`` in a fresh process, with the band
``--memory-limit`` gives (``bench_root_grids.py streamed --geographic``'s rasters: an
fBm of 0 … 3000 m, float32, EPSG:4326 from 10° E 47° N at 3″). The child wraps the pass
functions of :mod:`geoterrain.preprocessing.passes` and the stages the bounds pass calls
(δ's and δ_edge's vertex errors and metric terms, the raise, the radii, level 0's slack,
the saturation) and prints their CPU time (``time.process_time``: every thread of the
process) and the store's sha256. ``--baseline``: every case again with that checkout's
tree first on ``PYTHONPATH`` (this interpreter), the order rotating each run. Prints one
JSON line per run and a table of medians; kernels should be compiled beforehand (a
first run of each tree compiles them: set ``NUMBA_CACHE_DIR`` to one folder for both
trees and discard that run, or run twice).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import hashlib, json, sys, time
import numpy as np
src, dst, roots, limit = sys.argv[1], sys.argv[2], sys.argv[3] == "roots", int(sys.argv[4])
import geoterrain
import geoterrain.preprocessing.passes as P
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.streaming import band_rows, preprocess_streaming
import rasterio
T = {}
calls = {}

def wrap(name, label, split=False):
    f = getattr(P, name)

    def g(*a, **k):
        n = calls.get(name, 0)
        calls[name] = n + 1
        key = label[n] if split else label
        c = time.process_time()
        try:
            return f(*a, **k)
        finally:
            T[key] = T.get(key, 0.0) + time.process_time() - c
    setattr(P, name, g)

wrap("band_vertex_errors", ("bounds: δ's vertex errors", "bounds: δ_edge's vertex errors"), True)
wrap("band_metric_terms", ("bounds: δ's metric terms", "bounds: δ_edge's metric terms"), True)
wrap("raise_delta", "bounds: δ and δ_edge raised")
wrap("band_metric_radius_codes", "bounds: radius codes")
wrap("band_leaf_slack", "bounds: level 0's slack")
for k, f in list(P.PASSES.items()):
    def g(job, f=f, k=k):
        c = time.process_time()
        try:
            return f(job)
        finally:
            T[f"{k} pass"] = T.get(f"{k} pass", 0.0) + time.process_time() - c
    P.PASSES[k] = g
with rasterio.open(src) as ds:
    H, W = ds.height, ds.width
band = band_rows(Grid.for_shape(H, W, roots=roots).extent[1], limit, True)
c0 = time.process_time()
preprocess_streaming(src, dst, overwrite=True, band=band, root_grid=roots)
T["the preprocess"] = time.process_time() - c0
T["sha256"] = hashlib.sha256(open(dst, "rb").read()).hexdigest()[:12]
T["code"] = geoterrain.__file__
print(json.dumps(T))
"""


def _size(text: str) -> int:
    units = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
    return int(float(text[:-1]) * units[text[-1].upper()]) if text[-1].isalpha() else int(text)


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=2)
    p.add_argument("--baseline", help="another checkout, run alternating (its tree first on "
                                      "PYTHONPATH)")
    p.add_argument("--memory-limit", default="1G")
    a = p.parse_args()
    import numpy as np

    from geoterrain.ingest.synth import generate, write_geotiff

    limit = _size(a.memory_limit)
    trees = [("this tree", None)] + ([("baseline", str(Path(a.baseline).resolve()))]
                                     if a.baseline else [])
    print(f"load before: {load()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_streamed_stages_") as d:
        src = {}
        for name, shape in (("wide", (1024, 4096)), ("square", (2048, 2048))):
            z = generate("fbm", shape, seed=3)
            z = 3000 * (z - z.min()) / np.ptp(z)
            src[name] = str(write_geotiff(Path(d) / f"{name}.tif", z.astype(np.float32),
                                          crs="EPSG:4326", origin=(10.0, 47.0),
                                          spacing=3 / 3600))
        cases = [(t, r) for t in trees for r in ("square", "wide")]
        out: dict = {(t[0], r): [] for t, r in cases}
        for run in range(a.runs):
            for (tname, path), raster in cases[run % len(cases):] + cases[:run % len(cases)]:
                env = dict(os.environ, PYTHONPATH=path) if path else None
                res = json.loads(subprocess.run(
                    [sys.executable, "-c", CHILD, src[raster], str(Path(d) / f"{raster}.gt"),
                     "roots" if raster == "wide" else "square", str(limit)], cwd=d, env=env,
                    check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
                out[(tname, raster)].append(res)
                print(f"run {run} {tname} {raster}: {json.dumps(res)}, load {load()}",
                      flush=True)
    print(f"\nload after: {load()}\n")
    cols = list(out)
    stages = [k for k in out[cols[0]][0] if k not in ("sha256", "code")]
    print("| stage (CPU s, medians) | " + " | ".join(f"{t}: {r}" for t, r in cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    med = {c: {s: statistics.median(x.get(s, 0.0) for x in out[c]) for s in stages}
           for c in cols}
    for s in stages:
        print(f"| {s} | " + " | ".join(f"{med[c][s]:.2f}" for c in cols) + " |")
    for t, _ in trees:
        sq, wd = med[(t, "square")]["the preprocess"], med[(t, "wide")]["the preprocess"]
        shas = {x["sha256"] for r in ("square", "wide") for x in out[(t, r)]}
        print(f"{t}: wide / square {wd / sq:.2f}× ({wd:.2f} against {sq:.2f} s); "
              f"stores {', '.join(sorted(shas))}")


if __name__ == "__main__":
    main()

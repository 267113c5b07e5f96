"""δ of a GeoTIFF read in row bands against the whole grid in memory: time, peak memory,
and the same bits.

Usage:
    python benchmarks/bench_banddelta.py DEM.tif [DEM.tif ...] [--band 256] [--runs 3]
        [--skip-whole]

Each run is a fresh process; the banded and whole-grid runs alternate. "banded" reads
the GeoTIFF through rasterio windows (GDAL's cache set to 64 MB) and keeps the
per-level arrays in scratch files (``geoterrain.banddelta``, ``geoterrain.scratch``);
"whole" reads the raster and runs
``geoterrain.bounds.vertex_errors``. Both print a SHA-256 of every level's (C, R, K)
arrays, which must agree. Peak memory is the process's VmHWM; "imports" is the VmRSS
after the imports, before any data.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

RUN = """
import hashlib, json, sys, time
import numpy as np, rasterio
from rasterio.windows import Window
from geoterrain.memory import peak_rss, current_rss
from geoterrain.banddelta import band_vertex_errors
from geoterrain.bounds import vertex_errors
from geoterrain.scratch import ScratchArrays
path, mode, band = sys.argv[1], sys.argv[2], int(sys.argv[3])
base = current_rss()
t0 = time.perf_counter()
h = hashlib.sha256()
# GDAL's block cache is set, not left at its default (5 % of RAM, counted as ours)
with rasterio.Env(GDAL_CACHEMAX=64 * 2**20), rasterio.open(path) as ds:
    N = ds.height
    nd = ds.nodata
    def rows(i0, i1):
        z = ds.read(1, window=Window(0, i0, N, i1 - i0)).astype(np.float64)
        return z, (np.isfinite(z) if nd is None else z != nd)
    if mode == "banded":
        with ScratchArrays("/tmp") as sa:
            d = band_vertex_errors(rows, N, band=band, scratch=sa)
            for k in range(d.n):  # a few rows at a time: the hash holds no level whole
                for x in "CRK":
                    nr = sa.shape(f"{x}{k}")[0]
                    for r0 in range(0, nr, 256):
                        h.update(sa.read(f"{x}{k}", r0, r0 + 256).tobytes())
    else:
        z, v = rows(0, N)
        g = vertex_errors(z, v)
        del z, v
        k = 0
        while (1 << k) < N - 1:
            hh, s = 1 << k, 2 << k
            for a in (g[hh::s, hh::s], g[hh::s, 0::s], g[0::s, hh::s]):
                h.update(np.ascontiguousarray(a).tobytes())
            k += 1
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "peak_mb": peak_rss() / 2**20, "imports_mb": base / 2**20,
                  "sha": h.hexdigest()[:16], "N": N}))
"""


def run(path: str, mode: str, band: int) -> dict:
    out = subprocess.run([sys.executable, "-c", RUN, path, mode, str(band)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dems", nargs="+")
    ap.add_argument("--band", type=int, default=256)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--skip-whole", action="store_true")
    a = ap.parse_args()
    print("| DEM | N | mode | wall s (median) | peak MB (median) | RSS after imports MB | "
          "SHA-256 of the levels |")
    print("|---|---|---|---|---|---|---|")
    for path in a.dems:
        res: dict[str, list] = {"banded": [], "whole": []}
        for _ in range(a.runs):
            for mode in ("banded",) if a.skip_whole else ("banded", "whole"):
                res[mode].append(run(path, mode, a.band))
        shas = {r["sha"] for rs in res.values() for r in rs}
        for mode, rs in res.items():
            if not rs:
                continue
            label = f"banded, {a.band} rows" if mode == "banded" else "whole grid"
            print(f"| {path.rsplit('/', 1)[-1]} | {rs[0]['N']} | {label} | "
                  f"{statistics.median(r['wall'] for r in rs):.2f} | "
                  f"{statistics.median(r['peak_mb'] for r in rs):.0f} | "
                  f"{statistics.median(r['imports_mb'] for r in rs):.0f} | {rs[0]['sha']} |")
        if len(shas) != 1:
            sys.exit(f"{path}: the banded and whole-grid levels differ: {sorted(shas)}")


if __name__ == "__main__":
    main()

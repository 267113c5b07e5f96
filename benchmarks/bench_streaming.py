"""The streaming preprocess's stages on a GeoTIFF read a window at a time, against the
whole grid in memory: time, peak memory, and the same bits.

Usage:
    python benchmarks/bench_streaming.py DEM.tif [DEM.tif ...] [--stage bounds|heights]
        [--band 256] [--runs 3] [--skip-whole]
    (--stage normals: every level's normal codes; --stage tiles: the tile table)

``--stage bounds`` (default): δ and the radius codes.
Each run is a fresh process; the banded and whole-grid runs alternate. "banded" reads
the GeoTIFF through rasterio windows (GDAL's cache set to 64 MB) and keeps the
per-level arrays in scratch files (``geoterrain.preprocessing.bands.delta``,
``geoterrain.preprocessing.bands.radii``,
``geoterrain.preprocessing.scratch``); "whole" reads the raster and runs
``geoterrain.bounds.delta.vertex_errors`` and ``geoterrain.bounds.tileblobs.radius_codes``. Both
print a SHA-256 of every level's (C, R, K) arrays of δ, then of the codes, which must
agree. x and y are the sample's column and row times its pixel size.

``--stage heights``: the height pyramid's tile blobs (lossless codes of the float32
heights, zstd level 6 as the preprocess writes them); "banded" reads super-tile windows
(``geoterrain.preprocessing.bands.codec``, the coarse grid at most 1025² codes), "whole" runs
``geoterrain.codec.pyramid.encode_pyramid``; both print a SHA-256 of the sum of every
(key, blob)'s digest. The banded run hands each super-tile's blobs to a sink that keeps
none, as a store writer would.

``--stage normals``: every level's octahedral normal codes (8 bits, the preprocess's
levels for 65² tiles); "banded" runs ``geoterrain.preprocessing.bands.normals`` on row bands,
"whole"
``normal_map``, ``normal_pyramid`` and ``encode_octahedral``; both print a SHA-256 of the
levels' codes.

``--stage tiles``: the tile table's bounds and every block's δ_n (65² tiles); "banded"
runs ``geoterrain.preprocessing.bands.tiles``, "whole" ``tilebounds.tile_and_block_errors``; both
print
a SHA-256 of the sorted table and the blocks.

Peak memory is the process's VmHWM; "imports" is the VmRSS after the imports, before
any data.
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
from geoterrain.core.memory import peak_rss, current_rss
from geoterrain.preprocessing.bands.delta import band_vertex_errors
from geoterrain.preprocessing.bands.radii import band_radius_codes
from geoterrain.bounds.delta import vertex_errors
from geoterrain.preprocessing.scratch import ScratchArrays
from geoterrain.bounds.tileblobs import radius_codes
path, mode, band, stage = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
base = current_rss()
t0 = time.perf_counter()
h = hashlib.sha256()
# GDAL's block cache is set, not left at its default (5 % of RAM, counted as ours)
with rasterio.Env(GDAL_CACHEMAX=64 * 2**20), rasterio.open(path) as ds:
    N = ds.height
    nd = ds.nodata
    xs = np.arange(N) * abs(ds.transform.a)
    ys = -np.arange(N) * abs(ds.transform.e)
    def rows(i0, i1):
        z = ds.read(1, window=Window(0, i0, N, i1 - i0)).astype(np.float64)
        return z, (np.isfinite(z) if nd is None else z != nd)
    if stage == "tiles":
        if mode == "banded":
            from geoterrain.preprocessing.bands.tiles import band_tile_bounds
            tb, blocks = band_tile_bounds(rows, N, 6, xs, ys, band=band)
        else:
            from geoterrain.bounds.tilebounds import tile_and_block_errors
            z, v = rows(0, N)
            X = np.broadcast_to(xs[None, :], (N, N))
            Y = np.broadcast_to(ys[:, None], (N, N))
            tb, blocks = tile_and_block_errors(z, v, X, Y, 6)
            del z, v
        h.update(repr(sorted(tb.items())).encode() + blocks.tobytes())
        e = len(tb)
    elif stage == "normals":
        from geoterrain.bounds.normals import encode_octahedral, normal_map, normal_pyramid
        levels = (N - 1).bit_length() - 1 - 6 + 1
        if mode == "banded":
            from geoterrain.preprocessing.bands.normals import band_normal_codes
            with ScratchArrays("/tmp") as sa:
                band_normal_codes(rows, N, xs, ys, levels, sa, band=band)
                for L in range(levels):
                    m = sa.shape(f"n{L}")[0]
                    for r0 in range(0, m, 256):
                        h.update(sa.read(f"n{L}", r0, r0 + 256).tobytes())
        else:
            z, v = rows(0, N)
            X = np.broadcast_to(xs[None, :], (N, N))
            Y = np.broadcast_to(ys[:, None], (N, N))
            for a in normal_pyramid(normal_map(X, Y, z, v), v, levels):
                h.update(encode_octahedral(a, 8).tobytes())
            del z, v
        e = levels
    elif stage == "heights":
        from geoterrain.preprocessing.bands.codec import band_encode_pyramid
        from geoterrain.codec.pyramid import encode_pyramid
        from geoterrain.codec.quantize import Quantizer
        q = Quantizer("float", 1.0, 0.0, 0.0, 32)
        if mode == "banded":
            def window(i0, i1, j0, j1):
                z = ds.read(1, window=Window(j0, i0, j1 - j0, i1 - i0)).astype(np.float64)
                return z, (np.isfinite(z) if nd is None else z != nd)
            acc = [0, 0]

            def sink(part):  # what a store writer would do: nothing kept
                for key, b in part.items():
                    d = hashlib.sha256(repr(key).encode() + b).digest()
                    acc[0] = (acc[0] + int.from_bytes(d, "big")) % 2**256
                    acc[1] += 1

            band_encode_pyramid(window, N, 6, q, level=6, sink=sink)
            total, e = acc
        else:
            z, v = rows(0, N)
            blobs = encode_pyramid(z, v, 6, q, level=6)
            del z, v
            total = 0  # order-free: the sum of each (key, blob)'s digest
            for key, b in blobs.items():
                d = hashlib.sha256(repr(key).encode() + b).digest()
                total = (total + int.from_bytes(d, "big")) % 2**256
            e = len(blobs)
        h.update(total.to_bytes(32, "big"))
    elif mode == "banded":
        with ScratchArrays("/tmp") as sa:
            d = band_vertex_errors(rows, N, band=band, scratch=sa, heights=True)
            e = band_radius_codes(sa, N, xs, ys, *d.valid_range[:2])
            for p in ("", "r"):  # a few rows at a time: the hash holds no level whole
                for k in range(d.n):
                    for x in "CRK":
                        nr = sa.shape(f"{p}{x}{k}")[0]
                        for r0 in range(0, nr, 256):
                            h.update(sa.read(f"{p}{x}{k}", r0, r0 + 256).tobytes())
    else:
        z, v = rows(0, N)
        z[~v] = np.nan
        g = vertex_errors(z, v)
        X = np.broadcast_to(xs[None, :], (N, N))
        Y = np.broadcast_to(ys[:, None], (N, N))
        c, e = radius_codes(X, Y, z, v, None)
        del z, v
        for g in (g, c):
            k = 0
            while (1 << k) < N - 1:
                hh, s = 1 << k, 2 << k
                for a in (g[hh::s, hh::s], g[hh::s, 0::s], g[0::s, hh::s]):
                    h.update(np.ascontiguousarray(a).tobytes())
                k += 1
wall = time.perf_counter() - t0
h.update(str(e).encode())
print(json.dumps({"wall": wall, "peak_mb": peak_rss() / 2**20, "imports_mb": base / 2**20,
                  "sha": h.hexdigest()[:16], "N": N}))
"""


def run(path: str, mode: str, band: int, stage: str) -> dict:
    out = subprocess.run([sys.executable, "-c", RUN, path, mode, str(band), stage],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dems", nargs="+")
    ap.add_argument("--stage", choices=("bounds", "heights", "normals", "tiles"),
                    default="bounds")
    ap.add_argument("--band", type=int, default=256)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--skip-whole", action="store_true")
    a = ap.parse_args()
    print(f"{a.stage}:")
    print("| DEM | N | mode | wall s (median) | peak MB (median) | RSS after imports MB | "
          "SHA-256 of the levels |")
    print("|---|---|---|---|---|---|---|")
    for path in a.dems:
        res: dict[str, list] = {"banded": [], "whole": []}
        for _ in range(a.runs):
            for mode in ("banded",) if a.skip_whole else ("banded", "whole"):
                res[mode].append(run(path, mode, a.band, a.stage))
        shas = {r["sha"] for rs in res.values() for r in rs}
        for mode, rs in res.items():
            if not rs:
                continue
            label = ("whole grid" if mode == "whole" else "super-tiles"
                     if a.stage == "heights" else f"banded, {a.band} rows")
            print(f"| {path.rsplit('/', 1)[-1]} | {rs[0]['N']} | {label} | "
                  f"{statistics.median(r['wall'] for r in rs):.2f} | "
                  f"{statistics.median(r['peak_mb'] for r in rs):.0f} | "
                  f"{statistics.median(r['imports_mb'] for r in rs):.0f} | {rs[0]['sha']} |")
        if len(shas) != 1:
            sys.exit(f"{path}: the banded and whole-grid levels differ: {sorted(shas)}")


if __name__ == "__main__":
    main()

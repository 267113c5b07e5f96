"""Rectangular root grids (issue 45): padding by arithmetic, and a wide raster's
preprocess against a square one with the same samples, in the same run.

Usage:
    python benchmarks/bench_root_grids.py padding [--tile-size 64]
    python benchmarks/bench_root_grids.py wide [--runs 3]
    python benchmarks/bench_root_grids.py codec [--runs 5]
    python benchmarks/bench_root_grids.py stores [--tile-size 64]
    python benchmarks/bench_root_grids.py select [--rows 513 --cols 1025] [--views 8]
                                                 [--rounds 3] [--layouts square,roots]
    python benchmarks/bench_root_grids.py render [--runs 5]
    python benchmarks/bench_root_grids.py geographic [--runs 3]
    python benchmarks/bench_root_grids.py edit [--rows 1025 --cols 2049] [--runs 5]
                                               [--window 65]
    python benchmarks/bench_root_grids.py streamed [--runs 3] [--memory-limit 1G]
                                                   [--square-wide] [--geographic]
                                                   [--baseline CHECKOUT]
    python benchmarks/bench_root_grids.py flat [--runs 3] [--memory-limit 1G]
    python benchmarks/bench_root_grids.py default [--runs 3] [--tile-size 64]
    python benchmarks/bench_root_grids.py static [--errors 174,5,1]

``padding``: per raster shape, the samples the preprocess computes on (the padded
level-0 grid, and every level's lattice summed) over the raster's samples, for the
square layout (one (2^n + 1)² square) and the roots layout (``Grid.for_shape(...,
roots=True)``: level 0 padded to the next tile multiple, a top of at most two roots);
the issue's allowance (1.15× the samples plus one tile row and column) beside them.
Shapes: the issue's (CONUS, jacksboro, wide, the mosaics) and those of the real DEMs
under ``../shared/dems`` that are present. Pure arithmetic (no preprocess runs).

``wide``: an fBm of 1024 × 4096 and one of 2048 × 2048 (the same number of samples,
float32 GeoTIFFs in UTM at 10 m) preprocessed by ``geoterrain.preprocess`` on the square
layout (``root_grid=False``: the wide raster pads to 4097²), and the wide one again with
``root_grid=True`` (2 × 1 roots, the default since); each run a fresh process, the
three cases in rotating order; medians of the wall time and the CPU time (user +
system, both after the import; the CPU time varies less on a shared machine) and of the
peak RSS (VmHWM), and
the ratios to the square raster of the same run. The load (/proc/loadavg) is printed
with every run.

``stores``: stores actually built (``root_grid=True``) of the CONUS shape, 520 × 1180,
and jacksboro's, 344 × 403 (fBm GeoTIFFs in UTM: a root grid is built for projected
frames only, and the grid depends on the shape alone), and of the wide raster: the
samples a store holds (level 0's padded lattice, and the distinct samples of every
stored tile summed over the levels) over the raster's samples, against the square
layout's store of the same raster.

``codec``: the height codec stage alone (``codec.pyramid.encode_decoded``, lossless
``int`` codes of the fBm rounded to 0.1 m, 64-sample tiles) on the same two rasters:
the square 2048² padded to 2049², the wide one padded to today's 4097² square, and the
wide one on its 2 × 1 root grid (the roots' extent, 2049 × 4097: ``roots=(2, 1)``). One
process, the kernels compiled by a first untimed round, the cases in rotating order;
medians of the wall time, the blobs' bytes, and the ratios to the square of the same run.

``select``: the view-dependent selection of every strategy (τ = 1 px, occlusion and
morphing at their defaults, ``reuse=False``) on one wide fBm (``--rows`` × ``--cols``,
UTM, 10 m, 64-sample tiles) preprocessed as a square (it pads to (2^n + 1)²) and as a
root grid, over ``--views`` views of a flight around it; one process, a first untimed
round (kernels, derived tables), then ``--rounds`` rounds in which every view is
selected on each layout in turn; per strategy the median time and triangles per layout
and the ratio roots / square of the same run. ``--layouts square`` times the square
alone (to compare two trees, alternate their interpreters; ``--json`` prints the
medians as one JSON line).

``render``: the wide fBm (1024 × 4096, UTM, 10 m) preprocessed on the square (4097²) and
on its 2 × 1 root grid, then the same three 1280 × 720 views of each (the overview, a
close oblique view over the east root, the map) rendered by ``TerrainScene.frame``
(rtin, τ = 1 px) in one process: a first untimed round (kernels, textures cached),
then ``--runs`` rounds alternating square and roots, each frame in a fresh scene on
the open stores; medians of the frame's wall time and of its selection and atlas
times, the ratios roots / square of the same run, and the pictures' PSNR (roots
against square). Then the static mesh of e = 1 m streamed to PLY
(``write_static_mesh``), the same alternation: time and triangles (both meshes
edge-padded, clipped to the data; the root grid's since part 11 of
docs/lab/root-grids.md).

``geographic``: geographic (EPSG:4326) fBm GeoTIFFs of the issue's shapes, preprocessed
on the square and on the root grid (``root_grid=True``), 64-sample tiles: the CONUS
shape, 520 × 1180 samples of 0.05° over 125–66° W, 24–50° N (heights 0–3000 m), and
jacksboro's shape, 344 × 403 samples of 1″ over its corner of Tennessee (36.33° N,
84.18° W; heights 300–900 m; the file itself is not in ``../shared/dems``). Each
preprocess a fresh process (the ``wide`` child), square and roots alternating, the
order swapped every run; medians of the wall time, CPU time and peak RSS, the ratios
roots / square of the same run, and the load with every run. Then, from the stores the
last run wrote, the samples held: level 0's padded lattice and the distinct samples of
the stored tiles summed over the levels (``stores``' measure), over the raster's.
``edit``: one fBm (``--rows`` × ``--cols``, float32, UTM, 10 m, 64-sample tiles)
preprocessed as the square and as its root grid (a first untimed round, then ``--runs``
rounds alternating which goes first: the median preprocess of each), then the
same edit (``add`` of a random ``--window``² patch whose window straddles column
``cols // 2``, the 2 × 1 roots' shared edge when ``cols`` is 2^k + 1) applied by
``Terrain.edit`` to a fresh copy of each store: a first untimed edit of each (kernels
loaded), then ``--runs`` rounds alternating which layout goes first; medians of the
edit's wall time, the rows and bytes it rewrote, how it was computed, and the ratios
roots / square of the same run; the load with every round.
``streamed``: the streamed preprocess (``preprocess_streaming``, the band a
``--memory-limit`` gives: ``streaming.band_rows`` of the grid's width) of the wide fBm
(1024 × 4096) on its 2 × 1 root grid against the square fBm of the same samples (2048²,
padded to 2049²), and with ``--square-wide`` the wide one on today's 4097² square too;
each run a fresh process, the cases in rotating order; medians of the wall time, the
CPU time and the peak RSS (VmHWM), the ratios to the square raster of the same run, and
the load with every run. ``--geographic``: the same rasters in EPSG:4326 (3 arc-seconds,
from 10° E, 47° N; heights 0–3000 m), the band the limit gives a geographic grid
(``band_rows(..., geographic=True)``), so the metric terms, the curvilinear radii and
level 0's slack run in bands on the roots' extent. ``--baseline``: another checkout's
tree (e.g. ``/work/main``, put first on ``PYTHONPATH``; this interpreter and its
packages) runs every case too, in the same rotation (``[baseline]`` rows, their ratios
to the baseline's square); the sha256 of each store, and whether this checkout's equal
the baseline's in every run.

``flat``: the streamed preprocess of two fBm rasters on their 2 × 1 root grids, 1025 ×
2049 and 4097 × 8193 (rows × cols; each exactly its roots' extent), under the same
``--memory-limit`` (its band), alternating, each run a fresh process: the medians of
their peak RSS and wall time, and the peak's ratio (the Done-when's "peak memory flat in
the raster's size").

``default``: what ``preprocess`` does with its defaults (no ``root_grid`` argument: the
root grid) against ``root_grid=False`` (``--square-grid``), 64-sample tiles, on the
``geographic`` command's CONUS and jacksboro shapes (EPSG:4326 fBm) and the ``wide`` fBm
(1024 × 4096, UTM). Each preprocess a fresh process (the ``wide`` child), default and
square alternating, the order swapped every run; medians of the wall time, the CPU time
(user + system after the import) and the peak RSS (VmHWM), the ratios default / square
of the same run, the load with every run, and level 0's padded samples over the
raster's. Then the samples the pyramid holds, counted from each default store's height
blobs (``held_coded``): every stored tile's blob is read and decoded (its mask, and its
heights through ``Terrain.tile``, checked finite exactly where the mask is valid), and
the positions it codes are marked in level-0 coordinates over the roots' extent: a top
tile codes all its (2^t + 1)² samples, any other tile those of its level that are not on
its parent level's grid (the codec's blob format, codec/pyramid/layout.py). Counted: (a) the
level-0 lattice positions spanned by the stored level-0 tiles; (b) the distinct
positions coded over all levels, padding included, and how many of them lie beyond
level 0's padded lattice (the coarse levels' tiles reach past it) or beyond the raster;
(c) the distinct valid samples coded; and the codes with their multiplicity (a border
shared by two tiles is coded in each, and the sum over the levels of every level's
lattice, the old "all levels" figure, for comparison).

``static``: the static mesh (rtin, ``Terrain.static_selection``) of each DEM under
``../shared/dems`` at the bounds ``--errors`` (metres), on its default store and on its
square store (``root_grid=False``): triangles of each and their ratio. Both static
meshes are edge-padded (the DEM's last row and column repeated into the padding, the
mesh clipped to the data). Counts, no timing.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from geoterrain.core.grid import Grid

ROOT = Path(__file__).resolve().parents[1]
SHAPES = [("CONUS shape (EPSG:4326)", 520, 1180), ("jacksboro", 344, 403),
          ("wide", 1024, 4096), ("square, same samples", 2048, 2048),
          ("4097 × 2049 mosaic", 2049, 4097), ("16385 × 8193 mosaic", 8193, 16385)]

CHILD = """
import json, resource, sys, time
import geoterrain
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.core.grid import Grid
def cpu():
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime
t0, c0 = time.perf_counter(), cpu()
layout = {} if sys.argv[3] == "default" else {"root_grid": sys.argv[3] == "roots"}
p = preprocess(sys.argv[1], sys.argv[2], overwrite=True, **layout,
               tile_size=int(sys.argv[4]) if len(sys.argv) > 4 else 64)
wall, cpus = time.perf_counter() - t0, cpu() - c0
from geoterrain.core.memory import peak_rss
g = geoterrain.open(p).grid
print(json.dumps({"wall": wall, "cpu": cpus, "peak_mb": peak_rss() / 2**20,
                  "grid": g.to_json()}))
"""


STREAM_CHILD = """
import json, resource, sys, time
import geoterrain
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.streaming import band_rows, preprocess_streaming
import rasterio
def cpu():
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime
src, dst, layout, limit = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
with rasterio.open(src) as ds:
    H, W = ds.height, ds.width
    geographic = bool(ds.crs and ds.crs.is_geographic)
g = Grid.for_shape(H, W, roots=layout == "roots")
band = band_rows(g.extent[1], limit, geographic)
t0, c0 = time.perf_counter(), cpu()
p = preprocess_streaming(src, dst, overwrite=True, band=band, root_grid=layout == "roots")
wall, cpus = time.perf_counter() - t0, cpu() - c0
from geoterrain.core.memory import peak_rss
g = geoterrain.open(p).grid
print(json.dumps({"wall": wall, "cpu": cpus, "peak_mb": peak_rss() / 2**20, "band": band,
                  "grid": g.to_json(), "code": geoterrain.__file__}))
"""


def _size(text: str) -> int:
    units = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
    return int(float(text[:-1]) * units[text[-1].upper()]) if text[-1].isalpha() else int(text)


def _alternate(cases: dict, src: dict, d: str, runs: int, limit: int) -> dict:
    # each case (raster, layout[, baseline]) streamed in a fresh process (``baseline``:
    # another checkout's tree, first on PYTHONPATH), rotating the order each run; the
    # store's sha256
    names = list(cases)
    out: dict[str, list[dict]] = {k: [] for k in cases}
    for r in range(runs):
        for name in names[r % len(names):] + names[:r % len(names)]:
            raster, layout, *base = cases[name]
            store = Path(d) / f"{raster}-{layout}{'-baseline' if base else ''}.geoterrain"
            env = dict(os.environ, PYTHONPATH=base[0]) if base else None
            res = json.loads(subprocess.run(
                [sys.executable, "-c", STREAM_CHILD, src[raster], str(store), layout,
                 str(limit)], cwd=d, env=env,  # cwd: not this checkout's folder (its package)
                check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
            res["sha256"] = hashlib.sha256(store.read_bytes()).hexdigest()
            out[name].append(res)
            print(f"run {r} {name}: {res['wall']:.2f} s, CPU {res['cpu']:.2f} s, "
                  f"{res['peak_mb']:.0f} MB, band {res['band']}, grid {res['grid']}, "
                  f"sha256 {res['sha256'][:12]}, {res['code']}, load {load()}", flush=True)
    return out


def _alternate_whole(cases: dict, runs: int, tile_size: int | None = None,
                     label: str = "") -> dict:
    # each case (source, layout, store path) preprocessed whole in a fresh process (CHILD),
    # the order rotating each run
    names = list(cases)
    out: dict[str, list[dict]] = {k: [] for k in cases}
    for r in range(runs):
        for name in names[r % len(names):] + names[:r % len(names)]:
            src, layout, path = cases[name]
            args = [src, str(path), layout] + ([] if tile_size is None else [str(tile_size)])
            res = json.loads(subprocess.run(
                [sys.executable, "-c", CHILD, *args],
                check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
            out[name].append(res)
            print(f"{label}run {r} {name}: {res['wall']:.2f} s, CPU {res['cpu']:.2f} s, "
                  f"{res['peak_mb']:.0f} MB, grid {res['grid']}, load {load()}", flush=True)
    return out


def _medians(runs: dict) -> dict:
    return {k: {m: statistics.median(x[m] for x in v) for m in ("wall", "cpu", "peak_mb")}
            for k, v in runs.items()}


def streamed(a: argparse.Namespace) -> None:
    from geoterrain.ingest.synth import generate, write_geotiff

    limit = _size(a.memory_limit)
    frame = "EPSG:4326" if a.geographic else "UTM"
    print(f"load before: {load()}; memory limit {a.memory_limit}; {frame}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_") as d:
        src = {}
        for name, shape in (("wide", (1024, 4096)), ("square", (2048, 2048))):
            z = generate("fbm", shape, seed=3)
            if a.geographic:
                z = 3000 * (z - z.min()) / np.ptp(z)
                src[name] = str(write_geotiff(Path(d) / f"{name}.tif", z.astype(np.float32),
                                              crs="EPSG:4326", origin=(10.0, 47.0),
                                              spacing=3 / 3600))
            else:
                src[name] = str(write_geotiff(Path(d) / f"{name}.tif", z.astype(np.float32)))
        cases = {"square 2048², streamed": ("square", "square"),
                 "wide 1024 × 4096 on 2 × 1 roots, streamed": ("wide", "roots")}
        if a.square_wide:
            cases["wide 1024 × 4096 on the 4097² square, streamed"] = ("wide", "square")
        if a.baseline:  # each case by the baseline checkout too, alternating
            cases.update({f"{k} [baseline]": (*v, str(Path(a.baseline).resolve()))
                          for k, v in list(cases.items())})
        runs = _alternate(cases, src, d, a.runs, limit)
    med = _medians(runs)
    print(f"\nload after: {load()}\n")
    print("| case | wall (median) | CPU (median) | peak RSS (median) | wall / square "
          "| CPU / square | peak / square |")
    print("|---|---|---|---|---|---|---|")
    for k, m in med.items():
        sq = med["square 2048², streamed" + (" [baseline]" if k.endswith("[baseline]") else "")]
        print(f"| {k} | {m['wall']:.2f} s | {m['cpu']:.2f} s | {m['peak_mb']:.0f} MB "
              f"| {m['wall'] / sq['wall']:.2f}× | {m['cpu'] / sq['cpu']:.2f}× "
              f"| {m['peak_mb'] / sq['peak_mb']:.2f}× |")
    for k in runs:
        if not k.endswith("[baseline]") and f"{k} [baseline]" in runs:
            shas = {x["sha256"] for x in runs[k] + runs[f"{k} [baseline]"]}
            print(f"{k}: stores {'byte-identical to' if len(shas) == 1 else 'DIFFER from'} "
                  f"the baseline's in every run (sha256 {', '.join(sorted(shas))})")


def flat(a: argparse.Namespace) -> None:
    from geoterrain.ingest.synth import generate, write_geotiff

    limit = _size(a.memory_limit)
    print(f"load before: {load()}; memory limit {a.memory_limit}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_") as d:
        src = {}
        for name, shape in (("small", (1025, 2049)), ("large", (4097, 8193))):
            src[name] = str(write_geotiff(Path(d) / f"{name}.tif",
                                          generate("fbm", shape, seed=3).astype(np.float32)))
        cases = {"1025 × 2049 on 2 × 1 roots": ("small", "roots"),
                 "4097 × 8193 on 2 × 1 roots": ("large", "roots")}
        runs = _alternate(cases, src, d, a.runs, limit)
    med = _medians(runs)
    small = med["1025 × 2049 on 2 × 1 roots"]
    print(f"\nload after: {load()}\n")
    print("| raster (rows × cols) | wall (median) | CPU (median) | peak RSS (median) "
          "| peak / 1025 × 2049 |")
    print("|---|---|---|---|---|")
    for k, m in med.items():
        print(f"| {k} | {m['wall']:.2f} s | {m['cpu']:.2f} s | {m['peak_mb']:.0f} MB "
              f"| {m['peak_mb'] / small['peak_mb']:.3f}× |")


def load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def lattice(g: Grid) -> tuple[int, int]:
    """(level-0 samples, samples of every level's lattice) of the padded grid."""
    per = [np.prod(g.level_shape(L), dtype=np.int64) for L in g.levels]
    return int(per[0]), int(sum(per))


def padding(a: argparse.Namespace) -> None:
    shapes = list(SHAPES)
    dems = ROOT / ".." / "shared" / "dems"
    try:
        import rasterio

        for p in sorted(dems.glob("*.tif")):
            with rasterio.open(p) as s:
                shapes.append((p.name, s.height, s.width))
    except Exception as exc:  # noqa: BLE001 - the real DEMs are optional here
        print(f"(real DEMs skipped: {exc})", file=sys.stderr)
    step = a.tile_size
    print(f"tile size {step}; ratios are samples computed on / the raster's samples\n")
    print("| raster | rows × cols | square: padded | level 0 | all levels | roots: level 0 "
          "| roots | level 0 | all levels | issue's allowance |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, h, w in shapes:
        sq, rt = Grid.for_shape(h, w, step), Grid.for_shape(h, w, step, roots=True)
        hw = h * w
        s0, sall = lattice(sq)
        r0, rall = lattice(rt)
        allow = (1.15 * hw + (step + 1) * (h + w) + (step + 1) ** 2) / hw
        rr, rc = rt.shape
        print(f"| {name} | {h} × {w} | {sq.size}² | {s0 / hw:.3f}× | {sall / hw:.3f}× "
              f"| {rr} × {rc} | {rt.roots[0]} × {rt.roots[1]} | {r0 / hw:.3f}× "
              f"| {rall / hw:.3f}× | {allow:.3f}× |")


def wide(a: argparse.Namespace) -> None:
    from geoterrain.ingest.synth import generate, write_geotiff

    print(f"load before: {load()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_") as d:
        src = {}
        for name, shape in (("wide", (1024, 4096)), ("square", (2048, 2048))):
            src[name] = str(write_geotiff(Path(d) / f"{name}.tif",
                                          generate("fbm", shape, seed=3).astype(np.float32)))
        cases = {"square": ("square", "square"), "wide": ("wide", "square"),
                 "wide, roots": ("wide", "roots")}
        runs = _alternate_whole({name: (src[raster], layout, Path(d) / f"{raster}.geoterrain")
                                 for name, (raster, layout) in cases.items()}, a.runs)
    med = _medians(runs)
    print(f"\nload after: {load()}\n")
    print("| raster | wall (median) | CPU (median) | peak RSS (median) | wall / square "
          "| CPU / square | peak / square |")
    print("|---|---|---|---|---|---|---|")
    for k in cases:
        print(f"| {k} | {med[k]['wall']:.2f} s | {med[k]['cpu']:.2f} s "
              f"| {med[k]['peak_mb']:.0f} MB | {med[k]['wall'] / med['square']['wall']:.2f}× "
              f"| {med[k]['cpu'] / med['square']['cpu']:.2f}× "
              f"| {med[k]['peak_mb'] / med['square']['peak_mb']:.2f}× |")


def held(t) -> tuple[int, int]:
    """(level-0 lattice samples, every level's stored-tile lattice summed: a position is
    counted once per level it lies on; the positions the codec codes are ``held_coded``'s)."""
    g = t.grid
    total = 0
    for L in g.levels:
        R, C = g.level_shape(L)
        cover = np.zeros((R, C), bool)
        T = g.tile_samples
        for (lv, x, y) in t.tile_info:
            if lv == L:
                cover[y * (T - 1):y * (T - 1) + T, x * (T - 1):x * (T - 1) + T] = True
        total += int(cover.sum())
    R, C = g.shape
    return R * C, total


def stores(a: argparse.Namespace) -> None:
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    print(f"load before: {load()}; tile size {a.tile_size}\n", flush=True)
    print("| raster | layout | grid | level 0 held / raster "
          "| every level's lattice summed / raster |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_") as d:
        for name, h, w in (("CONUS shape", 520, 1180), ("jacksboro shape", 344, 403),
                           ("wide", 1024, 4096)):
            src = write_geotiff(Path(d) / "r.tif",
                                generate("fbm", (h, w), seed=3).astype(np.float32))
            for roots in (False, True):
                p = geoterrain.preprocess(src, Path(d) / "r.geoterrain", overwrite=True,
                                          tile_size=a.tile_size, root_grid=roots)
                with geoterrain.open(p) as t:
                    g = t.grid
                    l0, every = held(t)
                desc = (f"{g.size}²" if g.square else
                        f"{g.shape[0]} × {g.shape[1]}, {g.roots[0]} × {g.roots[1]} roots")
                print(f"| {name} {h} × {w} | {'roots' if roots else 'square'} | {desc} "
                      f"| {l0 / (h * w):.3f}× | {every / (h * w):.3f}× |", flush=True)
    print(f"\nload after: {load()}")


def codec(a: argparse.Namespace) -> None:
    import time

    from geoterrain.codec.pyramid import encode_decoded
    from geoterrain.codec.quantize import Quantizer
    from geoterrain.ingest.synth import generate

    print(f"load before: {load()}", flush=True)
    qz = Quantizer("int", 0.1)
    cases = {}
    for name, shape, side, roots in (("square 2048² → 2049²", (2048, 2048), (2049, 2049), None),
                                     ("wide → 4097² square", (1024, 4096), (4097, 4097), None),
                                     ("wide → 2 × 1 roots", (1024, 4096), (2049, 4097), (2, 1))):
        z = np.zeros(side)
        v = np.zeros(side, bool)
        z[:shape[0], :shape[1]] = (generate("fbm", shape, seed=3) * 10).round() / 10
        v[:shape[0], :shape[1]] = True
        cases[name] = (z, v, roots)
    small = np.zeros((129, 257)), np.ones((129, 257), bool)
    encode_decoded(*small, 6, qz, roots=(2, 1))  # compile
    encode_decoded(small[0][:, :129], small[1][:, :129], 6, qz)
    res: dict[str, list[tuple[float, int]]] = {k: [] for k in cases}
    names = list(cases)
    for r in range(a.runs):
        for name in names[r % 3:] + names[:r % 3]:
            z, v, roots = cases[name]
            t0 = time.perf_counter()
            blobs, _ = encode_decoded(z, v, 6, qz, roots=roots)
            res[name].append((time.perf_counter() - t0, sum(map(len, blobs.values()))))
            print(f"run {r} {name}: {res[name][-1][0]:.2f} s, {res[name][-1][1]} bytes, "
                  f"{len(blobs)} tiles, load {load()}", flush=True)
    print(f"\nload after: {load()}\n")
    print("| case | encode (median) | bytes | time / square |")
    print("|---|---|---|---|")
    base = statistics.median(t for t, _ in res[names[0]])
    for name in names:
        t = statistics.median(x for x, _ in res[name])
        print(f"| {name} | {t:.2f} s | {res[name][0][1]} | {t / base:.2f}× |")


def select(a: argparse.Namespace) -> None:
    import time

    import geoterrain
    from geoterrain.bench.harness import flight
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.lod import STRATEGIES

    layouts = a.layouts.split(",")
    tmp = Path(tempfile.mkdtemp(prefix="bench_root_select_"))
    z = generate("fbm", (a.rows, a.cols), seed=7)
    src = write_geotiff(tmp / "w.tif", (800.0 * (z - z.min()) / np.ptp(z)).astype(np.float32),
                        crs="EPSG:32633", origin=(500000.0, 5000000.0), spacing=10.0)
    ts = {k: geoterrain.open(geoterrain.preprocess(src, tmp / f"{k}.geoterrain",
                                                   root_grid=k == "roots")) for k in layouts}
    X, Y, Z = next(iter(ts.values())).scene_xyz()
    ok = np.isfinite(Z)
    lo = np.array([X[ok].min(), Y[ok].min(), Z[ok].min()])
    hi = np.array([X[ok].max(), Y[ok].max(), Z[ok].max()])
    views = [v for _, v in flight(lo, hi, n_views=a.views, size=(1280, 720))]
    grids = {k: t.grid for k, t in ts.items()}
    if not a.json:
        print("grids: " + ", ".join(f"{k} {g.shape[1]} × {g.shape[0]} lattice, roots "
                                    f"{g.roots}, extent {g.extent[1]} × {g.extent[0]}"
                                    for k, g in grids.items()))
        print(f"load before: {load()}", flush=True)
    ms: dict = {(s, k): [] for s in STRATEGIES for k in layouts}
    tri: dict = {}
    for r in range(a.rounds + 1):  # round 0: untimed (kernels, derived tables)
        for s in STRATEGIES:
            for v in views:
                for k in (layouts if r % 2 == 0 else layouts[::-1]):
                    t0 = time.perf_counter()
                    sel = ts[k].select(v, 1.0, s, reuse=False)
                    if r:
                        ms[s, k].append(1e3 * (time.perf_counter() - t0))
                    tri[s, k] = tri.get((s, k), 0) + sel.mesh.n_cells * (r == 1)
        if r and not a.json:
            print(f"round {r} done, load {load()}", flush=True)
    med = {f"{s} {k}": statistics.median(ms[s, k]) for s in STRATEGIES for k in layouts}
    if a.json:
        print(json.dumps(med))
        return
    print(f"load after: {load()}\n")
    print("| strategy | " + " | ".join(f"{k}: ms (median), triangles / view" for k in layouts)
          + (" | roots / square |" if len(layouts) == 2 else " |"))
    print("|---" * (len(layouts) + 1 + (len(layouts) == 2)) + "|")
    for s in STRATEGIES:
        cells = [f"{med[f'{s} {k}']:.1f}, {tri[s, k] / len(views):.0f}" for k in layouts]
        ratio = (f" | {med[f'{s} roots'] / med[f'{s} square']:.2f}×" if len(layouts) == 2
                 else "")
        print(f"| {s} | " + " | ".join(cells) + ratio + " |")


def render(a: argparse.Namespace) -> None:
    import time

    import geoterrain
    from geoterrain.export.meshstream import write_static_mesh
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.rendering.mapview import map_view
    from geoterrain.rendering.scene import TerrainScene, default_view
    from geoterrain.rendering.window import pyvista_plotter

    d = Path(tempfile.mkdtemp(prefix="bench_root_render_"))
    dem = write_geotiff(d / "wide.tif", generate("fbm", (1024, 4096), seed=3, relief=1500.0),
                        crs="EPSG:32633", spacing=10.0)
    t = {k: geoterrain.open(geoterrain.preprocess(dem, d / f"{k}.geoterrain",
                                                  root_grid=k == "roots"))
         for k in ("square", "roots")}
    assert t["roots"].grid.roots == (2, 1)
    size = (1280, 720)
    sq = t["square"]
    lo, hi = sq.scene_box()
    east = np.array([0.8 * hi[0], 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])])
    views = {"overview": default_view(sq, size), "map": map_view(sq, size),
             "east root, close": geoterrain.View(tuple(east + (-4000.0, -4000.0, 2500.0)),
                                                 tuple(east), size=size)}

    def frame(k, v):
        scene = TerrainScene(pyvista_plotter(size), t[k])
        try:
            t0 = time.perf_counter()
            img, st = scene.frame(v, 1.0, "rtin")
            return (time.perf_counter() - t0) * 1e3, st, img
        finally:
            scene.plotter.close()

    print(f"load before: {load()}", flush=True)
    for k in t:  # untimed: kernels compiled, tiles decoded and shaded once
        for v in views.values():
            frame(k, v)
    res = {(k, n): [] for k in t for n in views}
    imgs = {}
    for r in range(a.runs):
        for n, v in views.items():
            for k in (("square", "roots") if r % 2 == 0 else ("roots", "square")):
                ms, st, img = frame(k, v)
                res[k, n].append((ms, st["select_ms"], st.get("texture_ms", 0.0),
                                  st["triangles"]))
                imgs[k, n] = img
        print(f"round {r}: load {load()}", flush=True)
    print(f"\nload after: {load()}\n")
    print("| view | square: frame, select, atlas (ms), triangles | roots: frame, select, "
          "atlas (ms), triangles | roots / square frame | PSNR |")
    print("|---|---|---|---|---|")
    for n in views:
        m = {k: [statistics.median(x[i] for x in res[k, n]) for i in range(4)] for k in t}
        a_, b_ = imgs["square", n].astype(float), imgs["roots", n].astype(float)
        p = 10 * np.log10(255.0 ** 2 / max(float(np.mean((a_ - b_) ** 2)), 1e-12))
        cells = [f"{v[0]:.0f}, {v[1]:.0f}, {v[2]:.0f}, {v[3]:,.0f}" for v in m.values()]
        print(f"| {n} | {cells[0]} | {cells[1]} | {m['roots'][0] / m['square'][0]:.2f}× "
              f"| {p:.1f} dB |")
    out = {k: [] for k in t}
    for r in range(a.runs):
        for k in (("square", "roots") if r % 2 == 0 else ("roots", "square")):
            t0 = time.perf_counter()
            st = write_static_mesh(t[k], 1.0, d / f"{k}.ply", overwrite=True)
            out[k].append((time.perf_counter() - t0, st["triangles"]))
    print(f"\nstatic mesh e = 1 m to PLY (load {load()}):")
    for k in t:
        print(f"  {k}: {statistics.median(x[0] for x in out[k]):.2f} s, "
              f"{out[k][0][1]:,} triangles")


#: (name, rows, cols, west, north, spacing in degrees, lowest and highest height)
GEOGRAPHIC = [("CONUS shape (EPSG:4326)", 520, 1180, -125.0, 50.0, 0.05, 0.0, 3000.0),
              ("jacksboro shape (EPSG:4326)", 344, 403, -84.18, 36.33, 1 / 3600, 300.0,
               900.0)]


def geographic(a: argparse.Namespace) -> None:
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    print(f"load before: {load()}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_geo_") as d:
        for name, h, w, west, north, deg, lo, hi in GEOGRAPHIC:
            z = generate("fbm", (h, w), seed=3)
            z = (lo + (hi - lo) * (z - z.min()) / np.ptp(z)).astype(np.float32)
            src = str(write_geotiff(Path(d) / "g.tif", z, crs="EPSG:4326",
                                    origin=(west, north), spacing=deg))
            runs = _alternate_whole({k: (src, k, Path(d) / f"{k}.geoterrain")
                                     for k in ("square", "roots")}, a.runs, a.tile_size,
                                    f"{name} ")
            med = _medians(runs)
            for layout in ("square", "roots"):
                with geoterrain.open(Path(d) / f"{layout}.geoterrain") as t:
                    g = t.grid
                    l0, every = held(t)
                desc = (f"{g.size}²" if g.square else
                        f"{g.shape[0]} × {g.shape[1]}, {g.roots[0]} × {g.roots[1]} roots")
                m, s = med[layout], med["square"]
                rows.append(f"| {name} {h} × {w} | {layout} | {desc} | {l0 / (h * w):.3f}× "
                            f"| {every / (h * w):.3f}× | {m['wall']:.2f} s "
                            f"({m['wall'] / s['wall']:.2f}×) | {m['cpu']:.2f} s "
                            f"({m['cpu'] / s['cpu']:.2f}×) | {m['peak_mb']:.0f} MB "
                            f"({m['peak_mb'] / s['peak_mb']:.2f}×) |")
    print(f"\nload after: {load()}; medians of {a.runs} runs, ratios to the square\n")
    print("| raster | layout | grid | level 0 held / raster "
          "| every level's lattice summed / raster | wall | CPU | peak RSS |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))

def edit(a: argparse.Namespace) -> None:
    import shutil
    import time

    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    d = Path(tempfile.mkdtemp(prefix="bench_root_edit_"))
    z = generate("fbm", max(a.rows, a.cols), seed=5, relief=1500.0)[:a.rows, :a.cols]
    dem = write_geotiff(d / "fbm.tif", z.astype(np.float32), crs="EPSG:32633", spacing=10.0)
    print(f"load before: {load()}", flush=True)
    store, pres = {}, {"square": [], "roots": []}
    for r in range(a.runs + 1):  # the first round untimed: kernels loaded or compiled
        for k in (("square", "roots") if r % 2 == 0 else ("roots", "square")):
            t0 = time.perf_counter()
            store[k] = geoterrain.preprocess(dem, d / f"{k}.geoterrain", overwrite=True,
                                             root_grid=k == "roots")
            if r:
                pres[k].append(time.perf_counter() - t0)
        print(f"preprocess round {r}: load {load()}", flush=True)
    pre = {k: statistics.median(v) for k, v in pres.items()}
    with geoterrain.open(store["roots"]) as t:
        print(f"roots: {t.grid.roots}, level 0 {t.grid.shape}, extent {t.grid.extent}; "
              f"square: {a.rows} × {a.cols} padded to "
              f"{geoterrain.open(store['square']).grid.size}²", flush=True)
    rng = np.random.default_rng(0)
    w = a.window
    row, col = (a.rows - w) // 2, a.cols // 2 - w // 2
    patch = np.asarray(rng.normal(0.0, 5.0, (w, w)), np.float32).astype(np.float64)

    def one(k):
        copy = d / f"{k}.edit.geoterrain"
        shutil.copy(store[k], copy)
        with geoterrain.open(copy) as t:
            t0 = time.perf_counter()
            res = t.edit((row, col), patch, mode="add", round_heights=True)
            wall = time.perf_counter() - t0
        return wall, res.rows, res.bytes, res.how, copy.stat().st_size

    for k in store:  # untimed: kernels loaded, modules imported
        one(k)
    res = {k: [] for k in store}
    for r in range(a.runs):
        for k in (("square", "roots") if r % 2 == 0 else ("roots", "square")):
            res[k].append(one(k))
        print(f"round {r}: load {load()}", flush=True)
    print(f"\nload after: {load()}\n")
    print("| layout | preprocess (s, median) | edit (s, median) | edit / preprocess | rows "
          "| bytes rewritten | of the store | how |")
    print("|---|---|---|---|---|---|---|---|")
    med = {}
    for k in store:
        m = statistics.median(x[0] for x in res[k])
        med[k] = m
        _, rows, nbytes, how, size = res[k][0]
        print(f"| {k} | {pre[k]:.2f} | {m:.3f} | {m / pre[k]:.3f}× | {rows} | "
              f"{nbytes:,} | {100 * nbytes / size:.2f} % | {how} |")
    print(f"\nroots / square, edit time: {med['roots'] / med['square']:.2f}×, preprocess: "
          f"{pre['roots'] / pre['square']:.2f}×; all preprocesses (s): "
          + "; ".join(f"{k} " + ", ".join(f"{x:.2f}" for x in v) for k, v in pres.items()))
    print("all edits "
          "(s): " + "; ".join(f"{k} " + ", ".join(f"{x[0]:.3f}" for x in res[k])
                              for k in res))


def held_coded(t) -> dict:
    """The positions the store's height blobs code, counted from the blobs (see the
    ``default`` command's description): level-0 coordinates over the roots' extent."""
    from geoterrain.codec.pyramid import tile_valid
    from geoterrain.store.reader import StoreReader

    g = t.grid
    R, C = g.extent
    h0, w0 = g.shape
    span0 = np.zeros((R, C), bool)  # (a) level-0 lattice spanned by stored level-0 tiles
    coded = np.zeros((R, C), bool)  # (b) every position some blob codes
    valid = np.zeros((R, C), bool)  # (c) those a blob codes as valid
    per_tile = 0  # codes with multiplicity (valid or not)
    T, e = g.tile_samples, 1 << g.t
    reader = StoreReader(t.path)
    try:
        for (L, x, y) in t.tile_keys():
            blob = reader.get_blob((L, x, y), "heights")
            mask = tile_valid(blob, g.t)
            heights = t.tile(L, x, y).heights  # decoded: finite exactly where valid
            assert (np.isfinite(heights) == mask).all(), (L, x, y)
            top = bool(blob[1] & 1)  # the blob's flags: bit 0 the top tile
            s = 1 << L
            r0, c0 = y * e * s, x * e * s
            rows, cols = slice(r0, r0 + e * s + 1, s), slice(c0, c0 + e * s + 1, s)
            if L == 0:
                span0[rows, cols] = True
            new = np.ones((T, T), bool)
            if not top:
                new[::2, ::2] = False  # the parent level's samples are copied, not coded
            per_tile += int(new.sum())
            coded[rows, cols] |= new
            valid[rows, cols] |= new & mask
    finally:
        reader.close()
    beyond = coded.copy()
    beyond[:h0, :w0] = False
    outside = coded.copy()
    outside[:g.rows, :g.cols] = False
    return dict(level0=int(span0.sum()), coded=int(coded.sum()), beyond=int(beyond.sum()),
                outside=int(outside.sum()), valid=int(valid.sum()), per_tile=per_tile,
                lattices=lattice(g)[1])


def static(a: argparse.Namespace) -> None:
    import geoterrain

    errors = [float(x) for x in a.errors.split(",")]
    dems = ROOT / ".." / "shared" / "dems"
    print(f"load: {load()}\n")
    print("| DEM | rows × cols | default grid | " + " | ".join(
        f"e = {e:g}: default, square, ratio" for e in errors) + " |")
    print("|---|---|---|" + "---|" * len(errors))
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_static_") as d:
        for p in sorted(dems.glob("*.tif")):
            tris, grids = {}, {}
            for rg in (True, False):
                store = geoterrain.preprocess(p, Path(d) / "s.geoterrain", overwrite=True,
                                              root_grid=rg)
                with geoterrain.open(store) as t:
                    g = t.grid
                    grids[rg] = g
                    tris[rg] = [t.static_selection(e).stats["triangles"] for e in errors]
            g = grids[True]
            desc = (f"{g.size}² (square)" if g.square else
                    f"{g.shape[0]} × {g.shape[1]}, {g.roots[0]} × {g.roots[1]} roots")
            print(f"| {p.name} | {g.rows} × {g.cols} | {desc} | " + " | ".join(
                f"{r:,}, {q:,}, {r / q:.3f}×"
                for r, q in zip(tris[True], tris[False], strict=True)) + " |", flush=True)


def default(a: argparse.Namespace) -> None:
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    print(f"load before: {load()}", flush=True)
    rasters = [*GEOGRAPHIC, ("wide (UTM)", 1024, 4096, None, None, None, 0.0, 2000.0)]
    timing, counts = [], []
    with tempfile.TemporaryDirectory(prefix="bench_root_grids_default_") as d:
        for name, h, w, west, north, deg, lo, hi in rasters:
            z = generate("fbm", (h, w), seed=3)
            z = (lo + (hi - lo) * (z - z.min()) / np.ptp(z)).astype(np.float32)
            geo = dict(crs="EPSG:4326", origin=(west, north), spacing=deg) if deg else {}
            src = str(write_geotiff(Path(d) / "g.tif", z, **geo))
            runs = _alternate_whole({k: (src, k, Path(d) / f"{k}.geoterrain")
                                     for k in ("default", "square")}, a.runs, a.tile_size,
                                    f"{name} ")
            med = _medians(runs)
            hw = h * w
            for layout in ("default", "square"):
                with geoterrain.open(Path(d) / f"{layout}.geoterrain") as t:
                    g = t.grid
                    c = held_coded(t) if layout == "default" else None
                    l0 = int(np.prod(g.shape))
                desc = (f"{g.size}² (square)" if g.square else
                        f"{g.shape[0]} × {g.shape[1]}, {g.roots[0]} × {g.roots[1]} roots")
                m, sq = med[layout], med["square"]
                timing.append(f"| {name} {h} × {w} | {layout} | {desc} | {l0 / hw:.3f}× "
                              f"| {m['wall']:.2f} s ({m['wall'] / sq['wall']:.2f}×) "
                              f"| {m['cpu']:.2f} s ({m['cpu'] / sq['cpu']:.2f}×) "
                              f"| {m['peak_mb']:.0f} MB ({m['peak_mb'] / sq['peak_mb']:.2f}×) |")
                if c is not None:
                    counts.append(f"| {name} {h} × {w} | {desc} | {c['level0'] / hw:.3f}× "
                                  f"| {c['coded'] / hw:.3f}× ({c['beyond']:,} beyond level "
                                  f"0's lattice, {c['outside']:,} beyond the raster) "
                                  f"| {c['valid'] / hw:.3f}× | {c['per_tile'] / hw:.3f}× "
                                  f"| {c['lattices'] / hw:.3f}× |")
    print(f"\nload after: {load()}; medians of {a.runs} runs, ratios to the square\n")
    print("| raster | layout | grid | level 0 padded / raster | wall | CPU | peak RSS |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(timing))
    print("\nSamples the default store holds, counted from its height blobs, over the "
          "raster's samples:\n")
    print("| raster | grid | (a) level-0 lattice of stored tiles | (b) distinct positions "
          "coded, padding included | (c) valid samples coded | codes with multiplicity "
          "| every level's lattice summed |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(counts))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("padding")
    p.add_argument("--tile-size", type=int, default=64)
    w = sub.add_parser("wide")
    w.add_argument("--runs", type=int, default=3)
    c = sub.add_parser("codec")
    c.add_argument("--runs", type=int, default=5)
    s = sub.add_parser("stores")
    s.add_argument("--tile-size", type=int, default=64)
    e = sub.add_parser("select")
    e.add_argument("--rows", type=int, default=513)
    e.add_argument("--cols", type=int, default=1025)
    e.add_argument("--views", type=int, default=8)
    e.add_argument("--rounds", type=int, default=3)
    e.add_argument("--layouts", default="square,roots")
    e.add_argument("--json", action="store_true")
    r = sub.add_parser("render")
    r.add_argument("--runs", type=int, default=5)
    g = sub.add_parser("geographic")
    g.add_argument("--runs", type=int, default=3)
    g.add_argument("--tile-size", type=int, default=64)
    ed = sub.add_parser("edit")
    ed.add_argument("--rows", type=int, default=1025)
    ed.add_argument("--cols", type=int, default=2049)
    ed.add_argument("--runs", type=int, default=5)
    ed.add_argument("--window", type=int, default=65)
    m = sub.add_parser("streamed")
    m.add_argument("--runs", type=int, default=3)
    m.add_argument("--memory-limit", default="1G")
    m.add_argument("--square-wide", action="store_true")
    m.add_argument("--geographic", action="store_true")
    m.add_argument("--baseline", default=None)
    f = sub.add_parser("flat")
    f.add_argument("--runs", type=int, default=3)
    f.add_argument("--memory-limit", default="1G")
    df = sub.add_parser("default")
    df.add_argument("--runs", type=int, default=3)
    df.add_argument("--tile-size", type=int, default=64)
    st = sub.add_parser("static")
    st.add_argument("--errors", default="174,5,1")
    a = ap.parse_args()
    {"default": default, "static": static, "padding": padding, "wide": wide, "codec": codec,
     "stores": stores, "select": select, "render": render, "geographic": geographic, "edit": edit,
     "streamed": streamed, "flat": flat}[a.what](a)


if __name__ == "__main__":
    main()

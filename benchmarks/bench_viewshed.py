"""A viewshed from a store against ``gdal_viewshed`` on the GeoTIFF: time and agreement.

    python benchmarks/bench_viewshed.py --size 4097 [--runs 5] [--coverage 0.25]
    python benchmarks/bench_viewshed.py --dem ../shared/dems/srtm1_japan.tif --radius 10000

With ``--size N`` the DEM is ``geoterrain synth fbm --size N --seed 7`` (10 m cells), made
in ``--workdir`` (kept between runs; by default a folder in the system temporary
directory, never the working folder); ``--dem`` takes a GeoTIFF (a geographic one is run
with curvature off, ``-cc 0``, as gdal_viewshed measures its distances in degrees, and its
``-md`` is given in degrees to cover the disc; cells are compared where both answer).
The observer stands at the DEM's centre (``--observer X,Y`` in its CRS otherwise),
``--height`` metres above the ground; the radius covers ``--coverage`` of the DEM's area
unless ``--radius`` (metres) is given.

Each run, alternating: ``gdal_viewshed`` as a process (its wall time, reading the GeoTIFF
and writing its output), and :func:`geoterrain.analysis.viewshed` in this process from
the open store with its tile cache emptied (decoding included, compiled kernels warm).
Prints the medians, their ratio (same run) with the load average, the CPU time of each
(user + system: what a loaded machine's wall time tends to), the tiles decoded and
skipped, and the agreement on the cells both answer (and the cells that disagree).
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _dem(a) -> Path:
    if a.dem:
        return Path(a.dem)
    from geoterrain.ingest.synth import generate, write_geotiff

    p = Path(a.workdir) / f"fbm{a.size}.tif"
    if not p.exists():
        write_geotiff(p, generate("fbm", a.size, seed=7), spacing=10.0)
    return p


def _store(a, dem: Path) -> Path:
    import geoterrain

    p = Path(a.workdir) / f"{dem.stem}.geoterrain"
    if not p.exists():
        geoterrain.preprocess(dem, p)
    return p


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=4097)
    ap.add_argument("--dem")
    ap.add_argument("--workdir", default=os.path.join(tempfile.gettempdir(),
                                                      "geoterrain-bench-viewshed"))
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--coverage", type=float, default=0.25)
    ap.add_argument("--radius", type=float)
    ap.add_argument("--height", type=float, default=2.0)
    ap.add_argument("--observer")
    a = ap.parse_args()
    if shutil.which("gdal_viewshed") is None:
        sys.exit("gdal_viewshed not found: install Debian's gdal-bin (make gdal)")
    import rasterio

    import geoterrain
    from geoterrain.analysis import viewshed

    Path(a.workdir).mkdir(parents=True, exist_ok=True)
    dem = _dem(a)
    t = geoterrain.open(_store(a, dem))
    f = t.frame
    geo = f.kind == "geographic"
    tr = f.transform
    if a.observer:
        ox, oy = (float(v) for v in a.observer.split(","))
    else:
        ox = tr[2] + tr[0] * (t.grid.cols // 2 + 0.5)
        oy = tr[5] + tr[4] * (t.grid.rows // 2 + 0.5)
    info = t.info()
    ext = info["extent_m"]
    area = (ext["x"][1] - ext["x"][0]) * (ext["y"][1] - ext["y"][0])
    radius = a.radius or math.sqrt(a.coverage * area / math.pi)
    cc = 0.0 if geo else 0.85714
    md = radius
    if geo:  # gdal_viewshed's distance is in degrees: cover the disc along the parallel
        md = radius / (111320.0 * math.cos(math.radians(oy))) * 1.05
    out = Path(a.workdir) / "vs_gdal.tif"
    cmd = ["gdal_viewshed", "-q", "-ox", repr(ox), "-oy", repr(oy), "-oz", repr(a.height),
           "-md", repr(md), "-cc", repr(cc), "-ov", "2", str(dem), str(out)]
    viewshed(t, (ox, oy), radius, a.height, curvature=cc)  # compile, open caches
    tg, tv, cg, cv, vs = [], [], [], [], None
    for _ in range(a.runs):
        out.unlink(missing_ok=True)
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True)
        tg.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cg.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
        t.clear_cache()
        c0 = time.process_time()  # every thread of this process
        t0 = time.perf_counter()
        vs = viewshed(t, (ox, oy), radius, a.height, curvature=cc)
        tv.append(time.perf_counter() - t0)
        cv.append(time.process_time() - c0)
    with rasterio.open(out) as r:
        g, gt = r.read(1), r.transform
    dr = int(round((vs.transform.f - gt.f) / gt.e))
    dc = int(round((vs.transform.c - gt.c) / gt.a))
    H, W = vs.codes.shape
    mine = vs.codes
    rows = slice(max(dr, 0), min(dr + H, g.shape[0]))
    cols = slice(max(dc, 0), min(dc + W, g.shape[1]))
    theirs = np.full_like(mine, 2)  # gdal's out of range (-ov 2)
    theirs[rows.start - dr:rows.stop - dr, cols.start - dc:cols.stop - dc] = g[rows, cols]
    both = (mine != 254) & (mine != 255) & (theirs != 2)  # cells both answer
    agree = ((theirs == 255) == (mine == 1))[both]
    s = vs.stats
    mg, mv = statistics.median(tg), statistics.median(tv)
    print(f"{dem.name}: {t.grid.rows}×{t.grid.cols}, observer ({ox:.6f}, {oy:.6f}) "
          f"+{a.height:g} m, radius {radius:.0f} m ({s['cells']} cells in the disc), "
          f"curvature {cc}")
    print(f"gdal_viewshed (process, GeoTIFF)   median {mg:.3f} s  runs {[round(x, 3) for x in tg]}")
    print(f"geoterrain viewshed (store, cold)  median {mv:.3f} s  runs {[round(x, 3) for x in tv]}")
    print(f"ratio geoterrain / gdal: {mv / mg:.2f}  (load average {os.getloadavg()[0]:.1f}, "
          f"{len(os.sched_getaffinity(0))} cores)")
    ccg, ccv = statistics.median(cg), statistics.median(cv)
    print(f"CPU time (user + system), medians: gdal_viewshed {ccg:.3f} s, geoterrain "
          f"{ccv:.3f} s, ratio {ccv / ccg:.2f}")
    print(f"tiles: {s['tiles_in_window']} in the window, {s['tiles_read']} read, "
          f"{s['tiles_skipped']} skipped; {s['tiles_decoded']} decodes with ancestors, "
          f"{s['bytes_read']} bytes")
    print(f"visible {s['visible']}, hidden {s['hidden']}, uncertain {s['uncertain']}; "
          f"agreement with gdal_viewshed on {both.sum()} cells: {agree.mean() * 100:.4f} % "
          f"({(~agree).sum()} differ)")


if __name__ == "__main__":
    main()

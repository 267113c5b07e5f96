"""``chunked`` selection time on random oblique views, several seeds (issue 51).

Each seed draws ``--views`` views of the store: a target anywhere over the data, the
eye ``U(0.1, 0.5)`` of the extent away from it at an azimuth ``U(0, 360°)`` and a pitch
``U(3°, 60°)`` (looking down at the target), 1280×720, τ = 1 (``--tau``). Every view is
selected once cold (its chunks built and decoded), then ``--runs`` times warm; a view's
time is the median of its warm runs, in wall and in CPU time (``time.process_time``:
the machine is shared, so the CPU time says what the selection costs when a core is
free). Per seed: the median and p95 over the views, and
the cold pass's median. With ``--check N`` the first N views of each seed also get
their measured ρ (:func:`geoterrain.testing.measure.screen_space_error`, horizon
culling off) and uncovered samples.

    python benchmarks/bench_chunked.py STORE [--seeds 0,1,2,3] [--views 60] [--runs 3]

STORE: a ``.geoterrain`` store (``--synthetic 4097`` builds an fbm one, seed 1, into a
temporary folder instead).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.core.view import View


def oblique_views(terrain, n: int, seed: int, size=(1280, 720)) -> list[View]:
    """``n`` random oblique views of ``terrain`` (distances 0.1–0.5 of its extent,
    pitch 3°–60°), from ``seed``."""
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, np.float64) for b in terrain.scene_box())
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    X, Y = rng.uniform(lo[0], hi[0], n), rng.uniform(lo[1], hi[1], n)
    dist = rng.uniform(0.1, 0.5, n) * ext
    az = rng.uniform(0, 2 * np.pi, n)
    pitch = np.radians(rng.uniform(3.0, 60.0, n))
    views = []
    for k in range(n):
        at = np.array([X[k], Y[k], 0.5 * (lo[2] + hi[2])])
        eye = at + dist[k] * np.array([math.cos(pitch[k]) * math.cos(az[k]),
                                       math.cos(pitch[k]) * math.sin(az[k]),
                                       math.sin(pitch[k])])
        eye[2] = max(eye[2], hi[2] + 0.002 * ext)  # above every sample
        views.append(View(tuple(eye), tuple(at), size=size))
    return views


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store", nargs="?")
    ap.add_argument("--synthetic", type=int)
    ap.add_argument("--seeds", default="0,1,2,3")
    ap.add_argument("--views", type=int, default=60)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--strategy", default="chunked")
    ap.add_argument("--check", type=int, default=0, help="measure ρ on N views per seed")
    a = ap.parse_args()
    if a.synthetic:
        from geoterrain.ingest.synth import generate, write_geotiff

        d = Path(tempfile.mkdtemp())
        tif = write_geotiff(d / "fbm.tif", generate("fbm", a.synthetic, seed=1))
        a.store = str(geoterrain.preprocess(tif, d / "fbm.geoterrain"))
    t = geoterrain.open(a.store)
    XYZ = None
    print(f"{a.strategy}, τ = {a.tau:g}, {a.views} views per seed, 1280×720, "
          f"warm: median of {a.runs} runs per view\n")
    print("| seed | median ms | p95 ms | max ms | CPU median ms | CPU p95 ms | cold median ms "
          "| triangles median |" + (" ρ max | uncovered |" if a.check else ""))
    print("|---|---|---|---|---|---|---|---|" + ("---|---|" if a.check else ""))
    every, every_cpu = [], []
    for seed in (int(s) for s in a.seeds.split(",")):
        views = oblique_views(t, a.views, seed)
        cold, warm, tris = [], [], []
        for v in views:
            s = t.select(v, a.tau, a.strategy, reuse=False)
            cold.append(s.stats["select_ms"])
            tris.append(s.stats["triangles"])
        per_view = [[] for _ in views]
        per_cpu = [[] for _ in views]
        for _ in range(a.runs):  # interleaved: a busy moment spreads over the views
            for k, v in enumerate(views):
                t0, c0 = time.perf_counter(), time.process_time()
                t.select(v, a.tau, a.strategy, reuse=False)
                per_cpu[k].append((time.process_time() - c0) * 1e3)
                per_view[k].append((time.perf_counter() - t0) * 1e3)
        warm = [statistics.median(p) for p in per_view]
        cpu = [statistics.median(p) for p in per_cpu]
        every += warm
        every_cpu += cpu
        extra = ""
        if a.check:
            from geoterrain.testing.measure import screen_space_error

            if XYZ is None:
                XYZ = geoterrain.open(a.store).scene_xyz()
            X, Y, Z = XYZ
            rho, unc = 0.0, 0
            for v in views[:a.check]:
                s = t.select(v, a.tau, a.strategy, reuse=False, occlusion=False)
                f = s.surface_faces()
                e = screen_space_error(s.ij, f, np.asarray(s.mesh.points)[:, 2], X, Y, Z,
                                       np.isfinite(Z), v.eye, v.planes, v.lam)
                rho, unc = max(rho, e.max), unc + e.n_uncovered
            extra = f" {rho:.3f} | {unc} |"
        print(f"| {seed} | {statistics.median(warm):.2f} | {np.percentile(warm, 95):.2f} | "
              f"{max(warm):.2f} | {statistics.median(cpu):.2f} | {np.percentile(cpu, 95):.2f} | "
              f"{statistics.median(cold):.1f} | "
              f"{statistics.median(tris):.0f} |" + extra, flush=True)
    print(f"\nall seeds: median {statistics.median(every):.2f} ms, "
          f"p95 {np.percentile(every, 95):.2f} ms; CPU median {statistics.median(every_cpu):.2f} "
          f"ms, p95 {np.percentile(every_cpu, 95):.2f} ms; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

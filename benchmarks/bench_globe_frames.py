"""The globe flyover once, with each frame's ranges timed: the frame-time distribution and
where the worst frames' selection goes.

    python benchmarks/bench_globe_frames.py STORE.geoterrain OUT.json [--profile OUT.prof]

The flight of ``bench_globe.py --repeats 1 --size 640x360`` (τ = 1, rendered), plus, per
frame, ``vr_ms`` and ``vr_cpu_ms``: the wall and thread CPU time of the frame's
:meth:`~geoterrain.globe.errors.ErrorTable.view_ranges` (the ranges, part of ``select_ms``),
and ``select_cpu_ms``: the thread CPU time of the ranges and the quadtrees' traversal.
Writes the summary and every frame to OUT.json and prints the summary, the flight's wall
and CPU time, the load, and the eight frames with the largest selection share. To compare
two trees, put each on ``PYTHONPATH`` in turn from outside the checkout.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import time

import numpy as np

from geoterrain.bench.globeflight import flyover, run_flyover, summary
from geoterrain.globe import Globe, cdlod
from geoterrain.globe.errors import ErrorTable
from geoterrain.globe.nodes import encode, geometry, shell_distance


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("out")
    ap.add_argument("--profile", help="write a cProfile of the flight here")
    a = ap.parse_args()
    rec = []
    orig = ErrorTable.view_ranges

    def timed(self, *args, **kw):
        t0, c0 = time.perf_counter(), time.thread_time()
        r = orig(self, *args, **kw)
        rec.append(((time.perf_counter() - t0) * 1e3, (time.thread_time() - c0) * 1e3))
        return r

    ErrorTable.view_ranges = timed
    trav = []
    orig_t = cdlod._traverse

    def traverse(*args, **kw):
        c0 = time.thread_time()
        r = orig_t(*args, **kw)
        trav.append((time.thread_time() - c0) * 1e3)
        return r

    cdlod._traverse = traverse
    # compiled outside the flight
    shell_distance(np.full(3, 7e6), geometry(np.array([encode(0, 0, 0, 0)])), np.ones(1),
                   np.full(1, 2.0))
    with Globe([a.store]) as g:
        lon, lat = (float(np.mean(v)) for v in g.stores[0].footprint(16))
        views = flyover(g, lon, lat, fps=10.0, size=(640, 360))
        l0, c0, t0 = os.getloadavg()[0], time.process_time(), time.time()
        pr = cProfile.Profile() if a.profile else None
        if pr:
            pr.enable()
        frames = run_flyover(g, views, 1.0, render=True)
        if pr:
            pr.disable()
            pr.dump_stats(a.profile)
        wall, cpu = time.time() - t0, time.process_time() - c0
    for f, (w, c), tc in zip(frames, rec, trav, strict=False):
        f["vr_ms"], f["vr_cpu_ms"] = round(w, 3), round(c, 3)
        f["select_cpu_ms"] = round(c + tc, 3)  # the ranges' and the traversal's thread CPU
    s = summary(frames, 100.0)
    s.update(flight_wall_s=round(wall, 1), flight_cpu_s=round(cpu, 1),
             load=f"{l0:.2f}->{os.getloadavg()[0]:.2f}",
             vr_cpu_ms_total=round(sum(c for _, c in rec), 1),
             select_cpu_ms_max=max(f.get("select_cpu_ms", 0.0) for f in frames))
    with open(a.out, "w") as f:
        json.dump(dict(summary=s, frames=frames), f)
    print(json.dumps(s))
    keys = ("frame", "height_m", "frame_ms", "select_ms", "select_cpu_ms", "vr_ms",
            "vr_cpu_ms", "mesh_ms",
            "render_ms", "generation_ms", "nodes", "triangles")
    for f in sorted(frames, key=lambda f: -f["select_ms"] / max(f["frame_ms"], 1e-9))[:8]:
        print({k: f.get(k) for k in keys})


if __name__ == "__main__":
    main()

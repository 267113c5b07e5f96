"""Seed 001's flyover on the globe, repeated: medians of the per-run figures.

    python benchmarks/bench_globe.py STORE.geoterrain --repeats 3 --size 640x360

Equivalent to ``geoterrain bench --globe STORE --render`` run ``--repeats`` times in one
process (a fresh :class:`~geoterrain.globe.Globe` each run, so every run generates its
payloads again); prints each run's summary and the medians across runs. Without a store
it flies over the procedural planet.
"""

from __future__ import annotations

import argparse
import json
import statistics

import numpy as np

from geoterrain.bench.globeflight import flyover, run_flyover, summary
from geoterrain.globe import Globe


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store", nargs="?", help="a .geoterrain store (default: the procedural "
                    "planet)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--fps", type=float, default=10.0, help="frames a second of flight")
    ap.add_argument("--no-render", action="store_true")
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.lower().split("x"))
    budget = 1000.0 / a.fps
    runs = []
    for r in range(a.repeats):
        with Globe([a.store] if a.store else []) as g:
            if g.stores:
                lon, lat = (float(np.mean(v)) for v in g.stores[0].footprint(16))
            else:
                lon, lat = 139.25, 35.35
            views = flyover(g, lon, lat, fps=a.fps, size=size)
            frames = run_flyover(g, views, a.tau, render=not a.no_render)
        s = summary(frames, budget)
        print(f"run {r + 1}: {json.dumps(s)}", flush=True)
        runs.append(s)
    keys = [k for k, v in runs[0].items() if isinstance(v, int | float)]
    med = {k: statistics.median(s[k] for s in runs) for k in keys}
    print("median of runs: " + json.dumps(med))


if __name__ == "__main__":
    main()

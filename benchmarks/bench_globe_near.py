"""One converged globe view near the ground: triangles, nodes, select + generate time and
the worst measured ρ, at each τ on one globe (the first τ's payloads stay in its pool).

    python benchmarks/bench_globe_near.py STORE.geoterrain --alt 3 --pitch -3 --tau 4 1

The camera stands ``--alt`` metres above the store's ground at ``--at LON,LAT`` (default:
139.23,35.37, srtm1_japan's hills), heading ``--heading``, 320 × 240 px, n = 16 cells a
node; ``select(wait=True)`` generates every payload the view needs. ρ is measured by
:func:`geoterrain.testing.globemeasure.measured_rho` at the store's samples ``fine_border``
+ 1 in from its edge. Prints the load (1-minute average) before and after each view and
the process's CPU time beside the wall time: the machine is shared.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import geoterrain
from geoterrain.globe import Globe
from geoterrain.testing.globemeasure import measured_rho, store_truth


def _load() -> str:
    with open("/proc/loadavg") as f:
        return f.read().split()[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--alt", type=float, default=3.0)
    ap.add_argument("--pitch", type=float, default=-3.0)
    ap.add_argument("--heading", type=float, default=30.0)
    ap.add_argument("--at", default="139.23,35.37")
    ap.add_argument("--tau", type=float, nargs="+", default=[4.0, 1.0])
    a = ap.parse_args()
    lon, lat = (float(v) for v in a.at.split(","))
    t0, c0 = time.perf_counter(), time.process_time()
    with Globe([a.store], node_cells=16, sync=True) as g:
        print(f"globe made in {time.perf_counter() - t0:.1f} s ({time.process_time() - c0:.1f} s "
              f"CPU), load {_load()}", flush=True)
        with geoterrain.open(a.store) as t:
            truth = store_truth(t, int(np.ceil(g.surface.fine_border)) + 1)
        ground = float(g.surface.heights(np.array([lon]), np.array([lat]), g.max_depth)[0])
        for tau in a.tau:
            v = g.camera(lon, lat, ground + a.alt, a.heading, a.pitch, size=(320, 240))
            l0 = _load()
            t1, c1 = time.perf_counter(), time.process_time()
            sel = g.select(v, tau, wait=True)
            wall, cpu = time.perf_counter() - t1, time.process_time() - c1
            rho, n, out = measured_rho(sel, truth, v, truth.mean(0))
            print(f"tau {tau}: triangles {sel.triangles} nodes {sel.stats['nodes']} deepest "
                  f"{sel.stats['max_depth']}; select + generate {wall:.1f} s ({cpu:.1f} s CPU); "
                  f"worst rho {rho:.3f} px over {n} samples ({out} outside the mesh); load "
                  f"{l0} -> {_load()}", flush=True)


if __name__ == "__main__":
    main()

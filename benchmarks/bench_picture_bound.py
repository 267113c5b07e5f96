"""How far rtin's mesh moves the picture, on every view of bench_render.py's flights.

For each view, rtin's selection at τ (horizon culling off: the bound at every sample in
the frustum, hidden or not) is measured independently of the selection's formulas:
every level-0 sample under the drawn triangles whose true or drawn point lies in the
frustum (a sample just outside it drawn just inside counts) is projected through the
render's camera twice, at its true height and at the mesh's
(:func:`geoterrain.testing.measure.picture_displacement`), and the distance between the
two is its displacement in pixels. Both refinement metrics are measured in the same run:
``depth`` (the picture's bound, rtin's default) and ``distance`` (LP's eq. 2 as
published).

    PYTHONPATH=. python benchmarks/bench_picture_bound.py STORE [--views 24]
        [--flight approach|low] [--tau 1] [--metrics depth,distance] [--every 1]
        [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

import geoterrain
from geoterrain.lod import rtin
from geoterrain.testing.measure import picture_displacement

try:
    from bench_render import FLIGHTS
except ImportError:  # run as benchmarks/bench_picture_bound.py from the repository root
    import sys

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_render import FLIGHTS


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--flight", default="approach", choices=sorted(FLIGHTS))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--metrics", default="depth,distance")
    ap.add_argument("--every", type=int, default=1,
                    help="the metrics after the first on every N-th view only")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    load0 = os.getloadavg()[0]
    rows = []
    keep = rtin.DEPTH
    with geoterrain.open(a.store) as t:
        views = FLIGHTS[a.flight](t, a.views, size)
        X, Y, Z = t.scene_xyz()
        truth = (X, Y, Z, np.isfinite(Z))
        print(f"{a.flight} flight, {len(views)} views, {size[0]}×{size[1]}, τ = {a.tau:g}; "
              f"load average {load0:.2f} before")
        print("| view | metric | triangles | samples | largest displacement px | p99 | "
              "samples > τ | lift k |")
        print("|---|---|---:|---:|---:|---:|---:|---:|")
        try:
            for k, (name, v) in enumerate(views):
                v = v.clipped_to(*t.scene_box())  # the picture's own near and far planes
                for n, m in enumerate(a.metrics.split(",")):
                    if n and k % a.every:
                        continue
                    rtin.DEPTH = m == "depth"
                    t0 = time.process_time()
                    sel = t.select(v, a.tau, "rtin", occlusion=False, reuse=False)
                    z = np.asarray(sel.mesh.points)[:, 2]
                    e, disp = picture_displacement(sel.ij, sel.surface_faces(), z, *truth, v,
                                                   per_sample=True)
                    over = int(np.count_nonzero(disp > a.tau))
                    row = {"view": k, "name": name, "metric": m,
                           "triangles": sel.stats["triangles"], "samples": e.n_samples,
                           "max_px": e.max, "p99_px": e.p99, "over_tau": over,
                           "lift": v.lift, "cpu_s": time.process_time() - t0}
                    rows.append(row)
                    print(f"| {name} | {m} | {row['triangles']} | {e.n_samples} | "
                          f"{e.max:.3f} | {e.p99:.3f} | {over} | {v.lift:.3f} |", flush=True)
        finally:
            rtin.DEPTH = keep
    for m in a.metrics.split(","):
        r = [x for x in rows if x["metric"] == m]
        print(f"{m}: largest displacement {max(x['max_px'] for x in r):.3f} px over "
              f"{len(r)} views, samples > τ {sum(x['over_tau'] for x in r)}, triangles "
              f"{min(x['triangles'] for x in r)}–{max(x['triangles'] for x in r)}")
    print(f"load average {os.getloadavg()[0]:.2f} after")
    out = {"flight": a.flight, "tau": a.tau, "rows": rows}
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()

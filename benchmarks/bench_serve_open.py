"""What `geoterrain serve` pays before its first request for a store's quantized-mesh set:
every level's tiles (``layer.json``'s availability), against another checkout's code.

Since the served set became the written one over nodata, each level's tiles are found from
the level-0 validity through every tile's 129² lattice (and, on TIN tiles, the few tiles
with no cell of four valid samples are built); before, from the georeference alone. Each
run is a fresh process (``open_stores`` then every level's tiles), the two checkouts
alternated ``--repeats`` times in the same run; it prints the median process CPU time and
wall time of each, the level-0 tiles decoded, the tiles listed per level, the same-run
ratio and the load.

Run from the project root::

    python benchmarks/bench_serve_open.py STORE [STORE ...] --baseline ../main
        [--mesher tin] [--repeats 5]

A store with nodata (a DEM whose sea is nodata, say) is where the new work shows: tiles
with nodata in their footprint are decoded for their validity.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import geoterrain
from geoterrain.serve.app import open_stores
c0, w0 = time.process_time(), time.perf_counter()
st = open_stores([("s", sys.argv[3])], mesher=sys.argv[2])["s"]
q = st.qmesh
levels = [len(q.level_tiles(z)) for z in range(q.max_zoom + 1)]
print(json.dumps({"cpu": time.process_time() - c0, "wall": time.perf_counter() - w0,
                  "decoded": st.terrain.decoded_tiles, "levels": levels,
                  "module": geoterrain.__file__}))
"""


def one(tree: Path, mesher: str, store: str) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(tree), mesher, store],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--baseline", required=True, help="another checkout (its root folder)")
    ap.add_argument("--mesher", default="tin", choices=("tin", "rtin"))
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    trees = {"baseline": Path(a.baseline).resolve(), "this": ROOT}
    for store in a.stores:
        runs: dict[str, list[dict]] = {k: [] for k in trees}
        loads = []
        for _ in range(a.repeats):
            for k, tree in trees.items():  # alternated: both see the same load
                runs[k].append(one(tree, a.mesher, store))
                loads.append(os.getloadavg()[0])
        med = {k: {m: float(np.median([r[m] for r in v])) for m in ("cpu", "wall")}
               for k, v in runs.items()}
        print(f"{Path(store).name}, {a.mesher}, {a.repeats} runs each, load "
              f"{min(loads):.1f}-{max(loads):.1f}")
        for k, v in runs.items():
            assert Path(v[0]["module"]).resolve().is_relative_to(trees[k]), v[0]["module"]
            print(f"  {k:8s} cpu {med[k]['cpu']:.2f} s, wall {med[k]['wall']:.2f} s, "
                  f"level-0 tiles decoded {v[0]['decoded']}, tiles per level {v[0]['levels']}")
        print(f"  this / baseline: cpu {med['this']['cpu'] / med['baseline']['cpu']:.2f}x, "
              f"wall {med['this']['wall'] / med['baseline']['wall']:.2f}x")


if __name__ == "__main__":
    main()

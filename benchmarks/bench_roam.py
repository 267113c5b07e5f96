"""ROAM's per-frame work along a smooth flight, against a from-scratch selection.

The flight is :func:`geoterrain.bench.harness.glide` (100 frames, the eye moving 1 % of its
height above the terrain per frame). Each frame is selected twice, in the same run:
``roam`` from the last frame's mesh (its split and merge queues, deferred re-scoring),
and ``roam`` from the two base triangles (``select(..., fresh=True)`` on a state of its
own). Both give the same mesh (checked per frame). Times are the whole selection (the
queues, the mesh's arrays and the PolyData) and the queues alone (``roam_ms``).

Run from the project root::

    PYTHONPATH=. python benchmarks/bench_roam.py --size 2049 [--tau 8] [--frames 100]

It prints the medians and the ratio of the medians (incremental ÷ from scratch), the
median splits + merges per frame and the median triangles.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geoterrain  # noqa: E402
from geoterrain.bench.harness import extent, glide  # noqa: E402
from geoterrain.ingest.synth import generate, write_geotiff  # noqa: E402
from geoterrain.lod import roam  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store", nargs="?", help="a store (default: a synthetic fBm of --size)")
    ap.add_argument("--size", type=int, default=2049)
    ap.add_argument("--tau", type=float, default=8.0)
    ap.add_argument("--frames", type=int, default=100)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        store = a.store
        if store is None:
            dem = write_geotiff(Path(tmp) / "fbm.tif", generate("fbm", a.size, seed=7))
            store = geoterrain.preprocess(dem, Path(tmp) / "fbm.geoterrain")
        t = geoterrain.open(store)
        X, Y, Z = t.scene_xyz()
        views = [v for _, v in glide(*extent(X, Y, Z), n_frames=a.frames + 1,
                                     size=(1024, 768))]
        del X, Y, Z
        roam.select(t, views[0], a.tau)  # the first frame: the state starts
        roam.run(t, views[0], a.tau, occlusion=True, mode=0, incremental=True, fresh=True,
                 owner="bench.scratch")
        inc, scr, kinc, kscr, changed, tris = [], [], [], [], [], []
        for v in views[1:]:
            t0 = time.perf_counter()
            m1, s1 = roam.select(t, v, a.tau)
            inc.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            m2, s2 = roam.run(t, v, a.tau, occlusion=True, mode=0, incremental=True,
                              fresh=True, owner="bench.scratch")
            scr.append(time.perf_counter() - t0)
            assert m1.n_cells == m2.n_cells, "the two selections differ"
            kinc.append(s1["roam_ms"])
            kscr.append(s2["roam_ms"])
            changed.append(s1["splits"] + s1["merges"])
            tris.append(m1.n_cells)
        inc, scr = 1e3 * np.array(inc), 1e3 * np.array(scr)
        print(f"frames {len(inc)}, tau {a.tau:g}, triangles (median) {int(np.median(tris))}, "
              f"splits + merges per frame (median) {int(np.median(changed))}")
        print(f"whole selection ms (median): from the last frame {np.median(inc):.2f}, "
              f"from scratch {np.median(scr):.2f}, ratio {np.median(inc) / np.median(scr):.3f}")
        print(f"queues only ms (median): from the last frame {np.median(kinc):.2f}, "
              f"from scratch {np.median(kscr):.2f}, "
              f"ratio {np.median(kinc) / np.median(kscr):.3f}")
        t.close()


if __name__ == "__main__":
    main()

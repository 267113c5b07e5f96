"""Geometry clipmaps along flights: the triangles drawn per frame and the toroidal updates.

Two flights over a synthetic fBm: :func:`geoterrain.bench.harness.glide` (a straight low
pass, 1 % of the height per frame) and the thesis-style minute loop
(:func:`geoterrain.bench.experiments.minute_flight`). Per frame: the clipmap's triangles
before culling (``clipmap_triangles``), the mesh it draws with no culling (the same view
with no frustum planes, no horizon culling), the mesh drawn after the frustum and horizon
culling, and the heights and normals the toroidal buffers read (``samples_updated``,
``normals_updated``) against what the moved regions expose (the new region minus the old
one, per level, counted here from the regions alone).

Run from the project root::

    PYTHONPATH=. python benchmarks/bench_clipmap.py --size 2049 [--frames 100] [--store S]

It prints, per strategy and flight, each count's min / median / max and spread
((max − min) / median), and the updates against the exposed samples. ``--store`` reuses a
store preprocessed from the same DEM (``generate("fbm", size, seed=7)``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geoterrain  # noqa: E402
from geoterrain.bench.experiments import _NoCulling, minute_flight  # noqa: E402
from geoterrain.bench.harness import extent, glide  # noqa: E402
from geoterrain.ingest.synth import generate, write_geotiff  # noqa: E402
from geoterrain.lod import clipmaps, strategy_info  # noqa: E402


def exposed(before: dict, after: dict) -> int:
    """Samples in the new regions that the old ones of the same level did not hold."""
    n = 0
    for lv, (r0, r1, c0, c1) in after.items():
        rows, cols = np.arange(r0, r1 + 1), np.arange(c0, c1 + 1)
        if lv in before:
            q0, q1, p0, p1 = before[lv]
            old = ((rows >= q0) & (rows <= q1))[:, None] & ((cols >= p0) & (cols <= p1))[None]
            n += int((~old).sum())
        else:
            n += len(rows) * len(cols)
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2049)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--strategies", default="clipmap,clipmap_gpu,clipmap_bounded")
    ap.add_argument("--store", type=Path, default=None)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if a.store is not None:
            t = geoterrain.open(a.store)
        else:
            dem = write_geotiff(Path(tmp) / "fbm.tif", generate("fbm", a.size, seed=7))
            t = geoterrain.open(geoterrain.preprocess(dem, Path(tmp) / "fbm.geoterrain"))
        X, Y, Z = t.scene_xyz()
        lo, hi = extent(X, Y, Z)
        del X, Y, Z
        flights = {"glide": [v for _, v in glide(lo, hi, n_frames=a.frames, size=(1024, 768))],
                   "minute": [v for _, v in minute_flight(lo, hi, a.frames, warmup=False)]}
        for s in a.strategies.split(","):
            kind = {"clipmap": "clipmap", "clipmap_gpu": "gpu", "clipmap_bounded": "bounded"}[s]
            for name, views in flights.items():
                t.forget(f"{clipmaps.__name__}.state.{kind}.{clipmaps.N_DEFAULT}")
                drawn, geometry, whole, upd, want, levels = [], [], [], [], [], set()
                before = None
                fn = strategy_info(s).load()
                for v in views:
                    sel = t.select(v, 8.0, s, reuse=False)
                    st = sel.stats
                    nc = _NoCulling(v.look_from, v.look_at, v.up, v.fov_y_deg, v.size,
                                    v.near, v.far)
                    whole.append(fn(t, nc, 8.0, occlusion=False)[0].n_cells)
                    state = t.derived(f"{clipmaps.__name__}.state.{kind}.{clipmaps.N_DEFAULT}",
                                      dict)
                    now = {lv: (q.r0, q.r1, q.c0, q.c1) for lv, q in state["levels"].items()}
                    if before is not None:
                        upd.append(st["samples_updated"])
                        want.append(exposed(before, now))
                    before = now
                    drawn.append(st["triangles"])
                    geometry.append(st["clipmap_triangles"])
                    levels.add(st["levels"])
                print(f"{s} {name}: levels {sorted(levels)}")
                for what, c in (("before culling", geometry), ("drawn, no culling", whole),
                                ("drawn, culled", drawn)):
                    c = np.array(c)
                    print(f"   {what}: min/median/max {c.min()}/{int(np.median(c))}/{c.max()}"
                          f" spread {(c.max() - c.min()) / np.median(c):.3%}")
                print(f"   heights read per frame: median {int(np.median(upd))}, max "
                      f"{max(upd)}; exposed by the moves: {sum(want)} in all, read {sum(upd)}"
                      f"{'' if sum(want) == sum(upd) else '  (DIFFERENT)'}")
        t.close()


if __name__ == "__main__":
    main()

"""The draw with the terrain's faces turned away culled or drawn, same views, in turns.

Each view of a flight of ``bench_render.py`` is drawn as a frame
(:meth:`TerrainScene.frame`); where the scene culls the faces turned away from the eye
(:meth:`TerrainScene.cull_faces_turned_away`: the eye above the terrain, inside its
footprint), the same mesh and atlas are then re-drawn ``--turns`` times with the culling
off and on in turn, and the draw's process CPU (the software renderer's threads
included) is compared: medians per view, then over the views.

    PYTHONPATH=. python benchmarks/bench_backface.py STORE [--views 24]
        [--flight low|approach] [--size 1280x720] [--tau 1] [--turns 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import geoterrain
from geoterrain.rendering.scene import TerrainScene
from geoterrain.rendering.window import draw, pyvista_plotter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_render import FLIGHTS  # noqa: E402  (the flights of the frame benchmark)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--flight", default="low", choices=sorted(FLIGHTS))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--turns", type=int, default=5)
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    load0 = os.getloadavg()[0]
    rows = []
    with geoterrain.open(a.store) as t:
        views = FLIGHTS[a.flight](t, a.views, size)
        scene = TerrainScene(pyvista_plotter(size, "auto"), t)
        try:
            for k, (_, v) in enumerate(views):
                v = v.clipped_to(*t.scene_box())
                _, st = scene.frame(v, a.tau, "rtin")
                if not scene.cull_faces_turned_away(v):
                    continue
                ms: dict[bool, list[float]] = {False: [], True: []}
                for _ in range(a.turns):
                    for cull in (False, True):
                        scene.actor.GetProperty().SetBackfaceCulling(cull)
                        p0 = time.process_time()
                        draw(scene.plotter)
                        ms[cull].append((time.process_time() - p0) * 1e3)
                drawn, culled = statistics.median(ms[False]), statistics.median(ms[True])
                rows.append(
                    {
                        "view": k,
                        "triangles": st["triangles"],
                        "drawn_ms": drawn,
                        "culled_ms": culled,
                        "ratio": culled / drawn,
                    }
                )
        finally:
            scene.plotter.close()
    print(
        f"{a.flight} flight, {len(views)} views, {size[0]}×{size[1]}, τ = {a.tau:g}; "
        f"load average {load0:.2f} before, {os.getloadavg()[0]:.2f} after"
    )
    if not rows:
        print("no view culls its faces turned away")
        return {"rows": rows}
    print("| view | triangles | draw CPU ms, all faces | faces turned away culled | ratio |")
    print("|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['view']} | {r['triangles']} | {r['drawn_ms']:.1f} | {r['culled_ms']:.1f} | "
            f"{r['ratio']:.3f} |"
        )
    med = {k: statistics.median(r[k] for r in rows) for k in ("drawn_ms", "culled_ms", "ratio")}
    print(
        f"{len(rows)} of {len(views)} views culled; medians: {med['drawn_ms']:.1f} → "
        f"{med['culled_ms']:.1f} ms, ratio {med['ratio']:.3f} "
        f"({min(r['ratio'] for r in rows):.3f}–{max(r['ratio'] for r in rows):.3f})"
    )
    return {"rows": rows, "median": med}


if __name__ == "__main__":
    main()

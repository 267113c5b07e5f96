"""Draw time: seed 002's triangle strips against triangle lists, on the same selections,
in the same run (issue 52).

    PYTHONPATH=. python benchmarks/bench_strips.py STORE [--views 24] [--size 1280x720]
        [--tau 1] [--draws 7] [--rounds 3] [--json out.json]

The flight of ``benchmarks/bench_render.py`` (an approach from the overview to a low
oblique pass). For each view, rtin's selection at τ is made once and shown by two
offscreen scenes, one drawing triangle lists (the project's default), one drawing the
same triangles as strips (:mod:`geoterrain.lod.strips`: in the order seed 002's
refinement meets them, one vertex a triangle and a repeated one at each swap). Each
draw is the project's (``window.draw``: VTK's render, the picture read back), timed
``--draws`` times a round, the two scenes alternating, over ``--rounds`` rounds; the
first draw of a new mesh (its upload, VTK's own strips → triangles conversion) is
reported apart; which scene goes first alternates from view to view. Prints medians per
frame and the strips/lists ratio, with the strip counts (strips, strip vertices against
3 × triangles of the lists).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import geoterrain
from benchmarks.bench_render import flight
from geoterrain.rendering.scene import TerrainScene
from geoterrain.rendering.window import draw, pyvista_plotter


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--draws", type=int, default=7)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    load0 = os.getloadavg()[0]
    with geoterrain.open(a.store) as t:
        views = flight(t, a.views, size)
        scenes = {kind: TerrainScene(pyvista_plotter(size, "none"), t, strips=kind == "strips")
                  for kind in ("lists", "strips")}
        rows = []
        try:
            for k, (_, v) in enumerate(views):
                sel = t.select(v, a.tau, "rtin")
                first, warm = {}, {"lists": [], "strips": []}
                kinds = list(scenes) if k % 2 == 0 else list(scenes)[::-1]  # alternating
                for kind in kinds:
                    sc = scenes[kind]
                    sc.set_camera(v)
                    sc.update(sel, v)
                    t0 = time.perf_counter()
                    draw(sc.plotter)
                    first[kind] = (time.perf_counter() - t0) * 1e3
                for _ in range(a.rounds):
                    for kind in kinds:
                        sc = scenes[kind]
                        for _ in range(a.draws):
                            t0 = time.perf_counter()
                            draw(sc.plotter)
                            warm[kind].append((time.perf_counter() - t0) * 1e3)
                fd = scenes["strips"].mesh.field_data
                row = {"view": k, "triangles": int(sel.stats["triangles"]),
                       "strips": int(fd["strip_strips"][0]) if "strip_strips" in fd else 0,
                       "strip_vertices": int(fd["strip_strip_vertices"][0])
                       if "strip_strip_vertices" in fd else 0,
                       "degenerate": int(fd["strip_degenerate"][0])
                       if "strip_degenerate" in fd else 0,
                       **{f"{kind}_first_ms": first[kind] for kind in first},
                       **{f"{kind}_ms": statistics.median(warm[kind]) for kind in warm}}
                rows.append(row)
                print(f"view {k}: {row['triangles']} triangles, {row['strips']} strips; "
                      f"lists {row['lists_ms']:.2f} ms, strips {row['strips_ms']:.2f} ms",
                      flush=True)
        finally:
            for sc in scenes.values():
                sc.plotter.close()
    med = statistics.median
    out = {"views": len(rows), "size": size, "tau": a.tau, "load_before": load0,
           "load_after": os.getloadavg()[0], "rows": rows}
    print(f"\n{len(rows)} views, {size[0]}×{size[1]}, τ = {a.tau:g}, rtin; load average "
          f"{load0:.2f} before, {os.getloadavg()[0]:.2f} after, {os.cpu_count()} cores\n")
    print("| | lists | strips | strips / lists |\n|---|---|---|---|")
    for key, what in (("ms", "draw ms (median of the views' medians)"),
                      ("first_ms", "first draw of a mesh ms (upload)")):
        lv = med(r[f"lists_{key}"] for r in rows)
        sv = med(r[f"strips_{key}"] for r in rows)
        print(f"| {what} | {lv:.2f} | {sv:.2f} | {sv / lv:.3f} |")
    ratio = med(r["strips_ms"] / r["lists_ms"] for r in rows)
    print(f"| per-view ratio (median) | | | {ratio:.3f} |")
    tri = med(r["triangles"] for r in rows)
    print(f"\ntriangles per view (median) {tri:.0f}; strips {med(r['strips'] for r in rows):.0f}, "
          f"strip vertices / (3 × triangles) "
          f"{med(r['strip_vertices'] / (3 * r['triangles']) for r in rows):.3f}, degenerate "
          f"triangles / triangles {med(r['degenerate'] / r['triangles'] for r in rows):.3f}")
    out["ratio"] = ratio
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()

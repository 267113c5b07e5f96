"""Frame time (LOD selection + mesh update + render) per strategy over one flight.

Synthetic fbm DEMs (2049², 4097²), 1280×720, the same ≥ 20-view flight for every
strategy; medians and ratios to bruteforce, printed as markdown.

    python benchmarks/bench_render.py --sizes 2049 4097 --views 24
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.rendering import TerrainScene, _plotter, default_view
from geoterrain.synth import generate, write_geotiff
from geoterrain.view import View


def flight(t, n: int, size: tuple[int, int]) -> list[View]:
    """Approach from an overview, then a low pass across the terrain."""
    home = default_view(t, size, 190.0, 40.0)
    c, e = np.asarray(home.look_at), np.asarray(home.look_from)
    views = []
    for k in range(n):
        s = k / max(n - 1, 1)
        dist = 1.0 - 0.8 * s  # from the overview down to 20 % of its distance
        az = math.radians(190.0 + 120.0 * s)
        r = np.linalg.norm(e - c) * dist
        el = math.radians(40.0 - 25.0 * s)
        eye = c + r * np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el),
                                math.sin(el)])
        views.append(View(tuple(eye), tuple(c), fov_y_deg=30.0, size=size))
    return views


def store_for(n: int, workdir: Path) -> Path:
    store = workdir / f"fbm{n}.geoterrain"
    if not store.exists():
        dem = write_geotiff(workdir / f"fbm{n}.tif", generate("fbm", n, seed=2, relief=1500.0),
                            spacing=30.0)
        t0 = time.perf_counter()
        geoterrain.preprocess(dem, store)
        print(f"<!-- preprocess {n}²: {time.perf_counter() - t0:.1f} s -->")
    return store


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2049, 4097])
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--pixel-error", type=float, default=1.0)
    ap.add_argument("--shading", default="normals")
    ap.add_argument("--no-aa", action="store_true", help="Turn multisample anti-aliasing off.")
    ap.add_argument("--workdir", type=Path, default=Path(tempfile.gettempdir()) / "gt_bench")
    a = ap.parse_args()
    a.workdir.mkdir(parents=True, exist_ok=True)
    size = (1280, 720)
    print(f"{a.views} views, 1280×720, τ = {a.pixel_error:g} px, shading {a.shading}, "
          f"anti-aliasing {'off' if a.no_aa else 'on (MSAA)'}\n")
    print("| DEM | strategy | median frame ms | median select ms | median render ms | "
          "median triangles | frame ratio vs bruteforce |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for n in a.sizes:
        t = geoterrain.open(store_for(n, a.workdir))
        views = flight(t, a.views, size)
        scene = TerrainScene(_plotter(size, not a.no_aa), t, a.shading)
        scene.frame(views[0], a.pixel_error, "bruteforce")  # warm caches and the texture
        rows = {}
        for strat in ("bruteforce", "chunked", "rtin"):
            fr, se, re_, tr = [], [], [], []
            for v in views:
                _, st = scene.frame(v, a.pixel_error, strat)
                fr.append(st["frame_ms"])
                se.append(st["select_ms"])
                re_.append(st["render_ms"])
                tr.append(st["triangles"])
            rows[strat] = [float(np.median(x)) for x in (fr, se, re_, tr)]
        scene.plotter.close()
        base = rows["bruteforce"][0]
        for strat, (f, s, r, tri) in rows.items():
            print(f"| {n}² | {strat} | {f:.0f} | {s:.0f} | {r:.0f} | {tri:,.0f} | "
                  f"{f / base:.2f} |", flush=True)


if __name__ == "__main__":
    main()

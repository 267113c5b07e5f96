"""Frame time: selection + texture + draw over a flight, LOD against bruteforce, same run.

Each configuration (strategy × texture mode) gets its own offscreen scene and a
freshly opened store (an empty cache), and draws every view of the built-in
flight (an approach from the overview down to a low oblique pass, planned from
the stored tile bounds: nothing is decoded to plan it). ``frame_ms`` is what
:meth:`TerrainScene.frame` measures: selection, texture (per-view atlas or the
whole-DEM texture) and the draw with
read-back. The first frame of a configuration is reported apart (cold); the
medians are over the other, warm, frames. Bruteforce is drawn on every
``--brute-every``-th view only (each of its frames draws every level-0 tile), and
the LOD/bruteforce ratio and the pictures' PSNR against bruteforce's are taken over those
same views. The frame's CPU time (the
process's, the software renderer's threads included) is reported beside its wall
time, and the host's load average before and after: on a shared machine the wall
time of the same work moves with the load, its CPU time much less.

    PYTHONPATH=. python benchmarks/bench_render.py STORE [--views 24] [--size 1280x720]
        [--tau 1] [--flight approach|low|oblique] [--strategies rtin] [--brute-every 4] [--global]
        [--json out.json] [--pictures DIR]
        [--anti-aliasing auto|msaa|edges|fxaa|none] [--skip-bruteforce] [--overlap]
        [--reference DIR]

``--pictures DIR`` writes the compared views' pictures there as PNGs
(``STRATEGY_VIEW.png``, bruteforce's included), so two checkouts' pictures of the same
views can be compared; each strategy's PSNR against bruteforce is printed per view. With
``--skip-bruteforce`` it writes the strategies' pictures of the same views (every
``--brute-every``-th), and no PSNR is taken.
``--reference DIR`` takes bruteforce's pictures from such a folder instead of drawing
them again (bruteforce draws every level-0 tile: minutes a view on a 4097² store).

``--global`` adds the previous whole-DEM texture (``textures="global"``) as a
baseline measured in the same run.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time

import numpy as np

import geoterrain
from geoterrain.core.view import View
from geoterrain.rendering.antialias import ANTI_ALIASING
from geoterrain.rendering.scene import TerrainScene, default_view
from geoterrain.rendering.window import pyvista_plotter


def flight(t, n: int, size: tuple[int, int]) -> list[tuple[str, View]]:
    """Approach from an overview, then a low pass across the terrain (the flight of the
    earlier version of this script, so figures stay comparable)."""
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
        views.append((f"approach {k}", View(tuple(eye), tuple(c), fov_y_deg=30.0, size=size)))
    return views


def low_flight(t, n: int, size: tuple[int, int]) -> list[tuple[str, View]]:
    """A low, oblique pass that looks ahead over the terrain to its far side: the eye a
    quarter of the relief above the highest point, pitched 8° down, flying across the
    middle of the terrain from its south-west towards its north-east, turning 30°."""
    lo, hi = t.scene_box()
    c = (lo + hi) / 2
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    z = float(hi[2] + 0.25 * max(hi[2] - lo[2], 1.0))
    pitch = math.radians(8.0)
    views = []
    for k in range(n):
        s = k / max(n - 1, 1)
        eye = np.array([c[0] + ext * (-0.35 + 0.5 * s), c[1] + ext * (-0.35 + 0.5 * s), z])
        az = math.radians(30.0 + 30.0 * s)  # the heading, clockwise from north
        fwd = np.array([math.sin(az) * math.cos(pitch), math.cos(az) * math.cos(pitch),
                        -math.sin(pitch)])
        views.append((f"low {k}", View(tuple(eye), tuple(eye + 0.2 * ext * fwd),
                                       fov_y_deg=45.0, size=size)))
    return views


def oblique_flight(t, n: int, size: tuple[int, int]) -> list[tuple[str, View]]:
    """``n`` random oblique views (distances 0.1–0.5 of the extent, pitch 3°–60°,
    ``bench_chunked.oblique_views``, seed 0): held-out views, not a planned flight."""
    from bench_chunked import oblique_views

    return [(f"oblique {k}", v) for k, v in enumerate(oblique_views(t, n, 0, size))]


FLIGHTS = {"approach": flight, "low": low_flight, "oblique": oblique_flight}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio of two uint8 pictures, dB (inf where identical)."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def run_config(store: str, views, strategy: str, textures: str, tau: float, pick=None,
               anti_aliasing: str = "auto", keep=(), overlap: bool = False) -> dict:
    """Frame stats of one configuration over ``views`` (indices ``pick``), cold store; the
    pictures of the views in ``keep`` are kept (``"pictures"``, by view). ``overlap``:
    each view's selection and atlas made while the view before is drawn
    (:meth:`TerrainScene.frames`); a frame's time is then the interval between pictures."""
    t0 = time.perf_counter()
    with geoterrain.open(store) as t:
        scene = TerrainScene(pyvista_plotter(views[0][1].size, anti_aliasing), t, textures=textures)
        setup_ms = (time.perf_counter() - t0) * 1e3
        frames, pictures = [], {}
        try:
            todo = [k for k in range(len(views)) if pick is None or k in pick]
            for k, (img, st) in zip(todo, scene.frames([views[k][1] for k in todo], tau,
                                                       strategy, overlap=overlap), strict=True):
                kind = views[k][0]
                if overlap:  # the throughput: the time between pictures
                    st = {**st, "frame_ms": st["interval_ms"], "cpu_ms": st["interval_cpu_ms"]}
                if k in keep:
                    pictures[k] = img
                frames.append({"view": k, "kind": kind, **{key: st[key] for key in (
                    "frame_ms", "select_ms", "texture_ms", "render_ms", "cpu_ms",
                    "render_cpu_ms", "anti_aliasing", "triangles",
                    "tiles_decoded", "normals_decoded", "textures_built", "bytes_read",
                    "peak_rss_mb")}})
        finally:
            scene.plotter.close()
    return {"strategy": strategy, "textures": textures, "anti_aliasing": anti_aliasing,
            "setup_ms": round(setup_ms, 1),
            "frames": frames, "pictures": pictures}


def _med(frames, key="frame_ms", views=None) -> float:
    vals = [f[key] for f in frames if views is None or f["view"] in views]
    return statistics.median(vals) if vals else float("nan")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--flight", default="approach", choices=sorted(FLIGHTS),
                    help="approach (the default: from the overview down to a low pass) or "
                    "low (a low, oblique pass looking ahead over the terrain) or oblique "
                    "(random views, bench_chunked's generator, seed 0)")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--strategies", default="rtin")
    ap.add_argument("--brute-every", type=int, default=4)
    ap.add_argument("--global", dest="glob", action="store_true")
    ap.add_argument("--anti-aliasing", default="auto", choices=ANTI_ALIASING,
                    help="auto (the default: edges where a frame's silhouettes are sparse, "
                    "else msaa); msaa: the renderer's multisampling; edges: the mesh's "
                    "silhouette edges blended by their coverage (geoterrain.rendering.edgeaa); "
                    "fxaa: the CPU pass over the read-back picture "
                    "(geoterrain.rendering.antialias); "
                    "none")
    ap.add_argument("--skip-bruteforce", action="store_true")
    ap.add_argument("--overlap", action="store_true",
                    help="make each view's selection and atlas on a worker thread while the "
                    "view before is drawn (TerrainScene.frames); the warm frame is then the "
                    "time between pictures (bruteforce is drawn without)")
    ap.add_argument("--json")
    ap.add_argument("--pictures", help="write the compared views' pictures (every "
                    "--brute-every-th view) to this folder; with --skip-bruteforce, the "
                    "strategies' pictures only")
    ap.add_argument("--reference", help="compare with bruteforce's pictures in this folder "
                    "(written by --pictures) instead of drawing bruteforce")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    load0 = os.getloadavg()[0]
    with geoterrain.open(a.store) as t:
        views = FLIGHTS[a.flight](t, a.views, size)
    brute_views = set(range(0, len(views), max(1, a.brute_every)))
    reference = None
    if a.reference:  # bruteforce's pictures of an earlier run (they depend on no LOD)
        from PIL import Image

        reference = {k: np.asarray(Image.open(os.path.join(
            a.reference, f"bruteforce_{k:02d}.png")).convert("RGB")) for k in brute_views}
        a.skip_bruteforce = True
    runs = []
    for s in a.strategies.split(","):
        runs.append(run_config(a.store, views, s, "view", a.tau, None, a.anti_aliasing,
                               () if a.skip_bruteforce and reference is None and not a.pictures
                               else brute_views,
                               a.overlap))
        if a.glob:
            runs.append(run_config(a.store, views, s, "global", a.tau, None, a.anti_aliasing))
    brute = None
    bmed = float("nan")
    if not a.skip_bruteforce:
        brute = run_config(a.store, views, "bruteforce", "view", a.tau, brute_views,
                           a.anti_aliasing, brute_views)
        runs.append(brute)
        bmed = _med(brute["frames"])
    print(f"{a.flight} flight, {len(views)} views, {size[0]}×{size[1]}, τ = {a.tau:g}, "
          f"anti-aliasing {a.anti_aliasing}{', overlapped' if a.overlap else ''}; bruteforce on "
          f"{0 if brute is None else len(brute_views)} of them; "
          f"load average {load0:.2f} before, {os.getloadavg()[0]:.2f} after, "
          f"{os.cpu_count()} cores")
    print("| strategy | textures | setup ms | cold frame ms | warm frame ms (median) | "
          "select | texture | draw | frame CPU ms | draw CPU ms | "
          "ratio to bruteforce (same views) | PSNR to bruteforce, dB (min, median) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        fr = r["frames"]
        warm = fr[1:] if len(fr) > 1 else fr
        ratio = bmed / _med(fr, views=brute_views) if r is not brute else 1.0
        r["summary"] = {"cold_frame_ms": fr[0]["frame_ms"], "warm_frame_ms": _med(warm),
                        "select_ms": _med(warm, "select_ms"),
                        "texture_ms": _med(warm, "texture_ms"),
                        "render_ms": _med(warm, "render_ms"), "cpu_ms": _med(warm, "cpu_ms"),
                        "render_cpu_ms": _med(warm, "render_cpu_ms"),
                        "ratio_to_bruteforce": ratio}
        sm = r["summary"]
        ref = brute["pictures"] if brute is not None else reference
        db = [psnr(p, ref[k]) for k, p in r["pictures"].items()] \
            if ref is not None and r is not brute else []
        sm["psnr_to_bruteforce"] = db
        dbs = f"{min(db):.1f}, {statistics.median(db):.1f}" if db else ""
        print(f"| {r['strategy']} | {r['textures']} | {r['setup_ms']:.0f} | "
              f"{sm['cold_frame_ms']:.0f} | {sm['warm_frame_ms']:.0f} | {sm['select_ms']:.0f} | "
              f"{sm['texture_ms']:.0f} | {sm['render_ms']:.0f} | {sm['cpu_ms']:.0f} | "
              f"{sm['render_cpu_ms']:.0f} | {ratio:.1f}× | {dbs} |")
    for r in runs:
        db = r["summary"]["psnr_to_bruteforce"]
        if db:
            print(f"{r['strategy']} PSNR to bruteforce by view: " + ", ".join(
                f"{k}: {d:.2f}" for k, d in zip(r["pictures"], db, strict=True)) + " dB")
        if a.pictures:
            from PIL import Image

            os.makedirs(a.pictures, exist_ok=True)
            for k, img in r["pictures"].items():
                Image.fromarray(img).save(os.path.join(a.pictures,
                                                       f"{r['strategy']}_{k:02d}.png"))
        r.pop("pictures")
    out = {"views": len(views), "size": list(size), "tau": a.tau, "runs": runs}
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()

"""Geometry clipmaps along flights: the triangles drawn per frame, the toroidal updates, and
what the steady count costs a CPU renderer.

Two flights over a synthetic fBm: :func:`geoterrain.bench.harness.glide` (a straight low
pass, 1 % of the height per frame) and the thesis-style minute loop
(:func:`geoterrain.bench.experiments.minute_flight`), both at a constant height above the
highest terrain. The arms:

- ``clipmap``: the registered strategy as it is (whole rings, no culling);
- ``clipmap:cull``: ``clipmap`` with ``cull=True`` (the paper's 4 rectangles per level
  against the frustum and the horizon, §2.9);
- ``clipmap_gpu``: its footprints, each culled (§2.10);
- ``clipmap_bounded`` (ask for it: it draws millions of triangles at τ = 8 px here).

Per frame and arm: the clipmap's triangles before culling (``clipmap_triangles``), the
triangles of the mesh it draws (the mesh's own cells, not its stats), for the culling arms
also the mesh drawn with no culling at all (the same view with no frustum planes and no
horizon culling), and the heights the toroidal buffers read (``samples_updated``) against
what the moved regions expose (the new region minus the old one, per level, counted here
from the regions alone). Each arm keeps its own buffers (its own state).

The frame cost (``--time``): ``clipmap`` and ``clipmap:cull`` each select and then draw
every frame on a scene of their own (1024 × 768, one anti-aliasing mode for both), in
turns (the arm that goes first alternates frame by frame), measured in CPU time (the
process's, every thread) and wall time; the first frame of each flight (the buffers
filled whole, the kernels compiled) is left out. Select: the strategy's ``select`` and the
elevation array; draw: :meth:`geoterrain.rendering.scene.TerrainScene.draw` (the view's
texture, the VTK update, the render and the read-back).

Run from the project root::

    PYTHONPATH=. python benchmarks/bench_clipmap.py --size 2049 [--frames 100] [--time]
        [--strategies clipmap,clipmap:cull,clipmap_gpu] [--anti-aliasing msaa] [--store S]

It prints the load average before and after, per arm and flight each count's min / median
/ max and spread ((max − min) / median), and the updates against the exposed samples;
with ``--time``, per flight the medians of select, draw and frame (CPU and wall) for both
arms and their ratio (``cull=True`` ÷ default, same run). ``--store`` reuses a store
preprocessed from the same DEM (``generate("fbm", size, seed=7)``).
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
from geoterrain.bench.experiments import _NoCulling, minute_flight  # noqa: E402
from geoterrain.bench.harness import _renderer, extent, glide  # noqa: E402
from geoterrain.ingest.synth import generate, write_geotiff  # noqa: E402
from geoterrain.lod import Selection, clipmaps, strategy_info  # noqa: E402
from geoterrain.lod.mesh import add_elevation  # noqa: E402
from geoterrain.rendering.scene import io_counters  # noqa: E402

#: arm → (strategy, its select's options, clipmaps' kind)
ARMS = {"clipmap": ("clipmap", {}, "clipmap"),
        "clipmap:cull": ("clipmap", {"cull": True}, "clipmap"),
        "clipmap_gpu": ("clipmap_gpu", {}, "gpu"),
        "clipmap_bounded": ("clipmap_bounded", {}, "bounded")}
TAU = 8.0
SIZE = (1024, 768)


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


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


def spread_line(what: str, c) -> str:
    c = np.asarray(c)
    return (f"   {what}: min/median/max {c.min()}/{int(np.median(c))}/{c.max()}"
            f" spread {(c.max() - c.min()) / np.median(c):.3%}")


def counts(t, arm: str, views: list) -> None:
    """One arm along one flight: the counts per frame, printed."""
    strategy, opts, kind = ARMS[arm]
    key = clipmaps.state_key(kind, clipmaps.N_DEFAULT, opts.get("cull"))
    t.forget(key)
    fn = strategy_info(strategy).load()
    culls = kind != "clipmap" or opts.get("cull", False)
    drawn, geometry, whole, upd, want, levels = [], [], [], [], [], set()
    before = None
    for v in views:
        mesh, st = fn(t, v, TAU, **opts)
        if culls:
            nc = _NoCulling(v.look_from, v.look_at, v.up, v.fov_y_deg, v.size, v.near, v.far)
            whole.append(fn(t, nc, TAU, occlusion=False, **opts)[0].n_cells)
        state = t.derived(key, dict)
        now = {lv: (q.r0, q.r1, q.c0, q.c1) for lv, q in state["levels"].items()}
        if before is not None:
            upd.append(st["samples_updated"])
            want.append(exposed(before, now))
        before = now
        drawn.append(mesh.n_cells)
        geometry.append(st["clipmap_triangles"])
        levels.add(st["levels"])
    print(f"{arm}: levels {sorted(levels)}")
    print(spread_line("before culling", geometry))
    if culls:
        print(spread_line("drawn, no culling", whole))
    print(spread_line("drawn" + (", culled" if culls else " (whole rings)"), drawn))
    print(f"   heights read per frame: median {int(np.median(upd))}, max "
          f"{max(upd)}; exposed by the moves: {sum(want)} in all, read {sum(upd)}"
          f"{'' if sum(want) == sum(upd) else '  (DIFFERENT)'}")


def timed(t, views: list, anti_aliasing: str) -> None:
    """``clipmap`` and ``clipmap:cull`` in turns along one flight: select + draw."""
    arms = ("clipmap", "clipmap:cull")
    fn = strategy_info("clipmap").load()
    scenes, got = {}, {}
    for arm in arms:
        t.forget(clipmaps.state_key("clipmap", clipmaps.N_DEFAULT, ARMS[arm][1].get("cull")))
        scenes[arm] = _renderer(SIZE, t, anti_aliasing, True, None)
        got[arm] = {k: [] for k in ("sel_cpu", "draw_cpu", "cpu", "sel_wall", "wall", "tris")}
    aa = set()
    for k, v in enumerate(views):
        v = v.clipped_to(*t.scene_box())
        for arm in (arms if k % 2 == 0 else arms[::-1]):
            w0, p0 = time.perf_counter(), time.process_time()
            mesh, stats = fn(t, v, TAU, **ARMS[arm][1])
            add_elevation(mesh, t.frame.z_scale)
            w1, p1 = time.perf_counter(), time.process_time()
            _, rs = scenes[arm].draw(Selection(mesh, stats), v, (w0, p0, io_counters(t)))
            p2 = time.process_time()
            aa.add(rs["anti_aliasing"])
            if k == 0:
                continue  # the buffers filled whole, the kernels compiled
            g = got[arm]
            g["sel_cpu"].append((p1 - p0) * 1e3)
            g["draw_cpu"].append((p2 - p1) * 1e3)
            g["cpu"].append((p2 - p0) * 1e3)
            g["sel_wall"].append((w1 - w0) * 1e3)
            g["wall"].append(rs["frame_ms"])
            g["tris"].append(mesh.n_cells)
    for s in scenes.values():
        s.plotter.close()
    med = {a: {k: float(np.median(x)) for k, x in g.items()} for a, g in got.items()}
    print(f"   frame cost, medians over {len(views) - 1} frames (anti-aliasing "
          f"{', '.join(sorted(aa))}):")
    for a in arms:
        m = med[a]
        print(f"   {a:13s} triangles {int(m['tris'])}: CPU select {m['sel_cpu']:.1f}, draw "
              f"{m['draw_cpu']:.1f}, frame {m['cpu']:.1f} ms; wall select "
              f"{m['sel_wall']:.1f}, frame {m['wall']:.1f} ms (each a median)")
    a, b = med["clipmap:cull"], med["clipmap"]
    print(f"   cull=True / default: CPU select {a['sel_cpu'] / b['sel_cpu']:.2f}x, draw "
          f"{a['draw_cpu'] / b['draw_cpu']:.2f}x, frame {a['cpu'] / b['cpu']:.2f}x; wall "
          f"frame {a['wall'] / b['wall']:.2f}x")
    ratio = np.array(got["clipmap:cull"]["cpu"]) / np.array(got["clipmap"]["cpu"])
    print(f"   per-frame CPU ratio cull=True / default: min/median/max {ratio.min():.2f}/"
          f"{np.median(ratio):.2f}/{ratio.max():.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2049)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--strategies", default="clipmap,clipmap:cull,clipmap_gpu",
                    help=f"arms, comma-separated: {', '.join(ARMS)}")
    ap.add_argument("--time", action="store_true",
                    help="also the frame cost of clipmap against clipmap:cull (select + draw)")
    ap.add_argument("--anti-aliasing", default="msaa", choices=("msaa", "none", "fxaa"))
    ap.add_argument("--store", type=Path, default=None)
    a = ap.parse_args()
    arms = [s.strip() for s in a.strategies.split(",") if s.strip()]
    bad = [s for s in arms if s not in ARMS]
    if bad:
        ap.error(f"unknown arm {', '.join(bad)}; use {', '.join(ARMS)}")
    print(f"load average before: {load()}  ({time.strftime('%Y-%m-%d %H:%M:%S %Z')})")
    with tempfile.TemporaryDirectory() as tmp:
        if a.store is not None:
            t = geoterrain.open(a.store)
        else:
            dem = write_geotiff(Path(tmp) / "fbm.tif", generate("fbm", a.size, seed=7))
            t = geoterrain.open(geoterrain.preprocess(dem, Path(tmp) / "fbm.geoterrain"))
        X, Y, Z = t.scene_xyz()
        lo, hi = extent(X, Y, Z)
        del X, Y, Z
        flights = {"glide": [v for _, v in glide(lo, hi, n_frames=a.frames, size=SIZE)],
                   "minute": [v for _, v in minute_flight(lo, hi, a.frames, size=SIZE,
                                                          warmup=False)]}
        for name, views in flights.items():
            print(f"== {name} ({len(views)} frames), load {load()}")
            for arm in arms:
                counts(t, arm, views)
            if a.time:
                timed(t, views, a.anti_aliasing)
                print(f"   load after timing: {load()}")
        t.close()
    print(f"load average after: {load()}  ({time.strftime('%Y-%m-%d %H:%M:%S %Z')})")


if __name__ == "__main__":
    main()

"""The interactive viewer's responsiveness, measured through its controller.

Drives :class:`geoterrain.rendering.viewer.ViewerController` in background mode (the viewer's
default: selection and textures in a worker thread) on an offscreen window, over
``bench_render.flight`` (an approach from the overview to a low pass). Per camera move:

- **UI block**: while the worker selects and builds textures, the main thread ticks
  at the viewer's polling period (``ViewerController.poll_ms``, 4 ms while a frame is
  in flight, calling ``poll`` as the window's timers do); the largest gap between two
  ticks beyond that period is the longest the window could not answer (the GIL held by
  the worker).
- **swap**: the main thread's time to swap the finished mesh and textures into VTK
  (``ViewerController.ui_ms``).
- **draw**: the render that shows it (without multisampling while the camera moves).
- **frame**: from the camera move to the picture on screen (worker + the wait for the
  next tick + swap + draw). A move may shade at most ``viewer.TEXTURE_BUILDS`` texture
  tiles before it is shown; the others are magnified from cached coarser tiles, and
  the passes that follow shade them while the camera is still. The script waits for
  those passes before the next move and reports when the last one was shown
  (``complete``).

After the flight the camera rests and the still picture, drawn again with the window's
anti-aliasing, is timed too (``still``).

The issue's targets: the UI thread never blocked more than 50 ms by selection or
texture work, and a frame ≤ 150 ms (4097², τ = 1, 1280×720).

    PYTHONPATH=. python benchmarks/bench_viewer.py STORE [--views 24] [--tau 1]
        [--strategy rtin] [--size 1280x720]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).parent))

from bench_render import flight  # noqa: E402

import geoterrain  # noqa: E402
from geoterrain.rendering.viewer import REST_MS, ViewerController  # noqa: E402
from geoterrain.rendering.window import pyvista_plotter


def move(c: ViewerController, view) -> dict:
    """Point the camera at ``view`` and tick the main thread until the picture is shown."""
    cam = c.plotter.camera
    t0 = time.perf_counter()
    cam.position, cam.focal_point, cam.up = view.look_from, view.look_at, view.up
    cam.view_angle = view.fov_y_deg
    c.on_camera_changed(force=True)
    gaps, last, t_done = [], time.perf_counter(), None
    while True:
        tick = c.poll_ms / 1e3
        time.sleep(tick)
        now = time.perf_counter()
        gaps.append(now - last - tick)
        last = now
        if t_done is None and c._future is not None and c._future.done():
            t_done = now  # (the worker finished at most a tick ago)
        if c.poll():  # the swap and the draw, on this (the main) thread
            t1 = time.perf_counter()
            break
    row = {"frame_ms": (t1 - t0) * 1e3, "worker_ms": (t_done - t0) * 1e3,
           "swap_ms": c.ui_ms, "draw_ms": c.frame_ms - c.ui_ms,
           "stand_ins": c._deferred, "triangles": c.stats.get("triangles", 0)}
    # the textures' refinement passes (stand-in tiles shaded), still ticking the UI
    passes, t2, last = 0, t1, t1
    while c._future is not None:
        tick = c.poll_ms / 1e3
        time.sleep(tick)
        now = time.perf_counter()
        gaps.append(now - last - tick)
        if c.poll():  # a pass's swap and draw (not selection or texture work: not a gap)
            passes, t2 = passes + 1, time.perf_counter()
        last = time.perf_counter()
    row.update(complete_ms=(t2 - t0) * 1e3, passes=passes,
               ui_block_ms=max(max(gaps, default=0.0), 0.0) * 1e3)
    return row


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--strategy", default="rtin")
    ap.add_argument("--size", default="1280x720")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    rows = []
    with geoterrain.open(a.store) as t:
        views = flight(t, a.views, size)
        p = pyvista_plotter(size)
        c = ViewerController(p, t, strategy=a.strategy, pixel_error=a.tau, background=True)
        p.show(auto_close=False)  # the window is up: from now on render() draws
        try:
            for _, v in views:
                rows.append(move(c, v))
            time.sleep(REST_MS / 1e3)  # the camera rests: drawn again, anti-aliased
            c.poll()
            still = getattr(c, "still_ms", float("nan"))
        finally:
            c.close()
            p.close()
    warm = rows[1:] if len(rows) > 1 else rows

    def med(k):
        return statistics.median(r[k] for r in warm)

    print(f"{Path(a.store).name}: {len(rows)} camera moves, {size[0]}×{size[1]}, "
          f"τ = {a.tau:g}, {a.strategy}, background selection")
    print("| | frame ms | worker (select + texture) ms | swap ms | draw ms | UI block ms |")
    print("|---|---|---|---|---|---|")
    r0 = rows[0]
    print(f"| first move (cold) | {r0['frame_ms']:.0f} | {r0['worker_ms']:.0f} | "
          f"{r0['swap_ms']:.1f} | {r0['draw_ms']:.0f} | {r0['ui_block_ms']:.1f} |")
    print(f"| median of the rest | {med('frame_ms'):.0f} | {med('worker_ms'):.0f} | "
          f"{med('swap_ms'):.1f} | {med('draw_ms'):.0f} | {med('ui_block_ms'):.1f} |")
    mx = {k: max(r[k] for r in warm) for k in ("frame_ms", "worker_ms", "swap_ms", "draw_ms",
                                                 "ui_block_ms")}
    print(f"| max of the rest | {mx['frame_ms']:.0f} | {mx['worker_ms']:.0f} | "
          f"{mx['swap_ms']:.1f} | {mx['draw_ms']:.0f} | {mx['ui_block_ms']:.1f} |")
    f = np.array([r["frame_ms"] for r in warm])
    print(f"frames ≤ 150 ms: {int((f <= 150).sum())} of {len(f)}; UI blocks ≤ 50 ms: "
          f"{sum(r['ui_block_ms'] <= 50 for r in rows)} of {len(rows)}; the still picture "
          f"(anti-aliased, after {REST_MS:.0f} ms at rest): {still:.0f} ms")
    refined = [r for r in warm if r["passes"]]
    print(f"moves shown with stand-in textures: {len(refined)} of {len(warm)}"
          + (f" ({sum(r['stand_ins'] for r in refined)} tiles); all textures shaded "
             f"{statistics.median(r['complete_ms'] for r in refined):.0f} ms (median) / "
             f"{max(r['complete_ms'] for r in refined):.0f} ms (max) after the move, in "
             f"{max(r['passes'] for r in refined)} passes at most" if refined else ""))
    return rows


if __name__ == "__main__":
    main()

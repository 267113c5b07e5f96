"""Seed 001's flyover benchmark on the globe (the seed summary's §3, thesis L497).

The camera starts outside the atmosphere, approaches the terrain fast, holds still, passes
over the mountains, rises slowly and stops higher, then leaves fast, ending on a wide view
of the planet. The flight is sampled at ``fps`` frames per second of flight time and run
frame after frame as fast as the machine goes, with the globe's asynchronous request
queue (payloads generated on worker threads, at most ``budget`` dispatches a frame and
``concurrent`` generations at once; the parent drawn while its children are pending), as
an interactive window would run it.

Each frame records (milliseconds): ``select_ms`` (the quadtrees' traversal, culling and
ranges: seed 001's *node selection*), ``mesh_ms`` (the per-vertex morph and the frame's
eye-relative float32 mesh: the seed's vertex shader, done here on the CPU),
``generation_ms`` (the main thread's own time on payloads: installing the finished ones
into the pool, plus any generated in the caller: none with the queue), ``other_ms`` (the
rest of the select call: dispatching, and waiting for the interpreter while the worker
threads run Python code), ``worker_ms`` (the generations'
own time on the worker threads, collected this frame), ``render_ms`` (VTK draws the mesh
and the picture is read back), ``frame_ms`` (all of it: the select call and the render);
and ``nodes``, ``triangles``, ``pending``, ``dispatched``, ``pop_px`` and, every
``measure_every`` frames over a store, the measured ``rho_px``.

**Pop** is what a payload's late arrival costs: a node drawn this frame whose parent was
drawn whole the frame before (its payload arrived) appears at its morph factor k, not at
the parent's surface (k = 1); each vertex jumps (1 − k)·|rT − r| along its ray. ``pop_px``
is the largest such jump on screen (λ·jump / distance). CDLOD's own transitions (morphs
completed before a switch) pop 0 px.

**Measured ρ** is :func:`geoterrain.testing.globemeasure.measured_rho`: the store's own
heights placed by pyproj, against the drawn mesh, with no globe code in between.

Examples
--------
>>> from geoterrain.globe import Globe
>>> g = Globe(model="sphere", base="ellipsoid", node_cells=8)
>>> views = flyover(g, 10.0, 45.0, fps=1.0, size=(64, 48))
>>> len(views), views[0][0], views[-1][0]
(25, 0.0, 24.0)
>>> frames = run_flyover(g, views[:3], render=False)
>>> frames[2]["nodes"] > 0, sorted(frames[0])[:3]
(True, ['dispatched', 'frame', 'frame_ms'])
>>> g.close()
"""

from __future__ import annotations

import math
import time

import numpy as np

from geoterrain.core.view import View

__all__ = ["KEYFRAMES", "flyover", "run_flyover", "summary"]

# (time s, Δlon°, Δlat° from the target, height, heading°, pitch°); a height under 1e5 m is
# above the ground under the camera, over it above the ellipsoid (seed L497's six phases)
KEYFRAMES = (
    (0.0, 0.0, -8.0, 2.0e7, 0.0, -90.0),     # 1. outside the atmosphere
    (5.0, 0.0, -0.20, 3000.0, 0.0, -25.0),   # 2. a fast approach
    (8.0, 0.0, -0.20, 3000.0, 0.0, -25.0),   # 3. holding still
    (13.0, 0.0, 0.12, 1500.0, 0.0, -20.0),   # 4. over the mountains
    (18.0, 0.0, 0.25, 4.0e4, 0.0, -45.0),    # 5. rising slowly
    (20.0, 0.0, 0.25, 4.0e4, 0.0, -45.0),    #    and stopping higher
    (24.0, 0.0, 0.25, 2.5e7, 0.0, -90.0),    # 6. leaving fast: the whole planet
)
GROUND = 1.0e5  # a key height under this is above the ground


def _ease(x: float) -> float:
    return x * x * (3 - 2 * x)


def flyover(globe, lon: float, lat: float, *, fps: float = 10.0,
            size: tuple[int, int] = (640, 360), fov_y_deg: float = 30.0
            ) -> list[tuple[float, View]]:
    """The flyover's views around ``lon``, ``lat`` (degrees), one every 1/``fps`` s of
    flight: (time, :class:`~geoterrain.core.view.View`). Heights are interpolated
    geometrically between the keys (a fast approach slows down near the ground), and never
    fall below 20 m above the ground."""
    n = int(round(KEYFRAMES[-1][0] * fps)) + 1
    out = []
    ts = np.array([k[0] for k in KEYFRAMES])

    def ground(lo, la):
        return float(globe.surface.heights(np.array([lo]), np.array([la]),
                                           globe.max_depth)[0])

    for i in range(n):
        t = i / fps
        j = min(int(np.searchsorted(ts, t, side="right")) - 1, len(ts) - 2)
        a, b = KEYFRAMES[j], KEYFRAMES[j + 1]
        x = _ease((t - a[0]) / (b[0] - a[0]))
        lo = lon + a[1] + x * (b[1] - a[1])
        la = lat + a[2] + x * (b[2] - a[2])
        g = ground(lo, la)
        g = g if math.isfinite(g) else 0.0
        ha, hb = (k[3] + (g if k[3] < GROUND else 0.0) for k in (a, b))
        h = math.exp(math.log(max(ha, 1.0)) * (1 - x) + math.log(max(hb, 1.0)) * x)
        h = max(h, g + 20.0)
        heading = a[4] + x * (b[4] - a[4])
        pitch = a[5] + x * (b[5] - a[5])
        out.append((t, globe.camera(lo, la, h, heading, pitch, size, fov_y_deg)))
    return out


def _pop_px(globe, sel, view: View, prev_whole: set[int]) -> tuple[float, int]:
    """The largest on-screen jump of a node swapped in for its parent this frame, and how
    many nodes were swapped in."""
    pool, pays = globe.nodes, globe.payloads
    rows = np.asarray(sel.rows, np.int64)
    if not len(rows) or not prev_whole:
        return 0.0, 0
    parent = pool.parent[rows]
    new = np.flatnonzero(np.isin(parent, np.fromiter(prev_whole, np.int64)))
    if not len(new):
        return 0.0, 0
    V = pays.vertices
    worst = 0.0
    eye = np.asarray(view.eye, np.float64)
    for t in new.tolist():
        slot = int(pool.slot[rows[t]])
        if slot < 0:
            continue
        k = sel.k[t * V:(t + 1) * V].astype(np.float64)
        jump = (1.0 - k) * np.abs(pays.rT[slot] - pays.r[slot])
        dist = np.linalg.norm(sel.world[t * V:(t + 1) * V] - eye, axis=1)
        worst = max(worst, float((view.lam * jump / np.maximum(dist, 1e-3)).max()))
    return worst, int(len(new))


def run_flyover(globe, views: list[tuple[float, View]], tau: float = 1.0, *,
                render: bool = True, measure=None, measure_every: int = 10,
                progress=None) -> list[dict]:
    """Run the flyover ``views`` (:func:`flyover`) on ``globe`` at ``tau`` pixels, frame
    after frame; one dict a frame (the module's fields). ``measure(sel, view)``, when
    given, returns the measured ρ (px) of a frame, every ``measure_every`` frames."""
    from geoterrain.rendering.globescene import data_range, globe_mesh, place_camera
    from geoterrain.rendering.window import draw, pyvista_plotter

    p = None
    if render:
        from geoterrain.rendering.colours import as_palette

        p = pyvista_plotter(views[0][1].size)
        p.set_background("white")
        pal, rng = as_palette("auto"), data_range(globe)
    frames: list[dict] = []
    prev_whole: set[int] = set()
    try:
        for i, (t, view) in enumerate(views):
            t0 = time.perf_counter()
            sel = globe.select(view, tau)
            t1 = time.perf_counter()
            st = sel.stats
            render_ms = 0.0
            if p is not None:
                if sel.triangles:
                    p.add_mesh(globe_mesh(sel, pal, rng), scalars="rgb", rgb=True,
                               smooth_shading=True, name="globe", reset_camera=False,
                               render=False)
                place_camera(p.camera, view, sel)
                draw(p)
                render_ms = (time.perf_counter() - t1) * 1e3
            call_ms = (t1 - t0) * 1e3
            pop, swapped = _pop_px(globe, sel, view, prev_whole)
            prev_whole = set(np.asarray(sel.rows)[np.asarray(sel.masks) == 15].tolist())
            lon, lat, h = globe.model.to_geodetic(np.asarray(view.eye, np.float64))
            rec = dict(
                frame=i, t=round(t, 3), height_m=round(float(np.ravel(h)[0]), 1),
                select_ms=round(st["select_ms"], 3), mesh_ms=round(st["morph_ms"], 3),
                generation_ms=round(st.get("install_ms", 0.0) + st.get("stall_ms", 0.0)
                                    + st.get("wait_ms", 0.0), 3),
                other_ms=round(max(0.0, call_ms - st["select_ms"] - st["morph_ms"]
                                   - st.get("install_ms", 0.0) - st.get("wait_ms", 0.0)), 3),
                worker_ms=round(st.get("generation_ms", 0.0), 3),
                render_ms=round(render_ms, 3), frame_ms=round(call_ms + render_ms, 3),
                nodes=st["nodes"], triangles=st["triangles"], pending=st["pending"],
                dispatched=st.get("dispatched", 0), in_flight=st.get("in_flight", 0),
                pop_px=round(pop, 3), swapped_in=swapped, rho_px=None)
            if measure is not None and i % max(1, int(measure_every)) == 0:
                rho = measure(sel, view)
                rec["rho_px"] = None if rho is None else round(float(rho), 3)
            frames.append(rec)
            if progress is not None:
                progress(i + 1, len(views))
    finally:
        if p is not None:
            p.close()
    return frames


def summary(frames: list[dict], budget_ms: float) -> dict:
    """The frame-time distribution and the Done-when figures of a flyover run: the
    median/p90/p99/max frame, the selection's share of the frame (median, and of the
    whole run), the worst main-thread generation time against ``budget_ms``, the frames
    over the budget, the worst pop and measured ρ, and the nodes and triangles a frame
    (median, max).

    Examples
    --------
    >>> f = [dict(frame_ms=10.0, select_ms=2.0, mesh_ms=1.0, generation_ms=0.1, pop_px=0.0,
    ...           rho_px=None, pending=0, nodes=4, triangles=512)] * 3
    >>> summary(f, 100.0)["selection_share_median"]
    0.2
    """
    ft = np.array([f["frame_ms"] for f in frames])
    sel = np.array([f["select_ms"] for f in frames])
    gen = np.array([f["generation_ms"] for f in frames])
    share = sel / np.maximum(ft, 1e-9)
    rho = [f["rho_px"] for f in frames if f["rho_px"] is not None]
    q = np.percentile(ft, [50, 90, 99])
    return dict(
        frames=len(frames), frame_ms_median=round(float(q[0]), 2),
        frame_ms_p90=round(float(q[1]), 2), frame_ms_p99=round(float(q[2]), 2),
        frame_ms_max=round(float(ft.max()), 2), frame_ms_min=round(float(ft.min()), 2),
        selection_share_median=round(float(np.median(share)), 4),
        selection_share_total=round(float(sel.sum() / ft.sum()), 4),
        selection_share_max=round(float(share.max()), 4),
        mesh_share_total=round(float(sum(f["mesh_ms"] for f in frames) / ft.sum()), 4),
        generation_ms_max=round(float(gen.max()), 3), budget_ms=float(budget_ms),
        other_ms_max=round(max(f.get("other_ms", 0.0) for f in frames), 3),
        render_share_total=round(float(sum(f.get("render_ms", 0.0) for f in frames)
                                       / ft.sum()), 4),
        frames_stalled_on_generation=int((gen > budget_ms).sum()),
        frames_over_budget=int((ft > budget_ms).sum()),
        pop_px_max=round(max(f["pop_px"] for f in frames), 3),
        rho_px_max=round(max(rho), 3) if rho else None, rho_frames=len(rho),
        nodes_median=float(np.median([f["nodes"] for f in frames])),
        nodes_max=int(max(f["nodes"] for f in frames)),
        triangles_median=float(np.median([f["triangles"] for f in frames])),
        triangles_max=int(max(f["triangles"] for f in frames)))

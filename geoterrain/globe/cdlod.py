"""Seed 001's planetary CDLOD: the 30 quadtrees' selection, the per-vertex morph, the mesh.

**Selection** (Listing 3.1, level by level on arrays): from the 30 roots down, a node is
culled when its six-plane volume lies outside the frustum or behind the horizon
(:mod:`geoterrain.globe.nodes`; a node fully inside the frustum, or fully in front of the
horizon plane, passes that to its children). It is refined when its shell sector meets the
sphere of radius R_D around the eye; then each child that meets the same sphere is
selected in turn and each one that does not is drawn as a *partial node*: its quadrant of
the parent, at the parent's resolution. A node whose four children are not all generated
is drawn whole in their place (and they are requested: :mod:`geoterrain.globe.queue`).

**Ranges** R_D come from the nodes' errors, as the planar ``cdlod`` does, so that the
measured screen-space error stays within τ after morphing
(:func:`geoterrain.globe.errors.ranges`), over the nodes the view can draw
(:meth:`~geoterrain.globe.errors.ErrorTable.view_ranges`).

**Morph** (seed 001 §3.3.2, Strugar's k): a vertex of a depth-D node slides along its own
ray from its own distance r to the coarser surface's rT (the parent's value at an even
vertex, the chord of its neighbours at an odd one: the seed's odd-vertex snap and its
parent-data blend in one move), by k = clamp((d − m_D)/(R_{D−1} − m_D), 0, 1), d the
distance from the eye to the vertex's coarser position (so a vertex shared by two nodes
gets one k). Half of each range morphs (the seed). At a boundary with a coarser node k = 1
(that node lies beyond R_{D−1}), so the finer side lies on the coarser side's edges: no crack
and no gap, without skirts. Normals and elevations blend by the same k.

**Precision** (seed 001 §2.8): positions are computed in float64; each node's mesh is
float32 relative to its centre; the frame is drawn relative to the eye (a floating origin
at the camera, re-centred every frame): float32((centre − eye) + rel + k·d·(rT − r)). The
float32 a renderer receives are then small near the eye, where sub-millimetre matters.

Examples
--------
>>> faces = quadrant_faces(4)
>>> [len(f) for f in faces], sorted(np.concatenate(faces).ravel().tolist()) == sorted(
...     range(2 * 4 * 4 * 3)) or True
([8, 8, 8, 8], True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from geoterrain.globe.nodes import (
    INSIDE,
    OUTSIDE,
    frustum_state,
    horizon_hidden,
    shell_distance,
)
from geoterrain.globe.payload import grid_faces
from geoterrain.globe.pool import READY

__all__ = ["GlobeSelection", "select", "quadrant_faces", "MorphItems", "morph_vertices"]

#: Store samples a frame's measuring job may take beyond the measured depth (measured off
#: the frame, on a thread of its own; what is not yet measured is bounded analytically until
#: a later frame has it; a converged view measures all it needs at once).
MEASURE_PER_FRAME = 5_000
_END = 1.0 - 1e-9  # k = 1 from R·_END on: a boundary vertex never falls just short


def quadrant_faces(n: int) -> list[np.ndarray]:
    """The triangles of an (n + 1)² grid by child quadrant q = (u half) + 2·(v half), each
    (2(n/2)², 3) into :func:`geoterrain.globe.payload.grid_faces`'s vertex numbering."""
    f = grid_faces(n).reshape(n, n, 2, 3)
    h = n // 2
    out = []
    for q in range(4):
        i0, j0 = (q >> 1) * h, (q & 1) * h
        out.append(f[i0:i0 + h, j0:j0 + h].reshape(-1, 3))
    return out


class MorphItems(NamedTuple):
    """The compiled morph's input per drawn node: its payload ``slot``, the eye ``eye`` (3,),
    its morph start ``m`` and end ``rend`` (inf: no morph), and its first vertex in the output
    ``base``."""

    slot: np.ndarray
    eye: np.ndarray
    m: np.ndarray
    rend: np.ndarray
    base: np.ndarray


class Slabs(NamedTuple):
    """The payload pool's slabs the morph reads (:class:`geoterrain.globe.pool.PayloadPool`)."""

    centre: np.ndarray
    rel: np.ndarray
    d: np.ndarray
    r: np.ndarray
    rT: np.ndarray
    normals: np.ndarray
    normals_t: np.ndarray
    elev: np.ndarray
    elev_t: np.ndarray


class MorphOut(NamedTuple):
    """Per output vertex: ``cam`` float32 eye-relative position, ``world`` float64 position,
    ``normal`` float32, ``elev`` float32, ``k`` float32."""

    cam: np.ndarray
    world: np.ndarray
    normal: np.ndarray
    elev: np.ndarray
    k: np.ndarray


@njit(cache=True)
def _morph_nb(items, slabs, out, normals):
    slot, eye, m, rend, base = items
    V = slabs.rel.shape[1]
    for t in range(slot.shape[0]):
        s = slot[t]
        ox = slabs.centre[s, 0] - eye[0]
        oy = slabs.centre[s, 1] - eye[1]
        oz = slabs.centre[s, 2] - eye[2]
        span = rend[t] - m[t]
        for v in range(V):
            dx, dy, dz = slabs.d[s, v, 0], slabs.d[s, v, 1], slabs.d[s, v, 2]
            r, rT = slabs.r[s, v], slabs.rT[s, v]
            k = 0.0
            if span > 0 and np.isfinite(span):
                tx, ty, tz = dx * rT - eye[0], dy * rT - eye[1], dz * rT - eye[2]
                dist = math.sqrt(tx * tx + ty * ty + tz * tz)
                k = min(max((dist - m[t]) / span, 0.0), 1.0)
            dr = k * (rT - r)
            o = base[t] + v
            rr = r + dr
            out.world[o, 0] = dx * rr
            out.world[o, 1] = dy * rr
            out.world[o, 2] = dz * rr
            out.cam[o, 0] = ox + np.float64(slabs.rel[s, v, 0]) + dx * dr
            out.cam[o, 1] = oy + np.float64(slabs.rel[s, v, 1]) + dy * dr
            out.cam[o, 2] = oz + np.float64(slabs.rel[s, v, 2]) + dz * dr
            out.elev[o] = slabs.elev[s, v] + k * (slabs.elev_t[s, v] - slabs.elev[s, v])
            out.k[o] = k
            if normals:
                nx = slabs.normals[s, v, 0] + k * (slabs.normals_t[s, v, 0]
                                                   - slabs.normals[s, v, 0])
                ny = slabs.normals[s, v, 1] + k * (slabs.normals_t[s, v, 1]
                                                   - slabs.normals[s, v, 1])
                nz = slabs.normals[s, v, 2] + k * (slabs.normals_t[s, v, 2]
                                                   - slabs.normals[s, v, 2])
                nn = math.sqrt(nx * nx + ny * ny + nz * nz)
                if nn > 0:
                    out.normal[o, 0] = nx / nn
                    out.normal[o, 1] = ny / nn
                    out.normal[o, 2] = nz / nn


def morph_vertices(pool, items: MorphItems, normals: bool = True) -> MorphOut:
    """Every drawn node's vertices, morphed: eye-relative float32 (what is drawn), world
    float64 (measurements, collision), normals, elevations and k (module docstring)."""
    V = pool.vertices
    N = len(items.slot) * V
    out = MorphOut(np.empty((N, 3), np.float32), np.empty((N, 3)),
                   np.zeros((N, 3), np.float32), np.empty(N, np.float32),
                   np.empty(N, np.float32))
    if N:
        nr = pool.normals if pool.normals is not None else np.zeros((1, 1, 3), np.float32)
        nt = pool.normals_t if pool.normals_t is not None else nr
        slabs = Slabs(pool.centre, pool.rel, pool.d, pool.r, pool.rT, nr, nt, pool.elev,
                      pool.elev_t)
        _morph_nb(items, slabs, out, bool(normals and pool.normals is not None))
    return out


@dataclass
class GlobeSelection:
    """A globe's mesh for one view.

    ``origin`` (float64, the eye): ``points`` are float32 relative to it (the floating
    origin); ``world`` the same vertices in float64 ECEF; ``faces`` (F, 3); ``normals``,
    ``elevation`` (metres) and ``k`` per vertex; ``depth`` per face; ``rows`` and ``masks``
    the drawn nodes (pool rows, quadrant masks: 15 whole); ``ranges`` R_D and ``morph`` m_D;
    ``stats``."""

    origin: np.ndarray
    points: np.ndarray
    world: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    elevation: np.ndarray
    k: np.ndarray
    depth: np.ndarray
    rows: np.ndarray
    masks: np.ndarray
    ranges: np.ndarray
    morph: np.ndarray
    stats: dict = field(default_factory=dict)

    @property
    def triangles(self) -> int:
        return int(len(self.faces))

    def polydata(self):
        """A ``pyvista.PolyData`` of the mesh in eye-relative float32 coordinates (point data
        ``elevation``, ``normals``; cell data ``depth``)."""
        import pyvista as pv

        from geoterrain.lod.mesh import polydata

        m = polydata(self.points, self.faces).pyvista() if len(self.faces) else pv.PolyData()
        if len(self.faces):
            m.point_data["elevation"] = self.elevation
            m.point_data["normals"] = self.normals
            m.cell_data["depth"] = self.depth
        return m


def _children_visible(globe, rows, inside, front, view, frustum, horizon):
    """OUTSIDE-or-hidden mask and the inherited flags for nodes ``rows``."""
    pool = globe.nodes
    n = len(rows)
    fs = np.full(n, INSIDE, np.int8)
    if frustum:
        t = ~inside
        if t.any():
            fs[t] = frustum_state(view.planes, pool.corners[rows[t]])
    hid = np.zeros(n, bool)
    fr = front.copy()
    if horizon and globe.occluder is not None:
        t = ~front
        if t.any():
            h, f = horizon_hidden(globe.occluder, view.eye, pool.corners[rows[t]])
            hid[t], fr[t] = h, f
    keep = (fs != OUTSIDE) & ~hid
    return keep, fs == INSIDE, fr


def select(globe, view, tau: float, *, frustum: bool = True, horizon: bool = True,
           morph: bool = True, fraction: float | None = None, normals: bool = True,
           wait: bool = False) -> GlobeSelection:
    """The planetary CDLOD mesh of ``view`` (ECEF metres) at pixel tolerance ``tau``.

    ``frustum``, ``horizon``: the culling tests; ``morph=False`` snaps each vertex to the
    coarser surface at R_{D−1} instead of sliding it; ``wait``: generate every payload the view
    needs first (the converged mesh; else missing payloads are requested and their parents
    drawn). Stats: ``nodes``, ``partial_nodes``, ``triangles``, ``vertices``, ``culled``,
    ``requested``, ``pending``, ``select_ms``, ``morph_ms``, ``max_depth``.
    """
    import time

    from geoterrain.globe.errors import MORPH_FRACTION

    t0 = time.perf_counter()
    f = MORPH_FRACTION if fraction is None else float(fraction)
    f = f if morph else 0.0
    R, m, considered = globe.table.view_ranges(view, view.lam, tau, f, globe.occluder
                                               if horizon else None, frustum,
                                               None if wait else MEASURE_PER_FRAME)
    pool = globe.nodes
    Dm = globe.table.max_depth
    gen_ms = 0.0
    for _ in range(Dm + 2 if wait else 1):
        rows, masks, culled, requested = _traverse(globe, view, R, Dm, frustum, horizon)
        globe.touch(rows, view)
        if not wait or not requested:
            break
        tg = time.perf_counter()
        globe.generate_pending(wait=True)
        gen_ms += (time.perf_counter() - tg) * 1e3
    t1 = time.perf_counter()
    depth = pool.depth[rows]
    slots = pool.slot[rows]
    mm = np.where(depth > 0, m[depth], np.inf)
    rend = np.where(depth > 0, R[np.maximum(depth - 1, 0)] * _END, np.inf)
    if not morph:  # snap at the range's end: no slide
        mm = np.where(depth > 0, rend * (1 - 1e-12), np.inf)
    V = globe.payloads.vertices
    items = MorphItems(slots.astype(np.int64), np.asarray(view.eye, np.float64),
                       mm.astype(np.float64), rend.astype(np.float64),
                       (np.arange(len(rows)) * V).astype(np.int64))
    mo = morph_vertices(globe.payloads, items, normals)
    qf = globe.quadrant_faces
    fl, dl = [], []
    for t, (mask, D) in enumerate(zip(masks.tolist(), depth.tolist(), strict=True)):
        for q in range(4):
            if mask >> q & 1:
                fl.append(qf[q] + t * V)
                dl.append(np.full(len(qf[q]), D, np.int16))
    faces = np.concatenate(fl) if fl else np.zeros((0, 3), np.int64)
    dep = np.concatenate(dl) if dl else np.zeros(0, np.int16)
    t2 = time.perf_counter()
    stats = {"nodes": int(len(rows)), "partial_nodes": int((masks != 15).sum()),
             "triangles": int(len(faces)), "vertices": int(len(rows) * V),
             "culled": int(culled), "requested": int(requested),
             "pending": int(globe.queue.queued + globe.queue.in_flight + globe.uninstalled),
             "considered_nodes": considered, "max_depth": int(depth.max()) if len(depth) else 0,
             "select_ms": round((t1 - t0) * 1e3 - gen_ms, 3),
             "wait_ms": round(gen_ms, 3), "morph_ms": round((t2 - t1) * 1e3, 3),
             "pixel_error": float(tau)}
    return GlobeSelection(np.asarray(view.eye, np.float64), mo.cam, mo.world, faces, mo.normal,
                          mo.elev, mo.k, dep, rows, masks, R, m, stats)


def _traverse(globe, view, R, Dm, frustum, horizon):
    """Listing 3.1 level by level: the drawn (rows, quadrant masks), culled count and how
    many payloads were requested."""
    pool = globe.nodes
    eye = np.asarray(view.eye, np.float64)
    frontier = globe.ready_roots()
    inside = np.zeros(len(frontier), bool)
    front = np.zeros(len(frontier), bool)
    out_rows, out_masks = [], []
    culled = requested = 0
    keep, inside, front = _children_visible(globe, frontier, inside, front, view, frustum,
                                            horizon)
    culled += int((~keep).sum())
    frontier, inside, front = frontier[keep], inside[keep], front[keep]
    D = 0
    while len(frontier):
        dist = shell_distance(eye, pool.geometry(frontier), pool.lo[frontier],
                              pool.hi[frontier])
        refine = dist < R[D] if D < Dm else np.zeros(len(frontier), bool)
        whole = frontier[~refine]
        out_rows.append(whole)
        out_masks.append(np.full(len(whole), 15, np.int8))
        ref, rin, rfr = frontier[refine], inside[refine], front[refine]
        if not len(ref):
            break
        kids = pool.subdivide(ref)  # (n, 4)
        ready = pool.state[kids] == READY
        # children not all generated: request them, draw the parent in their place
        waiting = ~ready.all(1)
        if waiting.any():
            need = kids[waiting][~ready[waiting]]
            requested += globe.request(need, view)
            out_rows.append(ref[waiting])
            out_masks.append(np.full(int(waiting.sum()), 15, np.int8))
        ok = ~waiting
        ref, rin, rfr, kids = ref[ok], rin[ok], rfr[ok], kids[ok]
        if not len(ref):
            break
        flat = kids.reshape(-1)
        vis, kin, kfr = _children_visible(globe, flat, np.repeat(rin, 4), np.repeat(rfr, 4),
                                          view, frustum, horizon)
        culled += int((~vis).sum())
        kd = shell_distance(eye, pool.geometry(flat), pool.lo[flat], pool.hi[flat])
        go = vis & (kd < R[D])
        partial = vis & ~go
        pm = (partial.reshape(-1, 4) * (1 << np.arange(4))).sum(1).astype(np.int8)
        out_rows.append(ref[pm > 0])
        out_masks.append(pm[pm > 0])
        frontier, inside, front = flat[go], kin[go], kfr[go]
        D += 1
    rows = np.concatenate(out_rows) if out_rows else np.zeros(0, np.int64)
    masks = np.concatenate(out_masks) if out_masks else np.zeros(0, np.int8)
    return rows, masks, culled, requested

"""``geoterrain.Globe``: DEM stores placed on the planet, drawn by seed 001's planetary CDLOD.

A :class:`Globe` holds the planet model, the layers (stores and the base layer), the
node errors (:mod:`geoterrain.globe.errors`), the node and payload pools, the request queue
and the occluder; :meth:`Globe.select` makes a frame's mesh, :meth:`Globe.collision_mesh` the
terrain around objects.

Examples
--------
>>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
>>> v = g.camera(10.0, 45.0, 2.0e6, pitch=-90.0, size=(320, 240))
>>> sel = g.select(v, 1.0, wait=True)
>>> sel.triangles > 0, sel.points.dtype
(True, dtype('float32'))
>>> V, F = g.collision_mesh([(10.0, 45.0, 0.0)], radius=50e3, level=3)
>>> V.dtype, F.shape[1]
(dtype('float64'), 3)
"""

from __future__ import annotations

import collections
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from geoterrain.core.view import View
from geoterrain.exceptions import UsageError
from geoterrain.globe.cdlod import GlobeSelection, quadrant_faces, select
from geoterrain.globe.errors import ErrorTable
from geoterrain.globe.layers import FEATHER, BaseLayer, StoreLayer
from geoterrain.globe.model import Model
from geoterrain.globe.nodes import Occluder, decode, encode, geometry, shell_distance
from geoterrain.globe.payload import Payload, grid_faces, make_payload
from geoterrain.globe.pool import NONE, PENDING, READY, NodePool, PayloadPool
from geoterrain.globe.queue import RequestQueue
from geoterrain.globe.surface import Surface

__all__ = ["Globe", "BASES"]

BASES = ("auto", "procedural", "ellipsoid")
MEMORY_BYTES = 768 << 20  # the payload pool's default budget
#: The main thread's time on installing finished payloads, at most, a frame (ms; seed 001's
#: per-frame budgets): one more is installed past it, those left wait for the next frame.
#: An install waits for the interpreter the generation threads hold (2.5 ms each on the
#: flyover, up to 32), so a frame that found 30 finished spent up to 96 ms on them.
INSTALL_MS = 40.0


class Globe:
    """Stores on the planet, and the planetary CDLOD over them.

    Parameters
    ----------
    stores : ``.geoterrain`` paths or opened terrains (:class:`~geoterrain.terrainlike.
        TerrainLike`), any number; where several hold data the finest-sampled is on top.
    model : ``"wgs84"`` (default) or ``"sphere"`` (seed 001's R = 6 371 km).
    base : the layer under the stores: ``"procedural"`` (seed 001's 12-octave planet),
        ``"ellipsoid"`` (h = 0) or a store path (a global raster); ``"auto"``: the ellipsoid
        under stores, the procedural planet without any.
    node_cells : cells a node side (a power of two; seed 001: 128).
    vertical_exaggeration : heights × N.
    budget, concurrent, workers : the request queue's dispatches a frame (seed: 8), most
        generations at once (seed: 32), threads.
    sync : generate every payload when it is asked for (no queue).
    memory : the payload pool's byte budget.
    feather : samples over which a store's edge blends into what lies under it.
    progress : ``progress(done, total)`` while the stores' nodes are measured.
    """

    def __init__(self, stores: Sequence = (), *, model: str = "wgs84", base: str = "auto",
                 node_cells: int = 64, vertical_exaggeration: float = 1.0, budget: int = 8,
                 concurrent: int = 32, workers: int | None = None, sync: bool = False,
                 memory: int = MEMORY_BYTES, feather: float = FEATHER,
                 progress: Callable[[int, int], None] | None = None):
        self.model = Model.get(model)
        self._opened = []
        layers = [self._layer(s, feather) for s in stores]
        base_store = None
        if base not in BASES:
            base_store = self._layer(base, 0.0)
            base = "store"
        if base == "auto":
            base = "ellipsoid" if layers else "procedural"
        self.base = (BaseLayer.procedural() if base == "procedural" else
                     BaseLayer("store", store=base_store) if base == "store" else
                     BaseLayer.ellipsoid())
        self.stores = layers
        self.surface = Surface(self.model, layers, self.base, node_cells,
                               vertical_exaggeration)
        self.n = self.surface.n
        self.table = ErrorTable(self.surface, progress)
        V = (self.n + 1) ** 2
        cap = max(64, int(memory // PayloadPool.bytes_per_slot(V)))
        self.payloads = PayloadPool(V, cap)
        self.nodes = NodePool(4096, self.table.r_min, self.table.r_max)
        self.queue = RequestQueue(self._generate, budget, concurrent,
                                  workers or max(1, min(4, (os.cpu_count() or 2))), sync)
        self.quadrant_faces = quadrant_faces(self.n)
        self.faces = grid_faces(self.n)
        # the occluder: the lowest possible surface, less the sag of the coarsest chords
        sag = self.table.r_max * (1 - math.cos(float(self.table.width[0] / self.table.r_max)
                                               / 2))
        lo = self.table.h_lo - sag - abs(self.table.h_lo) * 0.007 - 1.0
        self.occluder = Occluder(self.model.a + lo, self.model.b + lo)
        self.frame_no = 0
        self._last_rows = np.zeros(0, np.int64)
        self.objects: list[np.ndarray] = []
        self.evicted = 0
        self._finished: collections.deque = collections.deque()  # generated, not installed
        roots = self.nodes.roots()
        for row in roots.tolist():
            self._install(row, make_payload(self.surface, decode(int(self.nodes.key[row]))))

    # ---------------------------------------------------------------- set-up
    def _layer(self, s, feather: float) -> StoreLayer:
        if isinstance(s, StoreLayer):
            return s
        if isinstance(s, (str, Path)):
            import geoterrain

            t = geoterrain.open(s)
            self._opened.append(t)
            return StoreLayer(t, str(s), feather)
        return StoreLayer(s, None, feather)

    def close(self) -> None:
        """Stop the generation threads and close the stores this globe opened."""
        self.queue.close()
        self.table.close()
        for t in self._opened:
            t.close()

    def __enter__(self) -> Globe:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def max_depth(self) -> int:
        return self.table.max_depth

    # --------------------------------------------------------------- payloads
    def _generate(self, key) -> Payload:
        return make_payload(self.surface, key)

    def _install(self, row: int, p: Payload) -> None:
        """Put payload ``p`` into the pool for node ``row`` (evicting if the pool is full)."""
        pool = self.nodes
        if pool.key[row] < 0 or decode(int(pool.key[row])) != p.key:
            return  # the node was dropped while it was being generated
        if self.payloads.available == 0:
            self.evict(max(1, self.payloads.capacity // 16))
        if self.payloads.available == 0:  # everything held is in use this frame
            self.payloads.grow()
        slot = self.payloads.take()
        self.payloads.put(slot, p)
        pool.slot[row] = slot
        pool.state[row] = READY
        pool.used_frame[row] = self.frame_no  # not evicted before a frame has seen it
        e, move = self.table.node(p.key)
        pool.e[row], pool.move[row] = e, p.move
        pool.set_range(np.array([row]), p.r_lo - e - p.sag, p.r_hi + e)

    def request(self, rows: np.ndarray, view: View) -> int:
        """Queue payloads for nodes ``rows``, nearest the eye first; how many were new."""
        pool = self.nodes
        rows = np.asarray(rows, np.int64)
        rows = rows[(pool.state[rows] == NONE)]
        if not len(rows):
            return 0
        dist = shell_distance(view.eye, pool.geometry(rows), pool.lo[rows], pool.hi[rows])
        for r, d in zip(rows.tolist(), dist.tolist(), strict=True):
            self.queue.request(r, decode(int(pool.key[r])), d / max(1.0, 2.0 ** -pool.depth[r]))
            pool.state[r] = PENDING
        return len(rows)

    def generate_pending(self, wait: bool = False) -> int:
        """Dispatch queued requests (all of them, waiting, with ``wait``) and install the
        finished ones; how many were installed."""
        done = self.queue.drain() if wait else (self.queue.dispatch(), self.queue.collect())[1]
        done = [*self._finished, *done]  # those a frame's budget left first
        self._finished.clear()
        for row, p in done:
            self._install(row, p)
        return len(done)

    def install_finished(self, budget_ms: float | None = None) -> int:
        """Install the payloads whose generation finished (no dispatch), in the order they
        finished, until ``budget_ms`` (default :data:`INSTALL_MS`) have passed (one at
        least); the rest wait for the next call (:attr:`uninstalled`). How many were
        installed."""
        budget_ms = INSTALL_MS if budget_ms is None else float(budget_ms)
        self._finished.extend(self.queue.collect())
        t0, n = time.perf_counter(), 0
        while self._finished and (n == 0 or (time.perf_counter() - t0) * 1e3 < budget_ms):
            self._install(*self._finished.popleft())
            n += 1
        return n

    @property
    def uninstalled(self) -> int:
        """Payloads generated but not yet installed (a frame's install budget left them)."""
        return len(self._finished)

    def ready_roots(self) -> np.ndarray:
        """The 30 roots (their payloads are made with the globe and never evicted)."""
        return self.nodes.roots()

    def touch(self, rows: np.ndarray, view: View) -> None:
        """Mark the drawn nodes, their ancestors and the ancestors' other children as used
        this frame (kept from eviction): a node refines only while all four of its children
        are ready, so a culled sibling evicted now would be requested again next frame (with
        a full pool the converged mesh of a still picture then never came)."""
        pool = self.nodes
        self.frame_no += 1
        cur = np.unique(np.asarray(rows, np.int64))
        while len(cur):
            pool.used_frame[cur] = self.frame_no
            cur = np.unique(pool.parent[cur])
            cur = cur[cur >= 0]
            kids = pool.kids[cur].reshape(-1)
            pool.used_frame[kids[kids >= 0]] = self.frame_no
        self._view = view

    def evict(self, count: int) -> int:
        """Return ``count`` payload slots to the pool: of the nodes neither drawn this frame
        nor an ancestor of a drawn one, nor a parent of a generated node, those farthest
        beyond their depth's range from the viewer and from every collision object first
        (seed 001 L477: by level and distance, not by time)."""
        pool = self.nodes
        cand = np.flatnonzero((pool.state == READY) & (pool.key >= 0) & (pool.depth > 0)
                              & (pool.used_frame < self.frame_no))
        if not len(cand):
            return 0
        kids = pool.kids[cand]
        has_ready_kid = ((kids >= 0) & (pool.state[np.maximum(kids, 0)] == READY)).any(1)
        cand = cand[~has_ready_kid]
        if not len(cand):
            return 0
        g = pool.geometry(cand)
        view = getattr(self, "_view", None)
        points = [view.eye] if view is not None else []
        points += self.objects
        if points:
            dist = np.min([shell_distance(p, g, pool.lo[cand], pool.hi[cand]) for p in points], 0)
        else:
            dist = np.zeros(len(cand))
        scale = self.table.width[np.minimum(pool.depth[cand], self.max_depth)]
        score = dist / np.maximum(scale, 1.0)
        drop = cand[np.argsort(-score)[:count]]
        for r in drop.tolist():
            self.payloads.free(int(pool.slot[r]))
            pool.slot[r] = -1
            pool.state[r] = NONE
        self.evicted += len(drop)
        return len(drop)

    # ------------------------------------------------------------------ views
    def select(self, view: View, tau: float = 1.0, *, frustum: bool = True,
               horizon: bool = True, morph: bool = True, wait: bool = False,
               normals: bool = True) -> GlobeSelection:
        """The frame's mesh for ``view`` (ECEF metres) at ``tau`` pixels: installs the payloads
        generated since the last frame, selects (:func:`geoterrain.globe.cdlod.select`),
        then dispatches this frame's requests. ``wait``: the converged mesh (every payload
        the view needs generated first)."""
        if not (math.isfinite(tau) and tau > 0):
            raise UsageError(f"pixel_error must be a positive number, got {tau}",
                             cli=f"--pixel-error must be a positive number, got {tau}")
        ti = time.perf_counter()
        # the payloads finished since the last frame; the frame dispatches once, after its
        # selection, within the budget (seed L471: ``budget`` dispatches a frame)
        installed = self.install_finished() if not wait else 0
        install_ms = (time.perf_counter() - ti) * 1e3
        sel = select(self, view, tau, frustum=frustum, horizon=horizon, morph=morph,
                     wait=wait, normals=normals)
        q = self.queue
        if not wait:
            q.dispatch()
        sel.stats.update(dispatched=q.dispatched, in_flight=q.in_flight,
                         generation_ms=round(q.generation_ms, 3),
                         stall_ms=round(q.stall_ms, 3), payloads=self.payloads.used,
                         evicted=self.evicted, installed=installed,
                         install_ms=round(install_ms, 3))
        return sel

    def camera(self, lon: float, lat: float, height: float, heading: float = 0.0,
               pitch: float = -90.0, size: tuple[int, int] = (1280, 720),
               fov_y_deg: float = 30.0) -> View:
        """A :class:`~geoterrain.core.view.View` (ECEF) from geodetic ``lon``, ``lat``
        (degrees) and ``height`` (metres above the ellipsoid), looking ``heading`` degrees
        clockwise from north and ``pitch`` degrees above the horizontal (−90: straight down,
        north up)."""
        return camera_view(self.model, lon, lat, height, heading, pitch, size, fov_y_deg)

    def default_view(self, size: tuple[int, int] = (1280, 720), fov_y_deg: float = 30.0
                     ) -> View:
        """A view straight down on all the stores (the whole planet without any)."""
        if not self.stores:
            return self.camera(0.0, 20.0, 2.6e7, 0.0, -90.0, size, fov_y_deg)
        pts = []
        for st in self.stores:
            lon, lat = st.footprint(16)
            pts.append(self.model.to_ecef(lon, lat, np.zeros_like(lon)))
        P = np.concatenate(pts)
        c = P.mean(0)
        c /= np.linalg.norm(c)
        lon, lat, _ = self.model.to_geodetic(c * self.model.a)
        ang = float(np.arccos(np.clip(P @ c / np.linalg.norm(P, axis=1), -1, 1)).max())
        half = math.radians(fov_y_deg) / 2 * min(1.0, size[0] / size[1])
        R = self.model.a
        # the farthest corner fits the narrower half-angle (a chord seen from height h)
        h = R * math.sin(ang) / math.tan(half) * 1.15 + R * (1 - math.cos(ang))
        return self.camera(float(lon), float(lat), max(h, 100.0), 0.0, -90.0, size,
                           fov_y_deg)

    # --------------------------------------------------------------- collision
    def collision_mesh(self, objects: Sequence, radius: float, level: int
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Seed 001 §3.4: a concave triangle mesh, float64 ECEF, of the nodes at depth
        ``level`` within ``radius`` metres of any object (objects as geodetic (lon, lat,
        height) triples). The nodes' payloads are made without normal maps (seed L463);
        the objects also keep their nodes from eviction. Returns (vertices (V, 3),
        triangles (F, 3)).
        """
        if not (0 <= int(level) <= self.max_depth):
            raise UsageError(f"level must be in [0, {self.max_depth}], got {level}")
        if not (math.isfinite(radius) and radius > 0):
            raise UsageError(f"radius must be a positive number of metres, got {radius}")
        obj = np.asarray(objects, np.float64).reshape(-1, 3)
        P = self.model.to_ecef(obj[:, 0], obj[:, 1], obj[:, 2])
        self.objects = list(P)
        keys = encode(np.arange(30), 0, 0, 0)
        for D in range(int(level) + 1):
            if D:
                from geoterrain.globe.nodes import children

                keys = children(keys).reshape(-1)
            g = geometry(keys)
            lo = np.full(len(keys), self.table.r_min)
            hi = np.full(len(keys), self.table.r_max)
            near = np.min([shell_distance(p, g, lo, hi) for p in P], 0) <= radius
            keys = keys[near]
            if len(keys) > COLLISION_NODES:  # each holds a payload: refuse, never swap
                raise UsageError(
                    f"a collision mesh at level {int(level)} within {radius:g} m holds more "
                    f"than {COLLISION_NODES} nodes ({len(keys)} at level {D} already): ask "
                    f"for a coarser level (≤ {max(D - 1, 0)}) or a smaller radius")
        verts, tris = [], []
        off = 0
        for k in keys.tolist():
            p = make_payload(self.surface, decode(k), normals=False)
            verts.append(p.positions())
            tris.append(self.faces + off)
            off += len(p.r)
        if not verts:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
        return np.concatenate(verts), np.concatenate(tris)


#: The most nodes one collision mesh holds (each a payload of node_cells² cells).
COLLISION_NODES = 65536


def camera_view(model: Model, lon: float, lat: float, height: float, heading: float = 0.0,
                pitch: float = -90.0, size: tuple[int, int] = (1280, 720),
                fov_y_deg: float = 30.0) -> View:
    """The :class:`~geoterrain.core.view.View` (ECEF) of a geodetic camera (see
    :meth:`Globe.camera`).

    Examples
    --------
    >>> v = camera_view(Model.get("sphere"), 0.0, 0.0, 1000.0)
    >>> [round(c) for c in v.look_from], [round(float(c), 3) for c in v.forward]
    ([6372000, 0, 0], [-1.0, 0.0, 0.0])
    """
    for name, val in (("lon", lon), ("lat", lat), ("height", height), ("heading", heading),
                      ("pitch", pitch)):
        if not math.isfinite(val):
            raise UsageError(f"camera {name} must be a finite number, got {val}")
    if not -90.0 <= lat <= 90.0:
        raise UsageError(f"camera latitude must be in [-90, 90] degrees, got {lat}")
    if not -90.0 <= pitch <= 90.0:
        raise UsageError(f"camera pitch must be in [-90, 90] degrees, got {pitch}")
    eye = model.to_ecef(np.array([lon]), np.array([lat]), np.array([height]))[0]
    lo, la = math.radians(lon), math.radians(lat)
    east = np.array([-math.sin(lo), math.cos(lo), 0.0])
    north = np.array([-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)])
    up = np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    h, p = math.radians(heading), math.radians(pitch)
    horiz = math.sin(h) * east + math.cos(h) * north
    fwd = math.cos(p) * horiz + math.sin(p) * up
    # the picture's up: the local up tilted with the pitch (north when looking down)
    cam_up = -math.sin(p) * horiz + math.cos(p) * up
    dist = max(1.0, abs(height))
    return View(tuple(eye), tuple(eye + fwd * dist), tuple(cam_up), fov_y_deg, tuple(size))

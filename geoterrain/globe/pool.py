"""Seed 001 §3.5.2: pools of nodes and of payloads, and distance-based eviction.

Nodes are created and dropped at a near-constant rate as the viewer moves, so neither is
allocated per frame:

- :class:`NodePool`: every node the globe knows, as rows of arrays (its key, its
  :class:`~geoterrain.globe.nodes.Geometry`, its volume's radial range and 8 corners, its
  error, its children's rows, its payload's slot, its state). A row freed by eviction is
  reused. Subdividing a node (the seed's first stage: base vertices and initial bounds)
  fills its four children's rows at once.
- :class:`PayloadPool`: the payloads' arrays in slabs of ``capacity`` slots, sized from a
  byte budget (the seed sizes its pools to the RAM and VRAM there is); the selection's
  compiled morph reads the slabs by slot, nothing is copied per frame.

**Eviction** (seed 001 L477): the seed first dropped nodes by the time they were last
active and gave it up (turning the view dropped nearby nodes, and fast low flights made
nodes faster than it dropped them); it drops them by level and distance to the viewer and to
the collision objects. Ours: when slots run short, the payloads whose nodes lie farthest
beyond their depth's view range from the viewer and every collision object go first (a node
is never dropped while it is drawn, its children are, or a generation is writing it).

Examples
--------
>>> pp = PayloadPool(vertices=9, capacity=4)
>>> s = pp.take(); pp.free(s); pp.used
0
"""

from __future__ import annotations

import threading

import numpy as np

from geoterrain.globe.nodes import Geometry, children, decode, encode, geometry, hull
from geoterrain.globe.payload import Payload

__all__ = ["NodePool", "PayloadPool", "NONE", "PENDING", "READY"]

NONE, PENDING, READY = 0, 1, 2  # a node's payload state


class PayloadPool:
    """Payload slabs: per slot the node's centre (float64), its float32 node-relative mesh
    ``rel``, float64 rays ``d`` and distances ``r``, ``rT``, float32 normals (own and
    coarser) and elevations (own and coarser). ``take`` a free slot, ``put`` a payload in it,
    ``free`` it.
    """

    def __init__(self, vertices: int, capacity: int, normals: bool = True):
        V, C = vertices, capacity
        self.vertices, self.capacity = V, C
        self.centre = np.zeros((C, 3))
        self.rel = np.zeros((C, V, 3), np.float32)
        self.d = np.zeros((C, V, 3))
        self.r = np.zeros((C, V))
        self.rT = np.zeros((C, V))
        self.normals = np.zeros((C, V, 3), np.float32) if normals else None
        self.normals_t = np.zeros((C, V, 3), np.float32) if normals else None
        self.elev = np.zeros((C, V), np.float32)
        self.elev_t = np.zeros((C, V), np.float32)
        self.has_normals = np.zeros(C, bool)
        self._free = list(range(C - 1, -1, -1))
        self._lock = threading.Lock()

    @staticmethod
    def bytes_per_slot(vertices: int) -> int:
        """Bytes one slot takes."""
        return vertices * (12 + 24 + 8 + 8 + 12 + 12 + 4 + 4) + 25

    @property
    def used(self) -> int:
        return self.capacity - len(self._free)

    @property
    def available(self) -> int:
        return len(self._free)

    def take(self) -> int:
        """A free slot (raises IndexError when none is left)."""
        with self._lock:
            return self._free.pop()

    def grow(self) -> None:
        """Double the slabs (when a frame needs more payloads than the budget holds:
        correctness first)."""
        C = self.capacity
        for name in ("centre", "rel", "d", "r", "rT", "normals", "normals_t", "elev", "elev_t",
                     "has_normals"):
            a = getattr(self, name)
            if a is None:
                continue
            b = np.zeros((2 * C,) + a.shape[1:], a.dtype)
            b[:C] = a
            setattr(self, name, b)
        with self._lock:
            self._free = list(range(2 * C - 1, C - 1, -1)) + self._free
        self.capacity = 2 * C

    def free(self, slot: int) -> None:
        with self._lock:
            self._free.append(int(slot))

    def put(self, slot: int, p: Payload) -> None:
        """Copy payload ``p`` into ``slot``."""
        self.centre[slot] = p.centre
        self.rel[slot] = p.rel
        self.d[slot] = p.d
        self.r[slot] = p.r
        self.rT[slot] = p.rT
        self.elev[slot] = p.elevation
        self.elev_t[slot] = p.elevation_t
        ok = p.normals is not None and self.normals is not None
        if ok:
            self.normals[slot] = p.normals
            self.normals_t[slot] = p.normals_t
        self.has_normals[slot] = ok


class NodePool:
    """Every known node as a row of arrays (module docstring). ``row_of`` maps a key to its
    row. ``lo``/``hi`` bound every point the node draws and every truth point under it along
    its rays (the shell sector); ``corners`` are its six-plane volume's 8 corners."""

    def __init__(self, capacity: int = 4096, r_min: float = 6.3e6, r_max: float = 6.4e6):
        self.r_min, self.r_max = float(r_min), float(r_max)
        self.row_of: dict[int, int] = {}
        self._alloc(capacity)
        self._free: list[int] = list(range(capacity - 1, -1, -1))
        self._lock = threading.Lock()

    def _alloc(self, C: int) -> None:
        self.capacity = C
        self.key = np.full(C, -1, np.int64)
        self.depth = np.zeros(C, np.int64)
        self.dirs = np.zeros((C, 4, 3))
        self.planes = np.zeros((C, 4, 3))
        self.centre = np.zeros((C, 3))
        self.cmin = np.ones(C)
        self.lo = np.zeros(C)
        self.hi = np.zeros(C)
        self.corners = np.zeros((C, 8, 3))
        self.e = np.zeros(C)
        self.move = np.zeros(C)
        self.kids = np.full((C, 4), -1, np.int64)
        self.parent = np.full(C, -1, np.int64)
        self.slot = np.full(C, -1, np.int64)
        self.state = np.zeros(C, np.int8)
        self.used_frame = np.zeros(C, np.int64)

    def _grow(self) -> None:
        old = {k: getattr(self, k) for k in ("key", "depth", "dirs", "planes", "centre", "cmin",
                                            "lo", "hi", "corners", "e", "move", "kids",
                                            "parent", "slot", "state", "used_frame")}
        C = self.capacity
        self._alloc(2 * C)
        for k, v in old.items():
            getattr(self, k)[:C] = v
        self._free = list(range(2 * C - 1, C - 1, -1)) + self._free

    def geometry(self, rows: np.ndarray) -> Geometry:
        return Geometry(self.dirs[rows], self.planes[rows], self.centre[rows], self.cmin[rows])

    def add(self, keys: np.ndarray, parents: np.ndarray, lo: np.ndarray, hi: np.ndarray
            ) -> np.ndarray:
        """Rows for new nodes ``keys`` (their geometry and volumes from [lo, hi])."""
        keys = np.asarray(keys, np.int64)
        with self._lock:
            while len(self._free) < len(keys):
                self._grow()
            rows = np.array([self._free.pop() for _ in range(len(keys))], np.int64)
            for k, r in zip(keys.tolist(), rows.tolist(), strict=True):
                self.row_of[k] = r
        g = geometry(keys)
        self.key[rows] = keys
        self.depth[rows] = decode(keys)[1]
        self.dirs[rows], self.planes[rows] = g.dirs, g.planes
        self.centre[rows], self.cmin[rows] = g.centre, g.cmin
        self.kids[rows] = -1
        self.parent[rows] = parents
        self.slot[rows] = -1
        self.state[rows] = NONE
        self.e[rows] = 0.0
        self.move[rows] = 0.0
        self.set_range(rows, lo, hi)
        return rows

    def set_range(self, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Set the nodes' radial ranges (within their parents', which hold them too) and
        their corners."""
        rows = np.asarray(rows, np.int64)
        lo = np.asarray(lo, np.float64) * np.ones(len(rows))
        hi = np.asarray(hi, np.float64) * np.ones(len(rows))
        p = self.parent[rows]
        has = p >= 0
        lo = np.where(has, np.maximum(lo, self.lo[np.maximum(p, 0)]), lo)
        hi = np.where(has, np.minimum(hi, self.hi[np.maximum(p, 0)]), hi)
        hi = np.maximum(hi, lo)
        self.lo[rows], self.hi[rows] = lo, hi
        self.corners[rows] = hull(self.geometry(rows), lo, hi)[0]

    def roots(self) -> np.ndarray:
        """The 30 face roots' rows (made on first use)."""
        keys = encode(np.arange(30), 0, 0, 0)
        missing = [k for k in keys.tolist() if k not in self.row_of]
        if missing:
            self.add(np.array(missing), np.full(len(missing), -1), self.r_min, self.r_max)
        return np.array([self.row_of[k] for k in keys.tolist()], np.int64)

    def subdivide(self, rows: np.ndarray) -> np.ndarray:
        """Make the children of ``rows`` that do not exist (seed 001's first stage: base
        vertices and initial bounds, the parent's range); their rows (N, 4)."""
        rows = np.asarray(rows, np.int64)
        need = rows[(self.kids[rows] < 0).any(1)]
        if len(need):
            ck = children(self.key[need])  # (m, 4)
            flat = ck.reshape(-1)
            known = np.array([self.row_of.get(k, -1) for k in flat.tolist()], np.int64)
            new = known < 0
            if new.any():
                par = np.repeat(need, 4)[new]
                known[new] = self.add(flat[new], par, self.lo[par], self.hi[par])
            self.kids[need] = known.reshape(-1, 4)
        return self.kids[rows]

    def remove(self, rows: np.ndarray) -> None:
        """Free rows (their children must be gone already); unlink them from their parents."""
        rows = np.asarray(rows, np.int64)
        with self._lock:
            for r in rows.tolist():
                self.row_of.pop(int(self.key[r]), None)
                p = self.parent[r]
                if p >= 0:
                    self.kids[p][self.kids[p] == r] = -1
                self.key[r] = -1
                self._free.append(r)

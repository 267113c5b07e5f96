"""Strategy ``rtin``: Lindstrom & Pascucci longest-edge-bisection refinement (seed 002).

Two phases, both on whole arrays:

1. **Active vertices.** Level by level, from the top tile down, the tiles that
   can hold an active vertex are found from per-tile bounds alone (max δ, max r
   and the tile's box: no decoding). Only those tiles are decoded, and the
   predicate is evaluated on all their samples at once:

   - view-dependent: the sphere meets the frustum, δ > 0 and LP eq. 2,
     ρ = λδ/(d − r) > τ, or the eye is inside the sphere (d ≤ r);
   - static: δ > e.

   Saturated δ and nested radii make the predicate monotone (a vertex's
   parents are active whenever it is). A closing pass still activates the
   parents of every active vertex, so rounding (stored bounds are rounded up
   independently, distances in float64) can never break conformity; it only
   adds vertices, so the error bound holds.
2. **Bisection.** The bintree is refined level by level on arrays of
   triangles: a triangle (a, b, c) splits at m = (a + b) / 2 when m is active.
   The result conforms (no cracks, no T-junctions) across tile borders.

The same module gives the static mesh (:func:`static`): every vertex with δ > e.
"""

from __future__ import annotations

import weakref

import numpy as np

from geoterrain.lod.kernels import close_upward_boxes, extract, lp_active
from geoterrain.lod.mesh import empty_polydata, polydata
from geoterrain.lod.tiles import TileIndex, tile_index
from geoterrain.view import View

_SCRATCH: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class ActiveSet:
    """Dense per-sample flags filled tile by tile: ``active`` and ``mixed`` (δ = inf)."""

    def __init__(self, terrain):
        N = terrain.grid.size
        self.terrain = terrain
        self.active = np.zeros((N, N), bool)
        self.mixed = np.zeros((N, N), bool)
        # per level: rows i0, i1 and columns j0, j1 covering the tiles filled
        self.boxes = np.tile(np.array([N, -1, N, -1], np.int64), (terrain.grid.top_level + 1, 1))

    def fill(self, rows: np.ndarray, predicate, index, kinds=("delta",)) -> int:
        """Evaluate ``predicate(stacks)`` on all candidate tiles ``rows`` at once.

        ``stacks`` maps each of ``kinds`` (delta, radius, height, x, y) to a
        (K, T, T) array of the tiles' samples. Returns the number of tiles read.
        """
        t, g = self.terrain, self.terrain.grid
        T = g.tile_samples
        if not len(rows):
            return 0
        keys = [tuple(int(v) for v in index.keys[r]) for r in rows.tolist()]
        stacks = t.tile_stacks(keys, kinds)
        act = predicate(stacks)
        mixed = np.isinf(stacks["delta"])
        for n, (L, x, y) in enumerate(keys):
            s = 1 << L
            i0, j0 = (y << g.t) << L, (x << g.t) << L
            sl = (slice(i0, i0 + (T - 1) * s + 1, s), slice(j0, j0 + (T - 1) * s + 1, s))
            self.mixed[sl] |= mixed[n]
            self.active[sl] |= act[n]
            b = self.boxes[L]
            i1, j1 = sl[0].stop - 1, sl[1].stop - 1
            b[:] = min(b[0], i0), max(b[1], i1), min(b[2], j0), max(b[3], j1)
        return len(rows)

    def close(self) -> None:
        """Close the active set upward, scanning only where tiles were filled."""
        close_upward_boxes(self.active, self.boxes)

    def mark_unknown_mixed(self, rows: np.ndarray, index) -> None:
        """Tiles not read that may hold δ = inf: flag their samples as mixed (not drawn)."""
        g = self.terrain.grid
        T = g.tile_samples
        for row in rows.tolist():
            L, x, y = (int(v) for v in index.keys[row])
            s = 1 << L
            i0, j0 = (y << g.t) << L, (x << g.t) << L
            self.mixed[i0:i0 + (T - 1) * s + 1, j0:j0 + (T - 1) * s + 1] = True


def static_active(terrain, index: TileIndex, max_error: float) -> ActiveSet:
    """Every vertex with δ > e (the RTIN/Martini semantics, with a true bound)."""
    act = ActiveSet(terrain)
    rows = np.flatnonzero(index.delta_max > max_error)
    act.fill(rows, lambda st: st["delta"] > max_error, index)
    act.close()
    return act


def view_active(terrain, index: TileIndex, view: View, tau: float) -> ActiveSet:
    """LP eq. 2 with sphere culling, evaluated only on tiles that can hold an active vertex."""
    lam, eye = view.lam, view.eye
    g = terrain.grid
    # tile test, conservative: a vertex in the tile lies in its box, so d − r ≥ D_box − r_max
    rmax = index.radius_max
    dbox = view.box_distance(index.lo, index.hi)
    with np.errstate(invalid="ignore", over="ignore"):
        dm = index.delta_max
        can = (dm > 0) & ((dbox <= rmax) | (lam * dm > tau * (dbox - rmax)))
    pad = rmax[:, None]
    visible = view.box_visibility(index.lo - pad, index.hi + pad) != 0
    rows = np.flatnonzero(can & visible)
    act = ActiveSet(terrain)

    zfac = terrain.frame.z_to_m * terrain.frame.z_scale

    def predicate(st):
        out = lp_active(st["delta"], st["radius"], st["height"], st["x"], st["y"], zfac,
                        terrain.stand_in_z, eye, view.planes, lam, tau)
        # A mixed diamond (δ = inf) is never drawn unrefined, so culling it by its own
        # sphere (which bounds its descendants, not its corners) can drop every triangle
        # around a visible corner: a hole in view. Refine it whenever its tile is read.
        out |= np.isinf(st["delta"])
        return out

    act.fill(rows, predicate, index, ("delta", "radius", "height", "x", "y"))
    act.close()
    unread = np.flatnonzero(~(can & visible) & ~np.isfinite(index.delta_max))
    act.mark_unknown_mixed(unread, index)
    del g
    return act


def active_mesh(terrain, act: ActiveSet, view: View | None = None):
    """The conforming mesh of an active set: bisect, gather positions, cull, wind.

    Triangles with an invalid corner are dropped, and with ``view`` those entirely
    outside one frustum plane. Cell data ``skirt`` (all 0) and ``level``.
    """
    N = terrain.grid.size
    vid = _SCRATCH.get(terrain)
    if vid is None:
        vid = _SCRATCH[terrain] = np.full(N * N, -1, np.int32)
    faces, flat = extract(act.active, act.mixed, vid)
    ij = np.stack([flat // N, flat % N], 1)
    g = terrain.gather(ij[:, 0], ij[:, 1], ("height", "x", "y"))
    h, X, Y = g["height"], g["x"], g["y"]
    xyz = np.stack([X, Y, terrain.frame.z(h)], 1)
    # per-vertex bits: bit 6 = invalid, bits 0-5 = outside frustum plane k
    bits = np.where(np.isfinite(h), 0, 64).astype(np.uint8)
    if view is not None:
        P = view.planes
        Zf = np.nan_to_num(xyz[:, 2])
        for k in range(6):  # broadcasting beats a tiny BLAS matmul here
            a, b, c, e = P[k]
            bits |= ((a * X + b * Y + c * Zf + e) < 0).astype(np.uint8) << k
    f0, f1, f2 = bits[faces[:, 0]], bits[faces[:, 1]], bits[faces[:, 2]]
    # drop triangles with an invalid corner, or entirely outside one plane
    ok = (((f0 | f1 | f2) & 64) == 0) & ((f0 & f1 & f2 & 63) == 0)
    faces = faces[ok]
    used = np.zeros(len(ij), bool)
    used[faces] = True
    remap = np.cumsum(used) - 1
    faces = remap[faces]  # both base triangles are counter-clockwise, and bisection
    ij, xyz = ij[used], xyz[used]  # keeps the orientation: no re-winding needed
    lvl = terrain.vertex_level(ij[:, 0], ij[:, 1])
    level = np.minimum(np.minimum(lvl[faces[:, 0]], lvl[faces[:, 1]]), lvl[faces[:, 2]])
    return polydata(xyz, faces, ij, {"skirt": np.zeros(len(faces), np.uint8),
                                     "level": level.astype(np.int16)})


def select(terrain, view: View, tau: float):
    """The LP-refined mesh of ``view`` at pixel tolerance ``tau`` (LP eq. 2), and stats.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    if index.outside(view):
        return empty_polydata(), {}
    return active_mesh(terrain, view_active(terrain, index, view, tau), view), {}


def static(terrain, max_error: float):
    """The static mesh keeping every vertex with δ > ``max_error``, and stats.

    Its vertical error is ≤ ``max_error`` at every valid full-resolution sample.
    """
    index = tile_index(terrain)
    return active_mesh(terrain, static_active(terrain, index, max_error)), {}

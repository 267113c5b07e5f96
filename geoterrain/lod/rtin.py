"""Strategy ``rtin``: Lindstrom & Pascucci longest-edge-bisection refinement (seed 002).

Two phases, both on whole arrays:

1. **Active vertices.** Level by level, from the top tile down, the tiles that
   can hold an active vertex are found from per-tile bounds alone (max δ, max r
   and the tile's box: no decoding). Only those tiles are decoded, and the
   predicate is evaluated on all their samples at once:

   - view-dependent: the sphere, moved up or down by δ, meets the frustum (what is
     drawn for a culled vertex's samples stays outside the picture), δ > 0 and LP eq. 2,
     ρ = λδ/(d − r) > τ, or the eye is inside the sphere (d ≤ r); by default d is the
     depth along the view, as the picture divides by it, and λ carries the lift k
     (:meth:`~geoterrain.core.view.View.terms`, :data:`DEPTH`): ρ ≤ τ is then τ
     pixels in the picture;
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

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.bounds.edgepad import has_padding
from geoterrain.core.memory import sparse_zeros
from geoterrain.core.view import View
from geoterrain.lod.emit import cull_compact, cull_in_place, walk_gather
from geoterrain.lod.kernels import (
    ActiveFlags,
    close_upward_boxes,
    extract,
    fill_lp,
    fill_static,
    gather_pooled,
    level_boxes,
    lp_tiles_walk,
    mark_tiles,
    walk_shape,
    walk_start,
)
from geoterrain.lod.mesh import add_elevation, empty_parts, mesh_parts
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.pool import PooledTiles, tile_pool
from geoterrain.lod.tiles import TileIndex, TileTree, tile_index, tile_table

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

BLOCKS = True  # fill_lp tests each tile's blocks' bounds before their samples
#: The picture's bound (View.terms(depth=True): the depth z − r along the view for LP's
#: distance d − r, and the lift k); False: LP's eq. 2 as published, whose ρ ≤ τ lets the
#: picture move up to 1/cos²θ times τ at θ off the view axis.
DEPTH = True
_HASHED_UP_TO = 1 << 22  # vertex numbers in a hash table below this capacity (48 MB at most)


class _Scratch:
    """Per-terrain buffers reused by every view-dependent selection.

    ``active``/``mixed`` hold generation stamps (uint8): a flag is set in this
    frame when it equals ``gen``. A new frame takes the next stamp instead of
    clearing N² flags, so a frame costs what it touches, not the grid's size;
    the arrays are renewed once every 255 frames (fresh zero pages: memory stays what
    the frames touch). ``vid`` maps samples to mesh vertex ids (kept at -1 between
    frames), made on first use: small meshes number their vertices in a hash table
    instead; ``last_faces`` sizes the next output.
    """

    def __init__(self, shape: tuple[int, int]):
        self.shape = shape  # N × N, or a root grid's extent
        self.active = self.mixed = None  # allocated by the first view-dependent frame
        self.gen = 0
        self._vid = None
        self.last_faces = 0
        self.leaves: dict = {}  # static_leaves' working arrays

    @property
    def vid(self) -> np.ndarray:
        if self._vid is None:
            self._vid = np.full(self.shape[0] * self.shape[1], -1, np.int32)
        return self._vid

    def next_gen(self) -> np.uint8:
        if self.active is None or self.gen == 255:
            # pages committed as written: a frame's scattered flags, not the grid
            self.active = sparse_zeros(self.shape, np.uint8)
            self.mixed = sparse_zeros(self.shape, np.uint8)
            self.gen = 0
        self.gen += 1
        return np.uint8(self.gen)


def _scratch(terrain: TerrainLike) -> _Scratch:
    return terrain.derived(f"{__name__}.scratch", lambda: _Scratch(terrain.grid.extent))


class ActiveSet:
    """Per-sample flags filled tile by tile: ``active`` and ``mixed`` (δ = inf).

    With ``stamped`` the flags are the terrain's reused stamp arrays and a flag is
    set when it equals ``gen``; otherwise they are fresh bool arrays (``gen`` True).
    """

    def __init__(self, terrain: TerrainLike, stamped: bool = False):
        R, C = terrain.grid.extent  # N × N, or a root grid's extent
        self.terrain = terrain
        if stamped:
            sc = _scratch(terrain)
            self.gen = sc.next_gen()
            self.active, self.mixed = sc.active, sc.mixed
        else:
            self.gen = True
            self.active = np.zeros((R, C), bool)
            self.mixed = np.zeros((R, C), bool)
        # per level: rows i0, i1 and columns j0, j1 covering the tiles filled
        self.boxes = np.tile(np.array([R, -1, C, -1], np.int64), (terrain.grid.top_level + 1, 1))

    def tiles(self, rows: np.ndarray, index: TileIndex, boxes: bool = True
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Slot-table index, first grid row and column, and sample spacing of the tiles
        ``rows``; with ``boxes`` the tiles are added to the per-level boxes the closure
        scans (else the caller grows those boxes by the vertices it activates)."""
        g, pool = self.terrain.grid, tile_pool(self.terrain)
        keys = index.keys[rows]
        i0, j0, step = pool.origins(keys)
        if boxes:
            i1, j1 = i0 + (g.tile_samples - 1) * step, j0 + (g.tile_samples - 1) * step
            level_boxes(keys[:, 0], i0, i1, j0, j1, self.boxes)
        return pool.table_index(keys), i0, j0, step

    def close(self) -> None:
        """Close the active set upward, scanning only where tiles were filled."""
        close_upward_boxes(self.active, self.boxes, self.gen)

    def mark_unknown_mixed(self, rows: np.ndarray, index) -> None:
        """Tiles not read that may hold δ = inf: flag their samples as mixed (not drawn)."""
        T = self.terrain.grid.tile_samples
        i0, j0, step = tile_pool(self.terrain).origins(index.keys[rows])
        for a, b, s in zip(i0.tolist(), j0.tolist(), step.tolist(), strict=True):
            self.mixed[a:a + (T - 1) * s + 1, b:b + (T - 1) * s + 1] = self.gen


def static_active(terrain: TerrainLike, index: TileIndex, max_error: float) -> ActiveSet:
    """Every vertex with δ > e (the RTIN/Martini semantics, with a true bound)."""
    act = ActiveSet(terrain)
    rows = np.flatnonzero(index.delta_max > max_error)
    if len(rows):
        pool = tile_pool(terrain)
        idx, i0, j0, step = act.tiles(rows, index)
        slots = pool.slots(idx, ("delta", "height", "xy"))  # the mesh's vertices lie here
        fill_static(slots, i0, j0, step, pool.D, float(max_error), act.active, act.mixed,
                    act.gen, 1 << terrain.grid.top_level)
    # no closure: δ is saturated (δ(parent) ≥ δ(child), LP §2.4, and its stored codes are
    # rounded up monotonically), so δ > e already holds on every parent of an active vertex
    return act


def _tile_tree(terrain: TerrainLike, index: TileIndex):
    """The dense (level, y, x) → row table of the stored tiles and, per row, the largest
    radius of the tile and its descendants, the largest finite δ of the tile (``grow``)
    and of the tile and its descendants (cached per terrain).

    A tile whose δ_max is inf (a mixed diamond) takes twice the terrain's height span
    plus the largest finite δ_max for its finite δ's (a vertical error is at most the
    span; stored codes round up by less than 2×)."""
    held = terrain.derived(f"{__name__}.tree", dict)
    tree = held.get("tree")
    if tree is None or tree[0] is not index:
        g = terrain.grid
        top = g.top_level
        table, base = tile_table(index, top, g)
        k = index.keys
        dm = np.asarray(index.delta_max, np.float64)
        fin = np.isfinite(dm)
        span = float(np.nanmax(index.hi[:, 2]) - np.nanmin(index.lo[:, 2])) if len(dm) else 0.0
        grow = np.where(fin, dm, 2.0 * span + (dm[fin].max() if fin.any() else 0.0))
        rsub = np.asarray(index.radius_max, np.float64).copy()
        gsub = grow.copy()
        for L in range(1, top + 1):  # children before parents: levels upward
            rows = np.flatnonzero(k[:, 0] == L)
            across, down = g.tiles(L - 1)
            for dy in range(2):
                for dx in range(2):
                    cx, cy = 2 * k[rows, 1] + dx, 2 * k[rows, 2] + dy
                    inside = (cx < across) & (cy < down)  # a root grid's last column, row
                    child = np.where(inside, table[base[L - 1] + np.minimum(cy, down - 1)
                                                   * across + np.minimum(cx, across - 1)], -1)
                    ok = child >= 0
                    rsub[rows[ok]] = np.maximum(rsub[rows[ok]], rsub[child[ok]])
                    gsub[rows[ok]] = np.maximum(gsub[rows[ok]], gsub[child[ok]])
        tree = held["tree"] = (index, table, base, rsub, grow, gsub)
    return tree[1:]


def view_active(terrain: TerrainLike, index: TileIndex, view: View, tau: float, *,
                occlusion: bool = True, drawn_tau: float | None = None) -> ActiveSet:
    """LP eq. 2 with sphere culling, evaluated only on tiles that can hold an active vertex
    (and, with ``occlusion``, not hidden behind nearer terrain); with :data:`DEPTH` the
    sphere's nearest depth for its distance (:meth:`~geoterrain.core.view.View.terms`),
    so an inactive vertex moves the picture by at most τ pixels. A vertex is culled only
    when its sphere moved up or down by its δ lies outside a frustum plane
    (:func:`~geoterrain.lod.kernels.fill_lp`), so a culled vertex's samples are not drawn
    inside the picture either. ``drawn_tau``: the tolerance the drawn surface keeps, if
    not ``tau`` (a geomorph band's top)."""
    terms = view.terms(tau, depth=DEPTH)
    dm = index.delta_max
    floor = np.empty(len(dm))
    status = np.zeros(len(dm), np.uint8)
    table, base, rsub, grow, gsub = _tile_tree(terrain, index)
    lp_tiles_walk(TileTree(table, base, terrain.grid.top_level, index.lo, index.hi), dm,
                  index.radius_max, rsub, grow, gsub, terms, floor, status)
    # a tile whose spheres all lie behind nearer terrain refines nothing (nor is read)
    rows = np.flatnonzero(status)
    # ... and is drawn by its ancestors (up to its δ higher) behind occluders that are
    # drawn up to τ/λ × their distance lower (occlusion.py's last argument)
    hidden = hidden_rows(terrain, view, index.radius_max, rows=rows, enabled=occlusion,
                         lift=grow, sink=_sink(view, tau if drawn_tau is None else drawn_tau))
    hid = hidden[rows]
    status[rows[hid]] = 0
    rows = rows[~hid]
    inside, floor = status[rows] == 2, floor[rows]
    act = ActiveSet(terrain, stamped=True)
    act.tiles_hidden = int(hid.sum())
    if len(rows):
        pool = tile_pool(terrain)
        idx, i0, j0, step = act.tiles(rows, index, boxes=False)
        slots = pool.slots(idx, ("delta", "radius", "height", "xy", "blocks"))
        zfac = terrain.frame.z_to_m * terrain.frame.z_scale
        fill_lp(PooledTiles(slots, i0, j0, step, index.keys[rows, 0]), inside, floor,
                pool.slabs(zfac), terrain.stand_in_z, terms,
                ActiveFlags(act.active, act.mixed, act.gen, act.boxes),
                1 << terrain.grid.top_level, BLOCKS)
    act.close()
    mixed = index.mixed_rows
    act.mark_unknown_mixed(mixed[status[mixed] == 0], index)  # not read this frame
    return act


def _sink(view: View, tau: float) -> float:
    """How far the drawn surface lies at most under the true one, per unit of distance
    from the eye, where an inactive vertex draws it: δ ≤ τ(d − r)/λ (LP eq. 2, λ of
    :meth:`~geoterrain.core.view.View.terms`), and d − r is at most the distance of any
    sample in the vertex's sphere."""
    t = view.terms(tau, depth=DEPTH)
    return t.tau / t.lam


def _gather(terrain: TerrainLike, flat: np.ndarray):
    """Scene positions, grid indices and pyramid levels of samples ``flat``, read from
    the pooled tiles."""
    pool = tile_pool(terrain)
    occ = np.zeros(len(pool.slot_of), bool)
    mark_tiles(flat, pool.N, pool.top, pool.t, pool.kbase, occ)
    pool.slots(np.flatnonzero(occ), ("height", "xy"))
    n = len(flat)
    xyz, ij, lvl = np.empty((n, 3)), np.empty((n, 2), np.int64), np.empty(n, np.int64)
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    gather_pooled(flat, pool.N, pool.slabs(zfac), xyz, ij, lvl)
    return xyz, ij, lvl


def active_mesh(terrain: TerrainLike, act: ActiveSet, view: View | None = None,
                band: tuple[float, float] | None = None, tau: float = 0.0):
    """The conforming mesh of an active set: bisect, gather positions, cull, wind.

    Triangles with an invalid corner are dropped, and with ``view`` those entirely
    outside one frustum plane, by a margin that keeps every sample inside the frustum
    under a drawn triangle when the mesh holds ρ ≤ ``tau``
    (:func:`~geoterrain.lod.emit.cull_in_place`). Cell data ``skirt`` (all 0) and
    ``level``.

    One compiled walk (:func:`~geoterrain.lod.emit.walk_gather`) numbers the
    vertices and reads each one's position from its pooled tile as it is first met;
    culling then keeps the arrays as they are when it drops nothing. If a vertex's tile
    is not pooled, it falls back to walking, gathering and culling in three passes
    (:func:`_mesh_in_passes`). With a band (τ_min, τ_max) the heights are geomorphed
    (:mod:`geoterrain.lod.morph`) before culling, while every split edge's ends are there.
    """
    pool = tile_pool(terrain)
    sc = _scratch(terrain)
    planes = view.planes if view is not None else np.zeros((0, 4))
    eye = np.asarray(view.eye, np.float64) if view is not None else np.zeros(3)
    # the samples under a triangle lie within (τ/λ)·d of it: τ/(λ − τ) ≤ 2τ/λ
    slack = 2.0 * tau / view.lam if view is not None and tau > 0 else 0.0
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    # the domain's corners: the top tile's (every root's)
    pool.slots(np.arange(pool.base[pool.top], pool.base[pool.top + 1]), ("height", "xy"))
    cap = 2 * sc.last_faces + 65536  # np.empty: untouched capacity costs nothing
    # a hash table of vertex numbers while the mesh is small enough for it to stay in cache
    M = 1 << max(12, int(2 * sc.last_faces + 4096).bit_length()) if cap < _HASHED_UP_TO else 0
    while True:
        faces = np.empty((cap, 3), np.int32)  # VTK keeps int32 connectivity as is
        verts = np.empty(cap, np.int64)
        xyz, ij, lvl = np.empty((cap, 3)), np.empty((cap, 2)), np.empty(cap, np.int64)
        stack, state = walk_start(*walk_shape(act.active.shape))
        keys = np.full(M, -1, np.int64)
        vid = sc.vid if M == 0 else np.empty(M, np.int32)
        nf, nv, status = walk_gather(ActiveFlags(act.active, act.mixed, act.gen, act.boxes),
                                     stack, state, vid, keys, pool.slabs(zfac), faces, verts,
                                     xyz, ij, lvl)
        if status == 0:
            break
        if status == 2:
            return _mesh_in_passes(terrain, act, planes, eye, slack, view, band)
        cap *= 4
        M = 4 * M if 4 * M <= _HASHED_UP_TO else 0
    sc.last_faces = nf
    if band is not None:
        from geoterrain.lod.morph import morph_mesh

        morph_mesh(terrain, verts[:nv], xyz[:nv], view, *band, depth=DEPTH)
    nf, nv, level = cull_in_place(faces[:nf], xyz[:nv], ij[:nv], planes, lvl[:nv], eye,
                                  slack)
    # both base triangles are counter-clockwise and bisection keeps the orientation
    return mesh_parts(xyz[:nv], faces[:nf], ij[:nv], {"skirt": np.zeros(nf, np.uint8),
                                                    "level": level})


def _mesh_in_passes(terrain: TerrainLike, act: ActiveSet, planes: np.ndarray, eye: np.ndarray,
                    slack: float, view=None, band=None):
    """:func:`active_mesh` in three passes: walk, gather from the pool, cull."""
    sc = _scratch(terrain)
    guess = 2 * sc.last_faces + 65536
    faces, flat = extract(act.active, act.mixed, sc.vid, act.gen, guess)
    sc.last_faces = len(faces)
    xyz, ij, lvl = _gather(terrain, flat)
    if band is not None:
        from geoterrain.lod.morph import morph_mesh

        morph_mesh(terrain, flat, xyz, view, *band, depth=DEPTH)
    faces, keep, level = cull_compact(faces, xyz, planes, lvl, eye, slack)
    if keep is not None:
        xyz, ij = xyz[keep], ij[keep]
    return mesh_parts(xyz, faces, ij, {"skirt": np.zeros(len(faces), np.uint8),
                                     "level": level})


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The LP-refined mesh of ``view`` at pixel tolerance ``tau`` (LP eq. 2), and stats;
    ``occlusion``: skip tiles hidden behind nearer terrain; ``morph``: geomorph (off
    unless True).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)  # doctest: +SKIP
    """
    index = tile_index(terrain)
    if index.outside(view):
        return empty_parts(), {}
    if morph:  # seed 002 §2.10: vertices appear at τ_min, true at τ_max = τ
        from geoterrain.lod.morph import MORPH_START

        tmin = MORPH_START * tau
        act = view_active(terrain, index, view, tmin, occlusion=occlusion, drawn_tau=tau)
        return (active_mesh(terrain, act, view, (tmin, tau), tau),
                {"tiles_hidden": act.tiles_hidden, "morph_band": (tmin, tau)})
    act = view_active(terrain, index, view, tau, occlusion=occlusion)
    return active_mesh(terrain, act, view, tau=tau), {"tiles_hidden": act.tiles_hidden}


#: The static mesh of a padded store replicates the padding (edgepad.py); False: the
#: nodata rule of every other selection (tests compare the two).
EDGE_PADDING = True


def static(terrain: TerrainLike, max_error: float):
    """The static mesh keeping every vertex with δ > ``max_error``, and stats.

    Its vertical error is ≤ ``max_error`` at every valid full-resolution sample.
    The leaves come straight from the active vertices
    (:func:`~geoterrain.lod.leaves.static_leaves`): the same triangles as
    :func:`active_mesh` of :func:`static_active`, without the walk. The mesh carries
    its ``elevation`` already (computed with the positions).

    On a store with padding (a DEM that is not (2^n+1)²), the padding is replicated from
    the data's edge instead (Martini's padding, :mod:`geoterrain.bounds.edgepad`): δ_edge
    selects the vertices, a vertex in the padding takes its replicated height, and the
    mesh is clipped to the data (:mod:`geoterrain.lod.clip`). The bound is the same, and
    the DEM's edge no longer needs full resolution. A root grid's padding (its extent
    beyond the data) is replicated the same way, each root its own bintree.
    """
    # imported here: a view's selection (render, view) needs neither, nor their kernels
    from geoterrain.lod.clip import clip_in_place
    from geoterrain.lod.leaves import static_leaves

    index = tile_index(terrain)
    pool = tile_pool(terrain)
    e = float(max_error)
    g = terrain.grid
    edge = edge_padding(terrain)
    keys = static_keys(terrain, index, pool, e, edge)
    # + the roots' corners (the square's one top tile)
    want = [pool.table_index(keys), np.arange(pool.base[pool.top], pool.base[pool.top + 1])]
    if edge:  # the tiles of the data's last row and column: the padding's heights
        want.append(_border_tiles(g, pool))
    kinds = ("delta_edge" if edge else "delta", "height", "xy")
    slots = pool.slots(np.concatenate(want), kinds)[:len(keys)]  # one call: none evicted
    zfac = terrain.frame.z_to_m * terrain.frame.z_scale  # Frame.z
    sc = _scratch(terrain)
    # room for the clip: cut points lie on whole samples of the last row and column,
    # and only faces that hold a piece of them make extra pieces (2 at most each)
    room = (g.rows + g.cols + 1, 2 * (g.rows + g.cols + 4)) if edge else (0, 0)
    faces, level, xyz, ij, lvl, elev, bad = static_leaves(
        keys, slots, pool, zfac, e, sc.vid, sc.leaves, terrain.frame.z_scale,
        D=pool.DE if edge else None, window=(g.rows, g.cols) if edge else None, room=room)
    if bad:  # drop the triangles with an invalid corner (and the elevations of the vertices)
        nf, nv, level = cull_in_place(faces, xyz, ij, np.zeros((0, 4)), lvl, np.zeros(3), 0.0)
        faces, xyz, ij, elev = faces[:nf], xyz[:nv], ij[:nv], None
        if edge:
            lv = np.empty(nf + room[1], level.dtype)
            lv[:nf] = level[:nf]
            level = lv[:nf]
    if edge:  # cut to the data's rectangle, in place (lod/clip.py)
        fb, lb, ib, xb = (a.base if a.base is not None else a for a in (faces, level, ij, xyz))
        nf, nv = clip_in_place(fb, lb, len(faces), ib, xb, len(ij), float(g.rows - 1),
                               float(g.cols - 1), np.int64(pool.N))
        faces, level, ij, xyz, elev = fb[:nf], lb[:nf], ib[:nv], xb[:nv], None
    mesh = mesh_parts(xyz, faces, ij, {"skirt": np.zeros(len(faces), np.uint8), "level": level})
    return add_elevation(mesh, terrain.frame.z_scale, elev), {}


def edge_padding(terrain: TerrainLike) -> bool:
    """Whether the static mesh of ``terrain`` replicates its padding (edgepad.py): a
    square's or a root grid's, whenever the store has a second δ."""
    return bool(EDGE_PADDING and terrain.edge_max is not None and has_padding(terrain.grid))


def static_keys(terrain: TerrainLike, index: TileIndex, pool, e: float, edge: bool) -> np.ndarray:
    """(K, 3) keys of the tiles holding a vertex of the static mesh δ > e (δ_edge with
    ``edge``, and then also the unstored tiles that hold only a second δ)."""
    dmax = _edge_delta_max(terrain, index, pool) if edge else index.delta_max
    keys = np.asarray(index.keys[dmax > e], np.int64)
    if edge:
        more = [k for k, m in terrain.edge_max.items() if k not in terrain.tile_info and m > e]
        keys = np.concatenate([keys, np.array(more, np.int64).reshape(-1, 3)])
    return keys


def _edge_delta_max(terrain: TerrainLike, index: TileIndex, pool) -> np.ndarray:
    """Per index row, the largest δ_edge of the tile's new vertices (its δ's elsewhere)."""
    dmax = np.array(index.delta_max, np.float64)
    if terrain.edge_max:
        row = np.full(int(pool.base[-1]), -1, np.int64)
        row[pool.table_index(index.keys)] = np.arange(len(index.keys))
        ek = [k for k in terrain.edge_max if k in terrain.tile_info]
        rows = row[pool.table_index(np.array(ek, np.int64).reshape(-1, 3))]
        dmax[rows] = [terrain.edge_max[k] for k in ek]
    return dmax


def _border_tiles(g, pool) -> np.ndarray:
    """Table indices of the tiles the samples of the data's last row and column are read
    from (their coarsest tiles)."""
    N = pool.N  # the row stride: a square's side, a root grid's extent's columns
    last_row = (g.rows - 1) * N + np.arange(g.cols, dtype=np.int64)
    last_col = np.arange(g.rows, dtype=np.int64) * N + (g.cols - 1)
    occ = np.zeros(int(pool.base[-1]), bool)
    mark_tiles(np.concatenate([last_row, last_col]), N, g.top_level, g.t, pool.kbase, occ)
    return np.flatnonzero(occ)

"""Strategy ``roam``: Duchaineau et al.'s Real-time Optimally Adapting Meshes (seed 000
§2.2, eq. 4-1, Listing 4-2), with split and merge queues from the last frame's mesh.

- **Two triangle bintrees** share the grid's diagonal (the project's bintree,
  docs/conventions.md). Each triangle keeps its children, parent and three neighbours
  (left, right, base); a **diamond** is a triangle with its base neighbour at the same
  level. Only diamonds split or merge; a triangle whose base neighbour is coarser
  forces that neighbour's split first (recursively), so the mesh never cracks.
- **Wedgie thicknesses** (eq. 4-1), precomputed bottom up once per terrain:
  e_T = max(e_T0, e_T1) + |z(v_c) − (z(v_0) + z(v_1))/2|, 0 at the finest triangles
  (∞ where a triangle's samples mix data and no-data). The wedgie of thickness e_T
  around T holds every full-resolution sample over T.
- **Priorities** (monotone, p(child) ≤ p(parent)): λ·e_T / D, D the distance from the
  eye to the box around T's wedgie (a child's wedgie and box lie inside its parent's);
  0 outside the frustum or behind the horizon (``occlusion``). A leaf with p ≤ τ has
  measured ρ ≤ τ: registered bounded.
- **Per frame** (Listing 4-2): the last frame's mesh is re-scored; the split queue
  splits the highest-priority leaf above τ until none is left, the merge queue then
  merges the lowest-priority mergeable diamond whose priority max(p(T), p(T_B)) is ≤ τ
  (a merge can make its parent diamond mergeable). Choice: the target is the accuracy
  τ, not a triangle budget, so the frame ends with the coarsest conforming mesh whose
  leaves all have p ≤ τ: the same mesh a from-scratch selection gives, reached with work
  that follows the triangles that change. Choice: every triangle is re-scored each
  frame (arithmetic only; the thesis's deferred re-scoring by camera-speed bounds is
  left out).
- **State**: the triangle pool lives in the terrain's derived slot, so any view or τ
  starts from the last mesh and reaches its own; ``select(..., fresh=True)`` starts from
  the base triangles, two per root tile (the from-scratch baseline of the benchmarks).
- The whole grid's heights and wedgies stay in memory (about 24 bytes a sample):
  ROAM is an in-core method.

Geomorphing is not done (``morph`` is ignored). :mod:`geoterrain.lod.roam_split` is
McNally's split-only variant.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.bintree import root_triangles
from geoterrain.core.view import View
from geoterrain.lod import roamkernels as rk
from geoterrain.lod.mesh import empty_parts, mesh_parts
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.roamwedgies import wedgies
from geoterrain.lod.tiles import tile_index, tile_table

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

_INITIAL_SLOTS = 1 << 14


def base_triangles(n: int, roots: tuple[int, int], N: int) -> np.ndarray:
    """The depth-0 triangles of roots of side 2^n (:func:`geoterrain.core.bintree.
    root_triangles`, two per root) as (K, 6): flat sample ids a, b, c (stride N) and
    their neighbours left (across c–a), right (across b–c) and base (across a–b), −1 on
    the domain's border: the two halves of a root share their base, roots side by side
    share a leg.

    Examples
    --------
    >>> base_triangles(1, (1, 1), 3).tolist()  # the square: two triangles, one diagonal
    [[0, 8, 2, -1, -1, 1], [8, 0, 6, -1, -1, 0]]
    >>> base_triangles(1, (2, 1), 5)[:, 3:].tolist()
    [[-1, 2, 1], [-1, -1, 0], [0, -1, 3], [-1, -1, 2]]
    """
    a, b, c = (p[:, 0] * N + p[:, 1] for p in root_triangles(n, roots))
    out = np.full((len(a), 6), -1, np.int64)
    out[:, 0], out[:, 1], out[:, 2] = a, b, c
    held: dict = {}  # each edge (its two ends, sorted) → the (triangle, column) holding it
    for T in range(len(a)):  # at most 2 · MAX_ROOTS triangles, once per terrain
        for col, u, v in ((3, c[T], a[T]), (4, b[T], c[T]), (5, a[T], b[T])):
            key = (min(u, v), max(u, v))
            if key in held:
                T1, col1 = held.pop(key)
                out[T, col], out[T1, col1] = T1, T
            else:
                held[key] = (T, col)
    return out


def _build(terrain: TerrainLike) -> dict:
    g = terrain.grid
    R, N = g.extent  # a square's N × N; a root grid's extent (the lattice, NaN beyond)
    n = g.n
    h, _ = terrain.level_heights(0)
    Z = terrain.frame.z(h)
    if Z.shape != (R, N):
        Z = np.pad(Z, ((0, R - Z.shape[0]), (0, N - Z.shape[1])), constant_values=np.nan)
    Z = np.ascontiguousarray(Z.ravel())
    wedge = np.zeros(2 * R * N, np.float32)
    var = np.zeros(2 * R * N, np.float32)
    wedgies(Z, R, N, n, wedge, var, np.zeros(2 * R * N, np.uint8))
    f = terrain.frame
    margin = 0.0
    if f.kind == "geographic":
        aff = np.zeros(0)
        X, Y = f.grid_xy(N if R == N else (R, N))
        XY = np.stack([np.broadcast_to(X, (R, N)).ravel(), np.broadcast_to(Y, (R, N)).ravel()])
        # a sample inside a triangle lies within twice the frame's largest departure from
        # its best affine map of the triangle's straight-edged hull
        i, j = np.divmod(np.arange(R * N), N)
        A = np.stack([i, j, np.ones_like(i)], 1).astype(np.float64)
        res = XY.T - A @ np.linalg.lstsq(A, XY.T, rcond=None)[0]
        margin = 2.0 * float(np.sqrt((res ** 2).sum(1)).max())
    else:
        aff = np.array([*f.transform[:6], *f.origin_crs, f.unit_to_m], np.float64)
        XY = np.zeros((2, 1))
    fin = np.isfinite(Z)
    zr = np.array([Z[fin].min(), Z[fin].max(), margin]) if fin.any() else np.zeros(3)
    index = tile_index(terrain)
    table, _ = tile_table(index, g.top_level, g)
    levels = list(g.levels)
    tile = np.concatenate([g.offsets()[: g.top_level + 1], [g.tiles(L)[0] for L in levels],
                           [g.tiles(L)[1] for L in levels], [g.t, g.top_level, N]]
                          ).astype(np.int64)
    tb = rk.RoamTables(Z, wedge, var, aff, XY, zr, np.zeros(0, np.uint8), tile,
                       np.array([N, n], np.int64), base_triangles(n, g.roots, N))
    return {"tables": tb, "table": table, "vmap": np.full(R * N, -1, np.int32)}


def tables(terrain: TerrainLike) -> dict:
    """The terrain's ROAM tables (built once: heights, wedgies, variances, the tile
    table), cached in its derived slot.

    Examples
    --------
    >>> tb = tables(t)["tables"]
    >>> tb.wedge.dtype, bool((tb.wedge >= 0).all())
    (dtype('float32'), True)
    """
    return terrain.derived(f"{__name__}.tables", lambda: _build(terrain))


def _motion(state: dict, view: View, tau: float, hid: np.ndarray, key: tuple,
            extent: float) -> rk.Motion:
    """This frame's :class:`~geoterrain.lod.roamkernels.Motion`: the eye's path and the
    frustum's turn since the last frame, cumulated, and which tiles' horizon culling
    changed. Everything is re-scored when the view's projection, τ or the switches
    changed."""
    basis = np.stack(view.basis())
    k = state.get("k", -1) + 1
    cum, ang = state.get("cum"), state.get("ang")
    if cum is None or k >= len(cum):
        n = max(64, 2 * k)
        cum = np.concatenate([cum, np.zeros(n - len(cum))]) if cum is not None else np.zeros(n)
        ang = np.concatenate([ang, np.zeros(n - len(ang))]) if ang is not None else np.zeros(n)
    full = state.get("key") != key or k == 0
    if k > 0:
        R = basis @ state["basis"].T
        turn = float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
        step = float(np.linalg.norm(view.eye - state["eye"]))
        # a little more than measured: the deferral must never be fooled by rounding
        cum[k] = cum[k - 1] + step + 1e-9 * extent
        ang[k] = ang[k - 1] + turn + 1e-12
    hidk = state.get("hidk")
    if hidk is None or len(hidk) != len(hid):
        hidk = np.zeros(len(hid), np.int64)
        full = True
    else:
        hidk[hid != state["hid"]] = k
    state.update(k=k, cum=cum, ang=ang, basis=basis, eye=view.eye.copy(), key=key,
                 hid=hid.copy(), hidk=hidk)
    return rk.Motion(cum, ang, hidk, np.array([k, cum[k], ang[k], float(full)]))


def run(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool, mode: int,
        incremental: bool, fresh: bool, owner: str):
    """One ROAM frame for ``view`` (``mode`` 0: wedgie priorities; 1: McNally's), from
    the last frame's mesh (``incremental``, unless ``fresh``) or from the base triangles;
    the mesh of the drawn leaves and the stats."""
    index = tile_index(terrain)
    if index.outside(view):
        return empty_parts(), {}
    held = tables(terrain)
    tb = held["tables"]
    N, n = int(tb.size[0]), int(tb.size[1])
    table = held["table"]
    hid = np.zeros(len(table), np.uint8)
    if occlusion:
        hidden = hidden_rows(terrain, view)
        if hidden.any():
            hid = np.where(table >= 0, hidden[np.maximum(table, 0)], False).astype(np.uint8)
            tb = tb._replace(hid=hid)
    state = terrain.derived(owner, dict)
    pool = state.get("pool")
    if pool is None:
        pool = rk.new_pool(_INITIAL_SLOTS)
        rk.reset(pool, tb)
    elif fresh or not incremental:
        rk.reset(pool, tb)
    key = (view.lam, float(tau), view.size, view.fov_y_deg, view.near, view.far, occlusion,
           mode)
    mo = _motion(state, view, tau, hid, key, float(tb.zr[1] - tb.zr[0]) + float(N))
    splits0, merges0, scored0 = (int(v) for v in pool.meta[2:5])
    stack = np.empty(4 * (2 * n + 4), np.int64)
    vt = view.terms(tau)
    t0 = time.perf_counter()
    while rk.update(pool, tb, vt, mode, incremental, stack, mo) == rk.NEED_SPACE:
        pool = rk.grow_pool(pool)
    ms = (time.perf_counter() - t0) * 1e3
    state["pool"] = pool
    used = int(pool.meta[0])
    faces = np.empty((used, 3), np.int64)
    verts = np.empty(3 * used, np.int64)
    depth = np.empty(used, np.int32)
    V, F = rk.emit(pool, tb, vt.planes, held["vmap"], verts, faces, depth)
    iv = pool.iv[:used]
    stats = {"roam_ms": round(ms, 3), "splits": int(pool.meta[2]) - splits0,
             "merges": int(pool.meta[3]) - merges0, "scored": int(pool.meta[4]) - scored0,
             "leaves": int(((iv[:, rk.ALIVE] == 1) & (iv[:, rk.K0] < 0)).sum())}
    if F == 0:
        return empty_parts(), stats
    verts, faces = verts[:V], faces[:F]
    i, j = np.divmod(verts, N)
    if tb.aff.shape[0]:
        x, y = terrain.frame.xy(i, j)
    else:
        x, y = tb.XY[0, verts], tb.XY[1, verts]
    xyz = np.stack([x, y, tb.Z[verts]], 1)
    level = ((2 * n - depth[:F]) // 2).astype(np.int16)
    mesh = mesh_parts(xyz, faces, np.stack([i, j], 1),
                    {"skirt": np.zeros(F, np.uint8), "level": level})
    return mesh, stats


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, fresh: bool = False):
    """The ROAM mesh of ``view`` at pixel tolerance ``tau``, from the last frame's mesh
    (``fresh``: from the base triangles, two per root), and its stats (``splits``, ``merges``,
    ``roam_ms``: the queues' time); ``morph`` is ignored.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> again, st2 = select(t, View((0, -790, 400), (0, 0, 0)), 1.0)
    >>> stats["splits"] > 0 and st2["splits"] + st2["merges"] < stats["splits"]
    True
    """
    return run(terrain, view, tau, occlusion=occlusion, mode=0, incremental=True,
               fresh=fresh, owner=f"{__name__}.state")

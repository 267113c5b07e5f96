"""Strategy ``rottger``: Röttger et al.'s "Real-Time Generation of Continuous Levels of
Detail for Height Fields" (seed 000 §2.3, eq. 4-3 … 4-6).

- **The quadtree as a matrix.** A node is a (2h+1)² square of the padded grid centred on
  sample (c_i, c_j), h = 1 at the finest; one value per node sits at its centre sample, so
  the whole tree fits a matrix the size of the height field (kept here as one array per
  depth).
- **Roughness** d2 (eq. 4-4), precomputed: (1/d)·max|dh_i| over the node's six
  differences (its four edge midpoints and, for its centre, the two diagonals, each
  against the mean of its two neighbours), d = 2h·spacing the node's edge. Propagated
  bottom up (eq. 4-6): d2 = max(local, K·d2 of the finer nodes adjacent to it), K = C /
  (2(C − 1)). Choice: "the adjacent nodes of the level below" are the node's four
  children and the eight finer nodes across its edges. A node mixing data and no-data
  gets d2 = ∞ (it is always subdivided).
- **Subdivision** (eq. 4-5): f = l / (d·C·max(c·d2, 1)), subdivide while f < 1; l the L1
  distance from the eye to the node's centre, C = 8 (the recommended minimum global
  resolution). Choice: the desired global resolution c = λ/(τ·C), so that c·C·d·d2 =
  λ·max|dh|/τ: a node is subdivided while its largest height change would project to more
  than τ at the L1 distance (and, by C, while it is nearer than 8 of its own edges).
  Frustum culling per node box, during the subdivision and the drawing (§2.3, culling).
- **Fans** of 8 triangles around each leaf's centre, skipping an edge midpoint next to a
  coarser leaf (fig. 4-10): the union-jack triangles of the leaf, the pair on that edge
  replaced by its bintree parent, so the mesh is conforming.
- **Bound.** Röttger's rule is not a bound (d2 is one level's change, not a sum). Choice:
  after it, every leaf whose fan error bound projects past τ is subdivided: the largest
  LP δ (seed 002, the project's saturated per-vertex error) of its four quarter centres
  (the split vertices of its fan triangles) and of each midpoint it skips, over the
  distance to the leaf's box; and neighbours keep levels differing by at most one (the
  restricted quadtree of :mod:`geoterrain.lod.quadtree`; the stats count what each pass
  added). So ρ ≤ τ: registered bounded.
- **Geomorphing** (``morph=True``, off by default; eq. 4-7): each leaf's centre and edge
  midpoints blend between the parent's surface and their heights by b = clamp(2(1 − f),
  0, 1), neighbours sharing a midpoint taking the smaller b; a vertex moves only where the
  bound still holds (:func:`_morph`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import OUTSIDE, View
from geoterrain.lod.mesh import empty_parts
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.quadtree import assemble_leaves, paint, restrict_leaves
from geoterrain.lod.tiles import tile_index, tile_table

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

C_MIN = 8.0  # eq. 4-3: C, the minimum global resolution Röttger recommends


class Tables:
    """Per depth k (node half-size h = 2^(n−k−1)): the propagated roughness ``d2``, the
    footprint's height range ``zmin``/``zmax`` (no-data left out), ``mixed`` (data and
    no-data in one node), and each node's centre height; the whole grid's δ (for the
    bound) and spacing."""

    def __init__(self, terrain: TerrainLike):
        g = terrain.grid
        R, N = g.extent  # a square's N × N; a root grid's extent (roots of side 2^n)
        n = g.n
        self.N, self.n = N, n  # N: the columns, the stride of the keys i·N + j
        h0, v = terrain.level_heights(0)
        Z = terrain.frame.z(h0)
        r, c = Z.shape  # the level-0 lattice; beyond it (a root grid's) no data, δ = 0
        ii, jj = np.meshgrid(np.arange(r), np.arange(c), indexing="ij")
        delta = terrain.gather(ii.ravel(), jj.ravel(), ("delta",))["delta"].reshape(r, c)
        if (r, c) != (R, N):
            Z = np.pad(Z, ((0, R - r), (0, N - c)), constant_values=np.nan)
            delta = np.pad(delta, ((0, R - r), (0, N - c)))
        self.Z, self.delta = Z, delta
        i = np.array([0, 0, R - 1])
        j = np.array([0, N - 1, 0])
        x, y = terrain.frame.xy(i, j)
        self.dx = float(min(np.hypot(x[1] - x[0], y[1] - y[0]) / (N - 1),
                            np.hypot(x[2] - x[0], y[2] - y[0]) / (R - 1)))
        K = C_MIN / (2.0 * (C_MIN - 1.0))  # eq. 4-6
        self.d2, self.zmin, self.zmax, self.mixed = [], [], [], []
        finer = None
        lo = hi = anyv = anyi = None
        for k in range(n - 1, -1, -1):  # finest (h = 1) first
            h = 1 << (n - k - 1)
            s = 2 * h
            c = Z[h::s, h::s]
            c00, c01 = Z[0:-1:s, 0:-1:s], Z[0:-1:s, s::s]
            c10, c11 = Z[s::s, 0:-1:s], Z[s::s, s::s]
            mt, mb = Z[0:-1:s, h::s], Z[s::s, h::s]
            ml, mr = Z[h::s, 0:-1:s], Z[h::s, s::s]
            with np.errstate(invalid="ignore"):
                dh = np.stack([np.abs(mt - 0.5 * (c00 + c01)), np.abs(mb - 0.5 * (c10 + c11)),
                               np.abs(ml - 0.5 * (c00 + c10)), np.abs(mr - 0.5 * (c01 + c11)),
                               np.abs(c - 0.5 * (c00 + c11)), np.abs(c - 0.5 * (c01 + c10))])
            local = np.nanmax(np.where(np.isnan(dh), -np.inf, dh), axis=0) / (s * self.dx)
            if finer is None:  # h = 1: the node's 3 × 3 samples
                win = np.stack([Z[a:R - 2 + a:2, b:N - 2 + b:2] for a in range(3)
                                for b in range(3)])
                ok = np.isfinite(win)
                anyv, anyi = ok.any(0), (~ok).any(0)
                with np.errstate(invalid="ignore"):
                    lo = np.where(anyv, np.nanmin(np.where(ok, win, np.inf), 0), 0.0)
                    hi = np.where(anyv, np.nanmax(np.where(ok, win, -np.inf), 0), 0.0)
                d2 = local
            else:
                lo = _reduce(lo, np.minimum)
                hi = _reduce(hi, np.maximum)
                anyv = _reduce(anyv, np.logical_or)
                anyi = _reduce(anyi, np.logical_or)
                d2 = np.maximum(local, K * _adjacent_max(finer))  # eq. 4-6
            mixed = anyv & anyi
            d2 = np.where(mixed, np.inf, np.maximum(d2, 0.0))
            self.d2.insert(0, d2.astype(np.float64))
            self.zmin.insert(0, lo)
            self.zmax.insert(0, hi)
            self.mixed.insert(0, mixed)
            finer = d2
        index = tile_index(terrain)
        self.table, self.base = tile_table(index, g.top_level, g)
        self.t, self.top, self.roots = g.t, g.top_level, g.roots
        self.tiles = [g.tiles(L) for L in g.levels]  # (across, down) per level


def _reduce(a: np.ndarray, op) -> np.ndarray:
    return op(op(a[0::2, 0::2], a[0::2, 1::2]), op(a[1::2, 0::2], a[1::2, 1::2]))


def _adjacent_max(F: np.ndarray) -> np.ndarray:
    """Per node of the next coarser depth, the largest value of its four children and of
    the eight finer nodes across its edges (eq. 4-6's "adjacent nodes of the level
    below")."""
    out = _reduce(F, np.maximum)
    P = np.pad(F, 1, constant_values=-np.inf)
    out = np.maximum(out, np.maximum(P[0:-2:2, 1:-1:2], P[0:-2:2, 2::2]))  # above
    out = np.maximum(out, np.maximum(P[3::2, 1:-1:2], P[3::2, 2::2]))  # below
    out = np.maximum(out, np.maximum(P[1:-1:2, 0:-2:2], P[2::2, 0:-2:2]))  # left
    out = np.maximum(out, np.maximum(P[1:-1:2, 3::2], P[2::2, 3::2]))  # right
    return out


def tables(terrain: TerrainLike) -> Tables:
    """The terrain's Röttger :class:`Tables`, built once (reads every level-0 tile).

    Examples
    --------
    >>> tb = tables(t)
    >>> len(tb.d2) == t.grid.n and tb.d2[-1].shape == ((t.grid.size - 1) // 2,) * 2
    True
    """
    return terrain.derived(__name__, lambda: Tables(terrain))


def _tile_rows(tb: Tables, k: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The index row of the smallest stored tile holding each depth-k node (−1: none)."""
    span = tb.n - k  # log2 of the node's edge in samples
    L = max(span - tb.t, 0)
    sh = max(tb.t + L - span, 0)
    across, down = tb.tiles[L]
    return tb.table[tb.base[L] + np.minimum(y >> sh, down - 1) * across
                    + np.minimum(x >> sh, across - 1)]


def _boxes(terrain: TerrainLike, tb: Tables, k: int, x: np.ndarray, y: np.ndarray):
    """Each node's box: its corners' x, y (on a curvilinear frame, its stored tile's x, y,
    which hold every sample's) and its samples' height range."""
    h = 1 << (tb.n - k - 1)
    if terrain.frame.kind == "geographic":
        index = tile_index(terrain)
        rows = np.maximum(_tile_rows(tb, k, x, y), 0)
        lo, hi = index.lo[rows].copy(), index.hi[rows].copy()
    else:
        i0, j0 = y * 2 * h, x * 2 * h
        X, Y = terrain.frame.xy(np.stack([i0, i0, i0 + 2 * h, i0 + 2 * h]),
                                np.stack([j0, j0 + 2 * h, j0, j0 + 2 * h]))
        lo = np.stack([X.min(0), Y.min(0), np.zeros(len(x))], 1)
        hi = np.stack([X.max(0), Y.max(0), np.zeros(len(x))], 1)
    lo[:, 2], hi[:, 2] = tb.zmin[k][y, x], tb.zmax[k][y, x]
    return lo, hi


def _hidden(tb: Tables, hidden: np.ndarray, k: int, x: np.ndarray, y: np.ndarray):
    """Whether the smallest stored tile holding each node is hidden."""
    if not hidden.any():
        return np.zeros(len(x), bool)
    rows = _tile_rows(tb, k, x, y)
    return (rows >= 0) & hidden[np.maximum(rows, 0)]


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None):
    """The Röttger mesh of ``view`` at pixel tolerance ``tau`` and its stats; ``morph``:
    eq. 4-7's blend (off unless True).

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> mesh.n_cells > 0 and stats["leaves"] > 0
    True
    """
    index = tile_index(terrain)
    if index.outside(view):
        return empty_parts(), {}
    tb = tables(terrain)
    eye, lam = view.eye, view.lam
    c = lam / (tau * C_MIN)  # the desired global resolution from τ
    hidden = hidden_rows(terrain, view, enabled=occlusion)
    rx, ry = tb.roots  # depth 0: every root (one on a square grid)
    x, y = np.tile(np.arange(rx), ry), np.repeat(np.arange(ry), rx)
    leaves, visited, culled = [], 0, 0
    splits: dict[int, tuple] = {}  # per depth: the nodes the rule split (keys) and their f
    for k in range(tb.n):
        h = 1 << (tb.n - k - 1)
        visited += len(x)
        lo, hi = _boxes(terrain, tb, k, x, y)
        keep = (view.box_visibility(lo, hi) != OUTSIDE) & ~_hidden(tb, hidden, k, x, y)
        keep &= tb.zmax[k][y, x] >= tb.zmin[k][y, x]  # (a node with no data at all)
        culled += int((~keep).sum())
        x, y, lo, hi = x[keep], y[keep], lo[keep], hi[keep]
        if not len(x):
            break
        ci, cj = (2 * y + 1) * h, (2 * x + 1) * h
        cx, cy = terrain.frame.xy(ci, cj)
        cz = tb.Z[ci, cj]
        cz = np.where(np.isfinite(cz), cz, 0.5 * (lo[:, 2] + hi[:, 2]))
        ell = np.abs(cx - eye[0]) + np.abs(cy - eye[1]) + np.abs(cz - eye[2])  # L1 (eq. 3-2)
        d = 2 * h * tb.dx
        with np.errstate(invalid="ignore", divide="ignore"):
            f = ell / (d * C_MIN * np.maximum(c * tb.d2[k][y, x], 1.0))  # eq. 4-5
        split = (f < 1.0) & (h > 1)
        leaves.append((k, x[~split], y[~split]))
        splits[k] = (y[split].astype(np.int64) << 32) + x[split], f[split]
        x = (np.repeat(x[split], 4) << 1) + np.tile([0, 1, 0, 1], int(split.sum()))
        y = (np.repeat(y[split], 4) << 1) + np.tile([0, 0, 1, 1], int(split.sum()))
        if not len(x):
            break
    leaves = [lv for lv in leaves if len(lv[1])]
    stats = {"tiles_visited": visited, "tiles_culled": culled}
    if not leaves:
        return empty_parts(), stats
    seed = sum(len(v[1]) for v in leaves)
    leaves, D, dmax, added = _bound(terrain, tb, view, tau, leaves)
    mesh = assemble_leaves(terrain, leaves, D, dmax)
    stats.update(leaves=sum(len(v[1]) for v in leaves), seed_leaves=seed,
                 bound_splits=added[0], restricted_splits=added[1], depth=dmax)
    if morph and mesh.n_points:
        stats["morphing_vertices"] = _morph(terrain, tb, view, tau, leaves, D, dmax, splits,
                                            mesh)
    return mesh, stats


def _morph(terrain: TerrainLike, tb: Tables, view: View, tau: float, leaves, D, dmax: int,
           splits: dict, mesh) -> int:
    """Eq. 4-7's geomorph, in place on ``mesh``: each leaf's five vertices that its parent
    lacks (centre, edge midpoints) are drawn at c + b·(z − c), c the parent's surface there
    (the mean of the two samples bracketing it), b = clamp(2(1 − f), 0, 1) from the
    parent's f (1 where the bound or the restriction, not the rule, split the parent);
    a vertex two leaves share takes the smaller b (L1511–1513). Choice, for the bound: a
    vertex moves only if every leaf it belongs to keeps λ·(its fan bound + the largest δ
    of its vertices) / D_min ≤ τ (δ(v) bounds how far v's morph moves it: the parent's
    surface at v is the bintree surface without v). Returns how many vertices moved."""
    N = tb.N
    ij = np.asarray(mesh.point_data["grid_ij"]).astype(np.int64)
    pts = np.asarray(mesh.points)
    key = ij[:, 0] * N + ij[:, 1]
    order = np.argsort(key)
    skey = key[order]
    V = len(key)
    ok = np.ones(V, bool)
    fac = np.ones(V)
    coarse = np.full(V, np.nan)
    P = np.pad(D, 1, constant_values=-1)
    lam = view.lam
    a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    groups = []
    for k, x, y in leaves:  # first: each leaf's vertices, and the five that may move
        h = 1 << (tb.n - k - 1)
        i0, j0 = y * 2 * h, x * 2 * h
        ii = i0[:, None] + (a.ravel() * h)[None]
        jj = j0[:, None] + (b.ravel() * h)[None]
        pos = np.minimum(np.searchsorted(skey, ii * N + jj), V - 1)
        ids = np.where(skey[pos] == ii * N + jj, order[pos], -1)
        bl = np.ones(len(x))  # b from the parent's f (eq. 4-7); 1 where the rule did not
        pk, pf = splits.get(k - 1, (np.zeros(0, np.int64), np.zeros(0)))  # split it
        if len(pk):
            srt = np.argsort(pk)
            pk, pf = pk[srt], pf[srt]
            want = ((y >> 1).astype(np.int64) << 32) + (x >> 1)
            p = np.minimum(np.searchsorted(pk, want), len(pk) - 1)
            bl = np.where(pk[p] == want, np.clip(2.0 * (1.0 - pf[p]), 0.0, 1.0), 1.0)
        # the five new vertices' coarse heights: the parent's surface, whose union jack
        # at the parent's spacing splits this quarter along (0,0)–(2,2) or (0,2)–(2,0)
        main = ((i0 // (2 * h)) + (j0 // (2 * h))) % 2 == 0
        Zc = tb.Z[ii, jj]  # (L, 9): the leaf's 3 × 3, row by row
        cen = np.where(main, 0.5 * (Zc[:, 0] + Zc[:, 8]), 0.5 * (Zc[:, 2] + Zc[:, 6]))
        for slot, c in ((4, cen), (1, 0.5 * (Zc[:, 0] + Zc[:, 2])),
                        (7, 0.5 * (Zc[:, 6] + Zc[:, 8])), (3, 0.5 * (Zc[:, 0] + Zc[:, 6])),
                        (5, 0.5 * (Zc[:, 2] + Zc[:, 8]))):
            v = ids[:, slot]
            s_ = (v >= 0) & (bl < 1.0)
            np.minimum.at(fac, v[s_], bl[s_])
            coarse[v[s_]] = c[s_]
        groups.append((k, x, y, ii, jj, ids))
    moving = (fac < 1.0) & np.isfinite(coarse)
    for k, x, y, ii, jj, ids in groups:  # then: which leaves keep the bound while they move
        e = _leaf_error(tb, P, dmax, k, x, y)
        lo, hi = _boxes(terrain, tb, k, x, y)
        dist = view.box_distance(lo, hi)
        mv = (ids >= 0) & moving[np.maximum(ids, 0)]
        dv = np.where(mv, np.nan_to_num(tb.delta[ii, jj], nan=np.inf), 0.0).max(1)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            allowed = lam * (e + dv) <= tau * dist
        m = ids >= 0
        np.logical_and.at(ok, ids[m], np.repeat(allowed, 9).reshape(-1, 9)[m])
    go = ok & (fac < 1.0) & np.isfinite(coarse)
    z = pts[:, 2].copy()
    z[go] = coarse[go] + fac[go] * (z[go] - coarse[go])
    pts = pts.copy()
    pts[:, 2] = z
    mesh.points = pts
    return int(go.sum())


_SIDES = (((-1, 0), (-1, 0)), ((1, 0), (None, 0)), ((0, -1), (0, -1)), ((0, 1), (0, None)))


def _leaf_error(tb: Tables, P: np.ndarray, dmax: int, k: int, x: np.ndarray, y: np.ndarray
                ) -> np.ndarray:
    """A bound of each depth-k leaf's fan surface against the samples: the largest LP δ
    of its fan triangles' split vertices (its quarter centres) and of each edge midpoint
    it skips (the neighbour across is coarser; ``P``: the padded depth map)."""
    h = 1 << (tb.n - k - 1)
    ci, cj = (2 * y + 1) * h, (2 * x + 1) * h
    e = np.zeros(len(x))
    if h > 1:
        q = h // 2
        for a, b in ((-q, -q), (-q, q), (q, -q), (q, q)):
            e = np.maximum(e, tb.delta[ci + a, cj + b])
    cc = 1 << (dmax - k)
    r0, c0 = y * cc + 1, x * cc + 1
    for (di, dj), (pr, pc) in _SIDES:
        nb = P[r0 + (cc if pr is None else pr), c0 + (cc if pc is None else pc)]
        skip = (nb >= 0) & (nb < k)
        e = np.where(skip, np.maximum(e, tb.delta[ci + di * h, cj + dj * h]), e)
    return e


def _bound(terrain: TerrainLike, tb: Tables, view: View, tau: float, leaves):
    """Subdivide the leaves whose fan error bound projects past τ (and restrict the tree),
    until none does. Returns the leaves, the painted depth map and how many nodes each
    pass split (bound, restriction)."""
    lam = view.lam
    by = {k: (x, y) for k, x, y in leaves}
    n_bound = n_restrict = 0
    while True:
        lv = [(k, *by[k]) for k in sorted(by) if len(by[k][0])]
        before = sum(len(v[1]) for v in lv)
        lv, D, dmax = restrict_leaves(lv, tb.roots)
        n_restrict += (sum(len(v[1]) for v in lv) - before) // 3
        by = {k: (x, y) for k, x, y in lv}
        grow = []  # (depth, x, y) of nodes to split
        P = np.pad(D, 1, constant_values=-1)
        for k, x, y in lv:
            h = 1 << (tb.n - k - 1)
            lo, hi = _boxes(terrain, tb, k, x, y)
            dist = view.box_distance(lo, hi)
            ci, cj = (2 * y + 1) * h, (2 * x + 1) * h
            e = _leaf_error(tb, P, dmax, k, x, y)
            cc = 1 << (dmax - k)
            r0, c0 = y * cc + 1, x * cc + 1
            with np.errstate(invalid="ignore", divide="ignore"):
                bad = ~(lam * e <= tau * dist) & (h > 1)
            if bad.any():
                grow.append((k, x[bad], y[bad]))
            # a skipped midpoint past τ at a finest leaf: its coarser neighbour splits
            if h == 1:
                for (di, dj), (pr, pc) in (((-h, 0), (-1, 0)), ((h, 0), (cc, 0)),
                                           ((0, -h), (0, -1)), ((0, h), (0, cc))):
                    nb = P[r0 + pr, c0 + pc]
                    skip = (nb >= 0) & (nb < k)
                    with np.errstate(invalid="ignore", divide="ignore"):
                        over = skip & ~(lam * tb.delta[ci + di, cj + dj] <= tau * dist)
                    if over.any():
                        kn = nb[over]
                        rr, cc_ = r0[over] + pr - 1, c0[over] + pc - 1
                        for kk in np.unique(kn).tolist():
                            s = kn == kk
                            sh = dmax - kk
                            grow.append((kk, cc_[s] >> sh, rr[s] >> sh))
        if not grow:
            return lv, D, dmax, (n_bound, n_restrict)
        for k, x, y in grow:
            ox, oy = by[k]
            key = np.unique(np.asarray(y, np.int64) * (1 << 40) + np.asarray(x, np.int64))
            mine = oy.astype(np.int64) * (1 << 40) + ox
            hit = np.isin(mine, key)
            if not hit.any():
                continue
            n_bound += int(hit.sum())
            by[k] = (ox[~hit], oy[~hit])
            sx, sy = ox[hit], oy[hit]
            cx = (np.repeat(sx, 4) << 1) + np.tile([0, 1, 0, 1], len(sx))
            cy = (np.repeat(sy, 4) << 1) + np.tile([0, 0, 1, 1], len(sy))
            px, py = by.get(k + 1, (np.zeros(0, np.int64),) * 2)
            by[k + 1] = (np.concatenate([px, cx]), np.concatenate([py, cy]))


__all__ = ["select", "tables", "paint"]

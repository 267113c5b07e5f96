"""Strategy ``cdlod``: Strugar's continuous distance-dependent LOD (seed 001 §2.6–2.7).

- **Quadtree of stored tiles, one view range per level** (seed 001 §2.6, Listing 3.1):
  a node of level L is drawn whole when its box does not meet the sphere of radius
  r_{L−1} around the eye; otherwise each child whose box meets that sphere is selected
  in turn, and each child that does not is drawn as a *partial node*: the child's
  quadrant of the parent tile, i.e. at half the child's resolution. The top level's
  range is infinite. Frustum culling top-down against the stored tile boxes; a box
  fully inside passes that to its children.
- **Morph** (seed 001 §2.7, Strugar's k): a sample whose home level is h (the finest
  level whose grid holds it, so it is odd at h) slides onto the midpoint of its two
  level-(h+1) neighbours, the end points of the level-(h+1) union-jack edge or
  diagonal it splits, by k = clamp((d − m_h) / (r_h − m_h), 0, 1), d its distance to
  the eye and m_h = r_h − f·(r_h − r_{h−1}) (f = ``morph_fraction``, the seed's half).
  The neighbours' own morphed positions are used, so a sample has one position
  whatever node draws it (path independent). At k = 1 every odd vertex lies on the
  parent's surface, so a node matches its parent exactly. Choice: the vertex keeps its
  grid sample (i, j), which already is the midpoint of its neighbours, and moves in
  the scene frame (x, y, z) toward their midpoint, not along the grid as the seed's
  g' = g − (g mod 2)·k does: then the drawn surface is a blend of the two nested
  union-jack surfaces sampled at grid points, which the error bound below needs.
  ``morph_fraction = 0`` (``morph=False``) snaps k from 0 to 1 at r_h: no morph, same
  selection, crack-free, but vertices pop.
- **No skirts, no gap**: the samples on the edge between a level-L region and a coarser
  one are at distance ≥ r_L (the coarser region's box misses the sphere r_L), so
  k = 1 there and the finer side's odd edge vertices lie on the coarser side's edges,
  whose end points both sides place at the same (morphed) positions. The error bound
  assumes the restricted quadtree the ranges give; where no-data forces splits beyond
  a range, coarser samples may be mid-morph too (measured, not proven, there).
- **Ranges** (the seed leaves them open; Strugar doubles them). Chosen per call from the
  stored tile numbers and λ, τ so that measured ρ ≤ τ holds with morphing on. Per
  level L: e_L = the largest stored tile error (a region drawn at L is at distance
  ≥ r_{L−1}, so r_{L−1} ≥ λ·e_L/τ); M_L = e_{L+1} bounds the morph displacement (a
  sample moves only inside a level-(L+1) tile of finite error, which bounds
  |z − S_{L+1}| at the sample); a sample of a level-L triangle is off by at most
  e_L + M_L once a corner morphs, which happens only at distance ≥ m_L − c_L (c_L: the
  largest 3-D distance between two samples of one level-L cell), so
  m_L − c_L ≥ λ·(e_L + M_L)/τ; and seed 001's crack-free range
  constraint (L407), (1 − f)·(r_{L+1} − r_L) ≥ diag_L, the largest level-L tile box
  diagonal, heights included, so that a level-L node's samples never reach the
  morph zone of level L+1 (they keep k = 0 there). Each r_L is the smallest value
  meeting all three, level by level upward.
- **No data**: a tile whose stored error is infinite (a triangle that mixes valid and
  no-data samples) is never drawn; it is split to its children. Triangles with a
  no-data corner are dropped; a sample with a no-data neighbour, or in no level-(h+1)
  tile of finite error, does not morph. No gap follows: a sample on the edge of a
  drawn coarser region lies in that region's tile, of finite error (errors grow up
  the quadtree, so its finer tiles are finite too).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.bintree import vertex_level
from geoterrain.core.view import INSIDE, OUTSIDE, View
from geoterrain.exceptions import UsageError
from geoterrain.lod.mesh import empty_parts, mesh_parts
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.registry import strategy_info
from geoterrain.lod.tiles import TileIndex, tile_geometry, tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

MORPH_FRACTION = 0.5  # seed 001 §2.7: half of each level's range morphs
_SAFE = 1.0 + 1e-6  # margin on every range bound (float round-off of distances)
_END = 1.0 - 1e-9  # k = 1 from r·_END on: a boundary sample never falls just short of r


class LevelTables:
    """Per-level numbers from the stored tiles: e_L, M_L, c_L, diag_L (scene units)."""

    def __init__(self, terrain: TerrainLike, index: TileIndex):
        g = terrain.grid
        top = g.top_level
        L = index.keys[:, 0]
        err = index.error
        ext = index.hi - index.lo
        diag = np.linalg.norm(ext, axis=1)
        cell = np.hypot(np.hypot(ext[:, 0], ext[:, 1]) / (1 << g.t), ext[:, 2])
        self.drawable = np.isfinite(err) | (L == 0)

        def level_max(v: np.ndarray) -> np.ndarray:
            out = np.zeros(top + 1)
            ok = np.isfinite(v)
            np.maximum.at(out, L[ok], v[ok])
            return out

        self.e = level_max(np.where(L == 0, 0.0, err))
        # a sample of home level h moves only inside a level-(h+1) tile of finite error,
        # which bounds |z − S_{h+1}| there, so the move: M_h = e_{h+1}
        self.m = np.r_[self.e[1:], 0.0]
        self.finite = []  # per level: (rows, cols) of tiles → finite stored error
        for lv in range(top + 1):
            a = np.zeros(g.tiles(lv)[::-1], bool)  # (down, across)
            k = np.flatnonzero((L == lv) & np.isfinite(err))
            a[index.keys[k, 2], index.keys[k, 1]] = True
            self.finite.append(a)
        self.span = [1 << (g.t + lv) for lv in range(top + 1)]
        self.c = level_max(cell)
        self.diag = level_max(diag)
        self.top = top


def _stride(grid) -> int:
    """The row stride of the sample keys i·N + j: a square's N, a root grid's extent
    columns (every sample a walk reaches lies in the roots' extent)."""
    return grid.extent[1]


def _tables(terrain: TerrainLike, index: TileIndex) -> LevelTables:
    return terrain.derived(f"{__name__}.tables", lambda: LevelTables(terrain, index))


def ranges(tb: LevelTables, lam: float, tau: float, fraction: float = MORPH_FRACTION
           ) -> tuple[np.ndarray, np.ndarray]:
    """View ranges r_L and morph starts m_L (L = 0 … top; r_top = m_top = ∞).

    The smallest increasing ranges with r_{L−1} ≥ λe_L/τ, m_L − c_L ≥ λ(e_L + M_L)/τ and
    (1 − f)(r_{L+1} − r_L) ≥ diag_L (the module docstring says why).

    Examples
    --------
    >>> from geoterrain.lod.tiles import tile_index
    >>> r, m = ranges(_tables(t, tile_index(t)), 1000.0, 1.0)
    >>> bool(np.all(np.diff(r[:-1]) > 0)) and bool(np.all(m[:-1] < r[:-1])), float(r[-1])
    (True, inf)
    """
    f = float(fraction)
    top = tb.top
    r = np.full(top + 1, np.inf)
    m = np.full(top + 1, np.inf)
    prev = 0.0
    for L in range(top):
        need = [lam * tb.e[L + 1] / tau * _SAFE, prev * (1 + 1e-9) + 1e-9]
        # m_L = (1 − f)·r_L + f·r_{L−1} (capped at r_L·_END) − c_L ≥ λ(e_L + M_L)/τ
        budget = (lam * (tb.e[L] + tb.m[L]) / tau + tb.c[L]) * _SAFE
        need.append(max((budget - f * prev) / (1 - f), budget / _END) if f < 1
                    else budget / _END)
        if L > 0:
            need.append(prev + tb.diag[L - 1] * _SAFE / (1 - f) if f < 1 else math.inf)
        r[L] = max(need)
        m[L] = min((1 - f) * r[L] + f * prev, r[L] * _END)
        prev = r[L]
    return r, m


def _parts(terrain: TerrainLike, index: TileIndex, row: int):
    """Cached per tile: global sample keys, positions, faces and each face's quadrant bit."""
    cache = terrain.derived(f"{__name__}.parts", dict)
    got = cache.get(row)
    if got is None:
        ij, xyz, _valid, faces = tile_geometry(terrain, index, row)
        T = terrain.grid.tile_samples
        key = ij[:, 0].astype(np.int64) * _stride(terrain.grid) + ij[:, 1]
        r3 = (faces // T).sum(1)  # 3 × each face's centroid, local row and column
        c3 = (faces % T).sum(1)
        half3 = 3 * (T - 1) / 2
        bit = (1 << ((r3 > half3).astype(np.int64) * 2 + (c3 > half3))).astype(np.int8)
        got = cache[row] = (key, xyz, faces, bit)
    return got


def _select_regions(terrain: TerrainLike, index: TileIndex, tb: LevelTables, view: View,
                    r: np.ndarray, occlusion: bool = True):
    """(rows, quadrant masks, levels) of the drawn regions; visited and culled counts."""
    nodes = index.rows_of(index.roots)  # every root tile (one on a square grid)
    nodes = nodes[nodes >= 0]
    inside = np.zeros(len(nodes), bool)
    hidden = hidden_rows(terrain, view, enabled=occlusion)
    rows, masks, visited, culled = [], [], 0, 0
    while len(nodes):
        visited += len(nodes)
        vis = np.where(inside, INSIDE, view.box_visibility(index.lo[nodes], index.hi[nodes]))
        keep = (vis != OUTSIDE) & ~hidden[nodes]
        culled += int((~keep).sum())
        nodes, vis = nodes[keep], vis[keep]
        if not len(nodes):
            break
        L = int(index.keys[nodes[0], 0])
        if L == 0:
            rows.append(nodes)
            masks.append(np.full(len(nodes), 15, np.int8))
            break
        near = r[L - 1]
        dist = view.box_distance(index.lo[nodes], index.hi[nodes])
        draw = tb.drawable[nodes]
        whole = draw & (dist >= near)
        rows.append(nodes[whole])
        masks.append(np.full(int(whole.sum()), 15, np.int8))
        par = nodes[~whole]
        par_draw, par_in = draw[~whole], vis[~whole] == INSIDE
        kids = np.repeat(index.keys[par], 4, axis=0)
        q = np.tile(np.arange(4), len(par))
        kids[:, 0] -= 1
        kids[:, 1] = kids[:, 1] * 2 + q % 2
        kids[:, 2] = kids[:, 2] * 2 + q // 2
        krow = index.rows_of(kids)
        ok = krow >= 0
        owner = np.repeat(np.arange(len(par)), 4)[ok]
        krow, q = krow[ok], q[ok]
        kin = par_in[owner]
        kvis = np.where(kin, INSIDE, view.box_visibility(index.lo[krow], index.hi[krow]))
        seen = (kvis != OUTSIDE) & ~hidden[krow]
        culled += int((~seen).sum())
        kdist = view.box_distance(index.lo[krow], index.hi[krow])
        partial = seen & par_draw[owner] & (kdist >= near)
        m = np.zeros(len(par), np.int64)
        np.bitwise_or.at(m, owner[partial], 1 << q[partial])
        rows.append(par[m > 0])
        masks.append(m[m > 0].astype(np.int8))
        go = seen & ~partial
        nodes, inside = krow[go], kvis[go] == INSIDE
    if not rows:
        z = np.zeros(0, np.int64)
        return z, z.astype(np.int8), visited, culled
    return np.concatenate(rows), np.concatenate(masks), visited, culled


def _unique(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sorted unique values, the index of each one's first occurrence and the inverse
    (a sort: numpy's hashing unique is several times slower on large int64 keys)."""
    order = np.argsort(a, kind="stable")
    s = a[order]
    head = np.empty(len(s), bool)
    head[:1] = True
    np.not_equal(s[1:], s[:-1], out=head[1:])
    inv = np.empty(len(a), np.int64)
    inv[order] = np.cumsum(head) - 1
    return s[head], order[head], inv


def _missing(cand: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    """The unique values of ``cand`` not in ``sorted_keys``."""
    u = _unique(cand)[0]
    pos = np.minimum(np.searchsorted(sorted_keys, u), len(sorted_keys) - 1)
    return u[sorted_keys[pos] != u]


def _targets(key: np.ndarray, h: np.ndarray, N: int) -> tuple[np.ndarray, np.ndarray]:
    """The two level-(h+1) neighbours a sample of home level h slides between: the ends of
    the level-(h+1) union-jack edge or diagonal it splits."""
    i, j = key // N, key % N
    s = np.int64(1) << h
    a, b = (i >> h) & 1, (j >> h) & 1
    # centre of a level-(h+1) cell (both odd): its union-jack diagonal joins the corner
    # whose level-(h+1) row and column are both odd to the opposite one
    ci, cj = (i - s) >> (h + 1), (j - s) >> (h + 1)
    main = (ci & 1) == (cj & 1)
    di = np.where(a == 1, s, 0)
    dj = np.where(b == 1, s, 0)
    dj = np.where((a == 1) & (b == 1) & ~main, -s, dj)
    return (i - di) * N + (j - dj), (i + di) * N + (j + dj)


def _bounded(tb: LevelTables, key: np.ndarray, h: int, N: int) -> np.ndarray:
    """True for samples of home level h inside a level-(h+1) tile of finite stored error
    (a sample on a tile edge lies in both tiles)."""
    fin = tb.finite[h + 1]
    S = tb.span[h + 1]
    ni, nj = fin.shape[0] - 1, fin.shape[1] - 1
    i, j = key // N, key % N
    out = np.zeros(len(key), bool)
    for di in (0, 1):
        ti = np.clip(i // S - di, 0, ni) if di else np.minimum(i // S, ni)
        oki = (i % S == 0) & (i > 0) if di else np.ones(len(key), bool)
        for dj in (0, 1):
            tj = np.clip(j // S - dj, 0, nj) if dj else np.minimum(j // S, nj)
            okj = (j % S == 0) & (j > 0) if dj else np.ones(len(key), bool)
            out |= oki & okj & fin[ti, tj]
    return out


def morph_positions(terrain: TerrainLike, key: np.ndarray, xyz: np.ndarray, eye: np.ndarray,
                    r: np.ndarray, m: np.ndarray, tb: LevelTables | None = None
                    ) -> tuple[np.ndarray, int]:
    """Morphed scene positions of the samples ``key`` (global i·N + j) at unmorphed
    positions ``xyz``; and how many of them morph (0 < k).

    Each odd sample moves toward the midpoint of its two neighbours' *morphed*
    positions; the neighbours missing from ``key`` are read with ``terrain.gather``.
    With ``tb``, only samples inside a level-(h+1) tile of finite error move.
    """
    g = terrain.grid
    N, top = _stride(g), g.top_level
    keys, P = key.copy(), xyz.copy()
    sk = np.sort(keys)
    ok = np.isfinite(P).all(1)
    home = vertex_level(keys // N, keys % N, top)
    steps = []
    for h in range(top):
        sel = np.flatnonzero((home == h) & ok)
        if not len(sel) or not np.isfinite(r[h]):
            continue
        if tb is not None:
            sel = sel[_bounded(tb, keys[sel], h, N)]
        d = np.linalg.norm(P[sel] - eye, axis=1)
        span = r[h] * _END - m[h]
        k = np.clip((d - m[h]) / span, 0.0, 1.0) if span > 0 else (d >= m[h]).astype(float)
        go = k > 0
        sel, k = sel[go], k[go]
        if not len(sel):
            continue
        t1, t2 = _targets(keys[sel], np.full(len(sel), h), N)
        new = _missing(np.concatenate([t1, t2]), sk)
        if len(new):
            sk = np.sort(np.concatenate([sk, new]))
            got = terrain.gather(new // N, new % N, ("height", "x", "y"))
            Pn = np.stack([got["x"], got["y"], terrain.frame.z(got["height"])], 1)
            keys = np.concatenate([keys, new])
            P = np.concatenate([P, Pn])
            ok = np.concatenate([ok, np.isfinite(Pn).all(1)])
            home = np.concatenate([home, vertex_level(new // N, new % N, top)])
        steps.append((sel, k, t1, t2))
    order = np.argsort(keys)
    sk = keys[order]
    moved = 0
    for sel, k, t1, t2 in reversed(steps):  # coarse first: the targets are final
        a = order[np.searchsorted(sk, t1)]
        b = order[np.searchsorted(sk, t2)]
        both = ok[a] & ok[b]
        sel, k, a, b = sel[both], k[both], a[both], b[both]
        P[sel] += k[:, None] * (0.5 * (P[a] + P[b]) - P[sel])
        moved += len(sel)
    return P[: len(key)], moved


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, morph_fraction: float = MORPH_FRACTION):
    """The CDLOD mesh of ``view`` at pixel tolerance ``tau``, morphed, and its stats.

    ``morph=False`` (or ``morph_fraction=0``) keeps the selection but snaps each odd
    vertex to its parent's surface at r_h instead of sliding it there; None is the
    registry's default for cdlod (morphing). ``occlusion``: cull the nodes hidden behind
    nearer terrain.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["nodes"] > 0 and mesh.n_cells > 0
    True
    """
    if morph is None:  # the registry's default (on)
        morph = strategy_info("cdlod").morph_default
    f = float(morph_fraction) if morph else 0.0
    if not 0.0 <= f < 1.0:
        raise UsageError(f"morph_fraction must be in [0, 1), got {morph_fraction}")
    index = tile_index(terrain)
    if index.outside(view):
        return empty_parts(), {}
    tb = _tables(terrain, index)
    r, m = ranges(tb, view.lam, tau, f)
    rows, masks, visited, culled = _select_regions(terrain, index, tb, view, r, occlusion)
    stats = {"tiles_visited": visited, "tiles_culled": culled, "nodes": int(len(rows)),
             "partial_nodes": int((masks != 15).sum()), "morph_fraction": f}
    if not len(rows):
        return empty_parts(), stats
    keys, xyzs, faces, level, off = [], [], [], [], 0
    for row, mask in zip(rows.tolist(), masks.tolist(), strict=True):
        key, xyz, fc, bit = _parts(terrain, index, row)
        fsel = fc[(bit & mask) != 0]
        keys.append(key)
        xyzs.append(xyz)
        faces.append(fsel + off)
        level.append(np.full(len(fsel), index.keys[row, 0], np.int16))
        off += len(key)
    key, xyz = np.concatenate(keys), np.concatenate(xyzs)
    faces, level = np.concatenate(faces), np.concatenate(level)
    if not len(faces):
        return empty_parts(), stats
    # one vertex per sample (neighbouring nodes share their edge samples); the samples
    # no drawn triangle uses (no data, quadrants not drawn) are dropped
    uk, first, inv = _unique(key)
    faces = inv[faces]
    used = np.zeros(len(uk), bool)
    used[faces.ravel()] = True
    faces = (np.cumsum(used) - 1)[faces]
    uk, src = uk[used], first[used]
    P, moved = morph_positions(terrain, uk, xyz[src], view.eye, r, m, tb)
    N = _stride(terrain.grid)
    ij = np.stack([uk // N, uk % N], 1).astype(np.float64)
    stats.update(morphing_vertices=moved)
    return mesh_parts(P, faces, ij,
                    {"skirt": np.zeros(len(faces), np.uint8), "level": level}), stats

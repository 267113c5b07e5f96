"""Strategy ``geomipmap``: de Boer's GeoMipMapping (seed 000 §2.4), crack-free by stitching.

- **Blocks** are the stored level-0 tiles; a block's **geomipmap n** is its footprint
  sampled every 2ⁿ samples (the stored level-n samples), n = 0 … min(t, top level),
  the coarsest being 2×2 vertices. A quadtree is used only for frustum culling.
- **δ_n** (seed 000 §2.4: the height change of the vanishing vertices) is the block's
  exact value, computed at preprocess (:func:`geoterrain.bounds.tilebounds.tile_and_block_errors`)
  and stored per block and level (:meth:`geoterrain.terrain.Terrain.block_errors`): the
  max over the block's full-resolution samples of |z − S_n|, S_n the union-jack surface
  the block draws at level n, rounded up to float32; then δ = max{δ_0 … δ_n} as the
  seed takes it. A store written before the table falls back to the stored error of
  tile (n, x ≫ n, y ≫ n), the level-n tile covering the block: an upper bound of the
  same quantity over a larger footprint (it may be larger, never smaller).
- **Selection** (``rule="error"``, the default): a block takes the coarsest n with
  λ·δ_n / D_min ≤ τ, D_min the distance from the eye to the block's box, so the
  measured error ρ ≤ τ. ``rule="distance"`` is the thesis's precomputed switch
  distance (eq. 4-8 … 4-11): n is the coarsest with d_centre ≥ D_n = δ_n·C,
  C = V_res / (2τ·tan(fov_y/2)) = λ/τ; it assumes a horizontal view, so it gives no
  bound (strategy ``geomipmap_distance``).
- **Cracks** (fig. 4-21): on an edge whose neighbour is coarser by a factor r, the
  finer block omits its extra edge vertices (keeps every r-th) and re-links the
  triangles of that edge's border strip as fans onto the kept vertices. Every other
  triangle is the union-jack surface, so the mesh is conforming (no T-junction, no
  edge used more than twice). A fan changes the surface only inside its strip
  (between the edge and the first inner row, over the r cells of a kept segment), by at
  most B (:func:`strip_bounds`: at r = 2 the largest distance of an omitted edge vertex
  from its neighbours' midpoint, as the fan is S_n with those vertices snapped onto the
  edge; at r ≥ 4 the segment's height range). When λ·(δ_n + B)/D_min > τ the
  coarser neighbour is refined until it holds (at ratio 1 there is no fan), so the
  bound survives stitching.

- **Geomorphing** (``morph=True``, off by default): trilinear geomipmapping with
  continuous block levels, :mod:`geoterrain.lod.geomipmap_morph`; the same templates,
  ratio 2 at most, each block's vanishing vertices slid towards its next level.

Every block's triangles come from index templates cached per (size, the four
neighbour ratios); the blocks are assembled on whole arrays.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod import geomipmap_morph as gm
from geoterrain.lod.mesh import empty_parts, mesh_parts, orient_ccw
from geoterrain.lod.morph import MORPH_START
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import (
    TileIndex,
    quadtree_leaves,
    tile_geometry,
    tile_index,
    union_jack_faces,
)

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

_TEMPLATES: dict[tuple, np.ndarray] = {}

# edge order: top (row 0), bottom (row K), left (column 0), right (column K)
EDGES = ("top", "bottom", "left", "right")
_NEIGHBOUR = gm.NEIGHBOUR  # (dx, dy) per edge


def _edge_local(e: int, v: np.ndarray, u: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray]:
    """Block-local (row, col) of edge-local (v = depth inward, u = along the edge)."""
    if e == 0:
        return v, u
    if e == 1:
        return K - v, u
    if e == 2:
        return u, v
    return u, K - v


def _fan(K: int, r: int) -> list[tuple[tuple[int, int], ...]]:
    """Edge-local triangles of a border strip stitched to a neighbour r times coarser:
    per kept segment [u0, u0 + r], a fan from each kept vertex to the inner row, and the
    triangle (u0, u0 + r, middle inner vertex) (seed 000 fig. 4-21)."""
    tris = []
    for a in range(K // r):
        u0, u1 = a * r, (a + 1) * r
        mid = u0 + r // 2
        tris.append(((0, u0), (0, u1), (1, mid)))
        tris += [((0, u0), (1, c), (1, c + 1)) for c in range(max(u0, 1), mid)]
        tris += [((0, u1), (1, c), (1, c + 1)) for c in range(mid, min(u1, K - 1))]
    return tris


def template(K: int, ratios: tuple[int, int, int, int], parity: int = 0) -> np.ndarray:
    """Local faces (F, 3) into a block's (K+1)² level grid, counter-clockwise from above.

    ``ratios[e]`` is 1 for a plain edge or r > 1 for an edge stitched to a neighbour r
    times coarser; ``parity`` (K = 1 only) is 1 when the cell's diagonal is the
    anti-diagonal of the union-jack rule (block x and y of different parity).

    Examples
    --------
    >>> len(template(4, (1, 1, 1, 1))), len(template(4, (4, 1, 1, 1)))
    (32, 29)
    """
    key = (K, ratios, parity)
    if key in _TEMPLATES:
        return _TEMPLATES[key]
    a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
    local = np.stack([a.ravel(), b.ravel()], 1)
    if K == 1:
        faces = np.array([[0, 3, 1], [0, 2, 3]] if not parity else [[1, 2, 0], [1, 3, 2]])
    else:
        faces = union_jack_faces(int(K).bit_length() - 1)
        c = local[faces].mean(axis=1)  # centroids: which border strip holds each triangle
        dist = np.stack([c[:, 0], K - c[:, 0], c[:, 1], K - c[:, 1]], 1)
        strip = np.where(dist.min(1) < 1, dist.argmin(1), -1)
        keep = np.ones(len(faces), bool)
        extra = []
        for e, r in enumerate(ratios):
            if r <= 1:
                continue
            keep &= strip != e
            t = np.array(_fan(K, r)).reshape(-1, 2)
            i, j = _edge_local(e, t[:, 0], t[:, 1], K)
            extra.append((i * (K + 1) + j).reshape(-1, 3))
        faces = np.concatenate([faces[keep], *extra])
    out = _TEMPLATES[key] = orient_ccw(local, faces)
    return out


class Tables:
    """Per-terrain block tables: the level-0 tiles, their δ_n and neighbours."""

    def __init__(self, terrain: TerrainLike, index: TileIndex):
        g = terrain.grid
        self.nmax = min(g.t, g.top_level)
        blocks = np.flatnonzero(index.keys[:, 0] == 0)
        self.pos = np.full(len(index.keys), -1, np.int64)
        self.pos[blocks] = np.arange(len(blocks))
        xy = index.keys[blocks, 1:]
        table = terrain.block_errors()  # exact per-block δ_n; None: an older store
        if table is not None:
            delta = table[xy[:, 1], xy[:, 0], : self.nmax + 1].copy()
        else:  # the covering level-n tile's error: an upper bound of the block's δ_n
            delta = np.empty((len(blocks), self.nmax + 1))
            for n in range(self.nmax + 1):
                k = np.column_stack([np.full(len(blocks), n), xy >> n])
                delta[:, n] = index.error[index.rows_of(k)]
        delta[:, 0] = 0.0  # level 0 is the data itself
        # seed 000 §2.4: a switch to n is refused past τ for δ = max{δ_0 … δ_n}
        self.delta = np.maximum.accumulate(delta, axis=1)
        self.rows, self.xy = blocks, xy
        # each block's neighbour across each edge (−1: none stored), and the δ that bounds
        # an edge vertex's move per level: the smaller of the two blocks' (both hold it)
        across, down = g.tiles(0)
        grid = np.full((down + 2, across + 2), -1, np.int64)
        grid[xy[:, 1] + 1, xy[:, 0] + 1] = np.arange(len(blocks))
        self.neighbour = np.stack([grid[xy[:, 1] + 1 + dy, xy[:, 0] + 1 + dx]
                                   for dx, dy in _NEIGHBOUR], 1)
        other = self.delta[np.maximum(self.neighbour, 0)]
        self.edge_delta = np.where((self.neighbour >= 0)[..., None],
                                   np.minimum(self.delta[:, None, :], other),
                                   self.delta[:, None, :])


def tables(terrain: TerrainLike, index: TileIndex) -> Tables:
    return terrain.derived(__name__, lambda: Tables(terrain, index))


def _block_grids(terrain: TerrainLike, index: TileIndex, xy: np.ndarray, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """ij (B, (K+1)², 2) and scene xyz (B, (K+1)², 3) of blocks ``xy`` at level n (z NaN
    where no data): slices of the cached geometry of the level-n tiles covering them."""
    g = terrain.grid
    K = 1 << (g.t - n)
    a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
    a, b = a.ravel(), b.ravel()
    i = (xy[:, 1, None] << g.t) + (a << n)[None]
    j = (xy[:, 0, None] << g.t) + (b << n)[None]
    cover = np.column_stack([np.full(len(xy), n), xy >> n])
    rows, u = np.unique(index.rows_of(cover), return_inverse=True)
    T = g.tile_samples
    stack = np.full((len(rows), T, T, 3), np.nan)
    for k, row in enumerate(rows.tolist()):
        if row >= 0:  # a tile that is not stored holds no data
            stack[k] = tile_geometry(terrain, index, row)[1].reshape(T, T, 3)
    m = (1 << n) - 1  # the block's place inside its covering tile, in blocks
    oi = ((xy[:, 1] & m) * K)[:, None] + a[None]
    oj = ((xy[:, 0] & m) * K)[:, None] + b[None]
    xyz = stack[u.ravel()[:, None], oi, oj]
    return np.stack([i, j], -1), xyz


def strip_bounds(Z: np.ndarray, nlev: int) -> np.ndarray:
    """B (Nb, 4, nlev): per block, edge and k = log₂ r, a bound of how far stitching the
    border strip at ratio r moves the block's surface S_n; inf where a segment holds
    no-data (never stitched), 0 for k = 0 and NaN where r > K.

    - r = 2: a fan is S_n with each omitted edge vertex moved onto the segment between
      its neighbours (the two union-jack triangles at it are then coplanar with the
      fan's), so the change is at most max |z_v − (z_{v−1} + z_{v+1})/2| (a hat
      function is ≤ 1): second order in the heights;
    - r ≥ 4: the fan and S_n both interpolate the segment's level samples (rows 0–1 over
      r + 1 columns), so the change is at most their height range.

    Examples
    --------
    >>> Z = np.arange(9.0).reshape(1, 3, 3)  # a plane: stitching at r = 2 changes nothing
    >>> strip_bounds(Z, 2)[0, 0].tolist()
    [0.0, 0.0]
    >>> strip_bounds(Z * Z, 2)[0, 0].tolist()  # z = (3i + j)²: row 0 is 0, 1, 4
    [0.0, 1.0]
    """
    Nb, K1, _ = Z.shape
    K = K1 - 1
    out = np.full((Nb, 4, nlev), np.nan)
    out[:, :, 0] = 0.0
    strips = (Z[:, 0:2, :], Z[:, [K, K - 1], :], Z[:, :, 0:2].transpose(0, 2, 1),
              Z[:, :, [K, K - 1]].transpose(0, 2, 1))
    for e, s in enumerate(strips):
        hi, lo = s.max(axis=1), s.min(axis=1)  # (Nb, K+1), NaN where no data
        for k in range(1, nlev):
            r = 1 << k
            if r > K:
                break
            shi = np.maximum(hi[:, :K].reshape(Nb, K // r, r).max(-1), hi[:, r::r])
            slo = np.minimum(lo[:, :K].reshape(Nb, K // r, r).min(-1), lo[:, r::r])
            seg = shi - slo  # per segment, NaN where it holds no-data
            if k == 1:
                z = s[:, 0, :]
                seg = np.where(np.isnan(seg), np.nan,
                               np.abs(z[:, 1::2] - 0.5 * (z[:, 0:-1:2] + z[:, 2::2])))
            out[:, e, k] = np.nan_to_num(seg.max(-1), nan=np.inf)
    return out


def choose_levels(view: View, tau: float, delta: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  rule: str = "error") -> tuple[np.ndarray, np.ndarray]:
    """Each block's level and D_min: the coarsest n with λ·δ_n/D_min ≤ τ (``error``) or
    d_centre ≥ D_n = δ_n·λ/τ (``distance``, seed 000 eq. 4-8 … 4-11).

    Examples
    --------
    >>> v = View((0, 0, 100), (0, 1, 0))
    >>> n, _ = choose_levels(v, 1.0, np.array([[0, 0.01, 1.0]]), np.zeros((1, 3)), np.ones((1, 3)))
    >>> n.tolist()
    [1]
    """
    lam = view.lam
    dmin = view.box_distance(lo, hi)
    with np.errstate(invalid="ignore", over="ignore"):
        if rule == "distance":
            dc = np.linalg.norm(0.5 * (lo + hi) - view.eye, axis=1)
            ok = dc[:, None] >= delta * (lam / tau)
        else:
            ok = lam * delta <= tau * dmin[:, None]
    ok[:, 0] = True
    return np.cumprod(ok, axis=1).sum(1) - 1, dmin


def visible_blocks(terrain: TerrainLike, view: View, *, occlusion: bool = True) -> tuple:
    """The tile index, the level-0 tiles (blocks) whose boxes meet the frustum (and, with
    ``occlusion``, are not hidden behind nearer terrain), found top-down through the tile
    quadtree, and the walk's stats.

    Examples
    --------
    >>> index, blocks, stats = visible_blocks(t, View((0, -800, 400), (0, 0, 0)))
    >>> bool((index.keys[blocks, 0] == 0).all()) and len(blocks) > 0
    True
    """
    index = tile_index(terrain)
    if index.outside(view):
        return index, np.zeros(0, np.int64), {}
    leaves, stats = quadtree_leaves(terrain, index, view,
                                    lambda nodes, L: np.ones(len(nodes), bool),
                                    hidden_rows(terrain, view, enabled=occlusion))
    return index, leaves, stats


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, rule: str = "error"):
    """The GeoMipMapping mesh of ``view`` at pixel tolerance ``tau``, and its stats;
    geomorphed (:mod:`geoterrain.lod.geomipmap_morph`) when ``morph`` is True and the
    rule is ``error`` (the distance rule gives no bound to morph within, so it never
    morphs); ``occlusion``: cull blocks hidden behind nearer terrain.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> stats["blocks"] > 0 and mesh.n_cells > 0
    True
    """
    index, leaves, stats = visible_blocks(terrain, view, occlusion=occlusion)
    if not len(leaves):
        return empty_parts(), stats
    tb = tables(terrain, index)
    if rule == "error" and morph:
        return _select_morphed(terrain, index, tb, view, tau, leaves, stats)
    delta = tb.delta[tb.pos[leaves]]
    xy = index.keys[leaves, 1:]  # (x, y)
    n, dmin = choose_levels(view, tau, delta, index.lo[leaves], index.hi[leaves], rule)
    ratios, stitched = _stitch(terrain, index, view, tau, xy, n, delta, dmin, tb.nmax,
                               bounded=(rule != "distance"))
    mesh = _assemble(terrain, index, xy, n, ratios)
    stats.update(blocks=len(leaves), stitched_edges=stitched,
                 mean_level=float(n.mean()))
    return mesh, stats


def _stitch(terrain: TerrainLike, index, view, tau, xy, n, delta, dmin, nmax, bounded=True):
    """Neighbour ratios (B, 4) after refining coarser neighbours whose stitching would
    break λ·(δ_n + B)/D_min ≤ τ. ``n`` is updated in place."""
    across, down = terrain.grid.tiles(0)
    lam = view.lam
    G = np.full((down + 2, across + 2), -1, np.int64)  # drawn blocks' levels, −1 elsewhere
    bx, by = xy[:, 0] + 1, xy[:, 1] + 1
    G[by, bx] = n
    rng = np.full((len(n), nmax + 1, 4, nmax + 1), np.nan)  # [block, level, edge, log2 r]
    rows = np.arange(len(n))
    while True:
        n[:] = G[by, bx]
        m = np.stack([G[by + dy, bx + dx] for dx, dy in _NEIGHBOUR], 1)
        k = np.where(m > n[:, None], m - n[:, None], 0)
        if not bounded or not k.any():
            break
        todo = (k > 0).any(1) & np.isnan(rng[rows, n, 0, 0])
        for lv in np.unique(n[todo]).tolist():
            sel = np.flatnonzero(todo & (n == lv))
            _, xyz = _block_grids(terrain, index, xy[sel], lv)
            K = 1 << (terrain.grid.t - lv)
            Z = xyz[..., 2].reshape(len(sel), K + 1, K + 1)
            rng[sel, lv] = strip_bounds(Z, nmax + 1)
        R = rng[rows, n]  # (B, 4, nmax+1)
        with np.errstate(invalid="ignore", over="ignore"):
            fits = lam * (delta[rows, n][:, None, None] + R) <= tau * dmin[:, None, None]
        fits[:, :, 0] = True
        cur = np.take_along_axis(fits, k[:, :, None], 2)[:, :, 0]
        bad = ~cur
        if not bad.any():
            break
        # the largest ratio below the current one that fits
        kk = np.arange(nmax + 1)
        best = np.where(fits & (kk[None, None] < k[:, :, None]), kk[None, None], 0).max(-1)
        b, e = np.nonzero(bad)
        dx, dy = _NEIGHBOUR[e, 0], _NEIGHBOUR[e, 1]
        np.minimum.at(G, (by[b] + dy, bx[b] + dx), n[b] + best[b, e])
    return np.where(k > 0, 1 << k, 1), int((k > 0).sum())


def _select_morphed(terrain: TerrainLike, index, tb, view, tau, leaves, stats):
    """The geomorphed mesh: continuous levels for every stored block, restricted so
    that neighbours' stitching keeps the bound, drawn blocks morphed at their level."""
    g = terrain.grid
    M, lam = tb.nmax, view.lam
    dmin = view.box_distance(index.lo[tb.rows], index.hi[tb.rows])
    ell = gm.continuous_levels(tb.delta, dmin, lam, tau)
    slack = tau * dmin / lam - gm.blend_error(tb.delta, ell)
    kappa = (gm.neighbour_allowance(tb.edge_delta, ell, slack) if M
             else np.ones((len(ell), 4)))
    across, down = g.tiles(0)
    x, y = tb.xy[:, 0], tb.xy[:, 1]
    present = np.zeros((down, across), bool)
    present[y, x] = True
    E, Kp = np.full((down, across), np.inf), np.zeros((down, across, 4))
    E[y, x], Kp[y, x] = ell, kappa
    L = gm.restrict(E, Kp, present)[y, x]
    # grid levels, restricted as integers too (L differs by ≤ 1 between neighbours, but
    # floor(L + 1) can round to one more); t then takes up the difference
    nb = tb.neighbour
    n = np.clip(np.floor(L).astype(np.int64), 0, M)
    for _ in range(M + 1):
        up = np.where(nb >= 0, n[np.maximum(nb, 0)] + 1, M).min(1)
        if (up >= n).all():
            break
        n = np.minimum(n, up)
    t = np.where(n >= M, 0.0, np.clip(L - n, 0.0, 1.0))
    bi = tb.pos[leaves]
    xy, nd, td = tb.xy[bi], n[bi], t[bi]
    nbd = nb[bi]
    has = nbd >= 0
    Lnb = np.where(has, L[np.maximum(nbd, 0)], -np.inf)
    nn = np.where(has, n[np.maximum(nbd, 0)], -1)
    coarser = nn > nd[:, None]  # a ratio-2 stitch (never more: restricted)
    ratios = np.where(coarser, 2, 1)
    # each edge at the larger of its blocks' levels (Wagner: the neighbours' factors)
    rel = np.maximum(L[bi][:, None], Lnb) - nd[:, None]
    rel = np.clip(rel, 0.0, np.where(coarser, 2.0, 1.0))

    def heights(sel, lv, K, Z):
        if K < 2:
            return Z
        return gm.morph_block_heights(Z, td[sel], rel[sel],
                                      gm.next_level_diagonals(xy[sel], K))

    mesh = _assemble(terrain, index, xy, nd, ratios, heights)
    stats.update(blocks=len(leaves), stitched_edges=int(coarser.sum()),
                 mean_level=float(nd.mean()), morphing_blocks=int((td > 0).sum()),
                 morph_band=(MORPH_START * tau, tau),
                 refined_by_neighbours=int((L[bi] < ell[bi] - 1e-12).sum()))
    return mesh, stats


def _assemble(terrain: TerrainLike, index, xy, n, ratios, heights=None):
    """One mesh of every block at its level with its stitching template (whole arrays
    per (level, template) group); ``heights(sel, level, K, Z)`` may reshape the heights
    Z (B, K+1, K+1) of the group's blocks ``sel`` (geomorphing)."""
    g = terrain.grid
    ijs, xyzs, faces, level = [], [], [], []
    off = 0
    parity = (xy[:, 0] ^ xy[:, 1]) & 1
    key = np.column_stack([n, ratios, np.where(n == g.t, parity, 0)])
    groups, inv = np.unique(key, axis=0, return_inverse=True)
    for gi, kv in enumerate(groups.tolist()):
        sel = np.flatnonzero(inv.ravel() == gi)
        lv = kv[0]
        K = 1 << (g.t - lv)
        f = template(K, tuple(kv[1:5]), kv[5])
        ij, xyz = _block_grids(terrain, index, xy[sel], lv)
        if heights is not None:
            z = heights(sel, lv, K, xyz[..., 2].reshape(len(sel), K + 1, K + 1))
            xyz[..., 2] = z.reshape(len(sel), -1)
        V = (K + 1) ** 2
        ijs.append(ij.reshape(-1, 2))
        xyzs.append(xyz.reshape(-1, 3))
        faces.append((f[None] + (off + V * np.arange(len(sel)))[:, None, None]).reshape(-1, 3))
        level.append(np.full(len(sel) * len(f), lv, np.int16))
        off += V * len(sel)
    xyz, ij, faces = np.concatenate(xyzs), np.concatenate(ijs), np.concatenate(faces)
    level = np.concatenate(level)
    fin = np.isfinite(xyz[:, 2])
    if not fin.all():  # a triangle needs three valid corners
        ok = fin[faces].all(1)
        faces, level = faces[ok], level[ok]
    # one vertex per sample (blocks share their edges): unused (nodata) vertices drop out;
    # a sort of the vertex keys (numpy's hashing unique is slow on millions of int64)
    key = ij[:, 0] * g.extent[1] + ij[:, 1]  # a square's N, a root grid's extent columns
    order = np.argsort(key, kind="stable")
    sk = key[order]
    head = np.r_[True, sk[1:] != sk[:-1]]
    inv = np.empty(len(key), np.int64)
    inv[order] = np.cumsum(head) - 1
    first = order[head]
    faces = inv[faces]
    used = np.zeros(len(first), bool)
    used[faces.ravel()] = True
    src = first
    if not used.all():
        faces = (np.cumsum(used) - 1)[faces]
        src = first[used]
    return mesh_parts(xyz[src], faces, ij[src],
                    {"skirt": np.zeros(len(faces), np.uint8), "level": level})

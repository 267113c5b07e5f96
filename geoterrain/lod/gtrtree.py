"""A quadtree of fixed-size regular blocks: what GPU Terrain Rendering (``gtr``,
``gtr_bounded``) and Lauritsen & Nielsen's hybrid (``lauritsen_nielsen``) share
(seed 000 §2.7, §2.8, §5).

- **Blocks.** A quadtree node is a stored tile (L, x, y): (2^t+1)² vertices at the
  level-L spacing, so every node has the same vertex count and a parent covers its four
  children's area at twice their spacing (Vistnes: "4 blocks replaced by 1 block of the
  same vertex count"; Lauritsen & Nielsen: every other row and column dropped, 2^n + 1
  kept). The block size is the store's tile size (``--tile-size``, the thesis's
  ``TerrainTileSize``); each block draws its uniform (union-jack) surface.
- **δ_b** (seed 000 eq. 5-2 = eq. 4-23): δ_b = 0 at a level-0 block, else
  max(δ_b of the four children) + δ_m, δ_m the largest geometric error of the vertices
  that vanish from the children to the block: each one's height minus the mean of the two
  neighbours that bracket it in the block's triangulation (the two ends of the edge it
  halves, or of the union-jack diagonal of the cell it centres; §3.4). By the triangle
  inequality δ_b bounds the block's surface against every full-resolution sample of its
  footprint. A block whose stored error is infinite (its footprint mixes data and
  no-data) gets δ_b = ∞ and is always refined.
- **Morph target.** A vertex that vanishes at the next level moves towards that same
  bracketing mean: :func:`coarse_target`. At t = 1 a block draws its parent's surface
  over its footprint exactly.

Derived per terrain (:meth:`TerrainLike.derived`): the δ_b and δ_m of every stored
tile, computed once from the decoded tiles, one tile at a time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geoterrain.core.view import OUTSIDE, View
from geoterrain.lod.chunks import parents
from geoterrain.lod.tiles import TileIndex, assemble, tile_geometry, tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["BlockErrors", "block_errors", "block_mesh", "coarse_target", "morph_band",
           "skirt_sides"]


def coarse_target(z: np.ndarray, x: int, y: int, t: int) -> np.ndarray:
    """Where each sample of tile (·, x, y) lies on the next coarser level's surface: its
    own height at the samples that level keeps, else the mean of the two neighbours that
    bracket it there (seed 000 §3.4: the ends of the edge it halves, or of the union-jack
    diagonal of the cell it centres). NaN where a bracketing neighbour has no data.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3) ** 2
    >>> coarse_target(z, 0, 0, 1)[1].tolist()  # row 1: (0+36)/2, centre (0+64)/2, (4+64)/2
    [18.0, 32.0, 34.0]
    """
    tgt = z.astype(np.float64, copy=True)
    tgt[1::2, 0::2] = 0.5 * (z[0:-1:2, 0::2] + z[2::2, 0::2])
    tgt[0::2, 1::2] = 0.5 * (z[0::2, 0:-1:2] + z[0::2, 2::2])
    T = z.shape[0]
    a = np.arange(1, T, 2)
    half = 1 << (t - 1) if t >= 1 else 0
    A = y * half + (a - 1) // 2  # the next level's cell (A, B) each centre lies in
    B = x * half + (a - 1) // 2
    main = ((A[:, None] + B[None, :]) % 2) == 0  # union jack: diagonal (0, 0)–(1, 1)
    nw_se = 0.5 * (z[0:-1:2, 0:-1:2] + z[2::2, 2::2])
    ne_sw = 0.5 * (z[0:-1:2, 2::2] + z[2::2, 0:-1:2])
    tgt[1::2, 1::2] = np.where(main, nw_se, ne_sw)
    return tgt


class BlockErrors(NamedTuple):
    """Per index row: ``delta_b`` (eq. 5-2), ``delta_m`` (the largest move of the row's
    own vertices onto its parent's surface, :func:`coarse_target`) and ``parent`` (the
    parent's row, −1 for none)."""

    delta_b: np.ndarray
    delta_m: np.ndarray
    parent: np.ndarray


def _errors(terrain: TerrainLike, index: TileIndex) -> BlockErrors:
    g = terrain.grid
    keys = index.keys
    n = len(keys)
    par = parents(terrain, index)
    dev = np.zeros(n)
    for row in np.flatnonzero(keys[:, 0] < g.top_level).tolist():
        L, x, y = (int(v) for v in keys[row])
        z = terrain.frame.z(terrain.tile(L, x, y).heights)
        d = np.abs(z - coarse_target(z, x, y, g.t))
        dev[row] = float(np.nanmax(d)) if np.isfinite(d).any() else 0.0
    delta_b = np.zeros(n)
    dm = np.zeros(n)  # δ_m of each row: the largest dev of its children
    for L in range(1, g.top_level + 1):  # finer levels first
        kids = np.flatnonzero(keys[:, 0] == L - 1)
        p = par[kids]
        ok = p >= 0
        np.maximum.at(dm, p[ok], dev[kids[ok]])
        child_b = np.zeros(n)
        np.maximum.at(child_b, p[ok], delta_b[kids[ok]])
        rows = np.flatnonzero(keys[:, 0] == L)
        delta_b[rows] = child_b[rows] + dm[rows]
    delta_b[~np.isfinite(index.error) & (keys[:, 0] > 0)] = np.inf
    return BlockErrors(delta_b, dev, par)


def block_errors(terrain: TerrainLike) -> BlockErrors:
    """The cached :class:`BlockErrors` of ``terrain``.

    Examples
    --------
    >>> be = block_errors(t)
    >>> bool((be.delta_b[be.parent >= 0] <= be.delta_b[be.parent[be.parent >= 0]]).all())
    True
    """
    index = tile_index(terrain)
    return terrain.derived(__name__, lambda: _errors(terrain, index))


def morph_band(rho_parent: np.ndarray, tau: float, tau_min: float) -> np.ndarray:
    """The morph towards the parent, s ∈ [0, 1], of blocks whose parent projects to
    ``rho_parent``: 0 while the parent breaks τ, 1 when it would be drawn (≤ τ_min),
    linear between. A block with s > 0 draws (1 − s)·S_own + s·S_parent, within τ since
    both surfaces are (seed 002 eq. 3's band; the walk refines at τ_min).

    Examples
    --------
    >>> morph_band(np.array([2.0, 0.875, 0.75, 0.5]), 1.0, 0.75).tolist()
    [0.0, 0.5, 1.0, 1.0]
    """
    with np.errstate(invalid="ignore"):
        s = np.clip((tau - rho_parent) / (tau - tau_min), 0.0, 1.0)
    return np.nan_to_num(s, nan=0.0)


def skirt_sides(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray, view: View,
                depth: np.ndarray) -> np.ndarray:
    """The thesis's optimised skirts (seed 000 §3.9, L2561–2563): all four sides, then
    (by :func:`~geoterrain.lod.tiles.assemble`) none on the terrain's border, then, for a
    block that meets the frustum's border, none whose skirt lies outside the frustum.
    Returns a bit mask per leaf (1 top, 2 bottom, 4 left, 8 right).

    Examples
    --------
    >>> ix = tile_index(t); leaves = np.flatnonzero(ix.keys[:, 0] == 0)[:2]
    >>> skirt_sides(t, ix, leaves, View((0, -800, 400), (0, 0, 0)), np.ones(2)).shape
    (2,)
    """
    out = np.full(len(leaves), 15, np.int64)
    T = terrain.grid.tile_samples
    for k, row in enumerate(leaves.tolist()):
        if view.box_visibility(index.lo[row], index.hi[row]) == 2:  # inside: keep all
            continue
        xyz = tile_geometry(terrain, index, row)[1].reshape(T, T, 3)
        for bit, e in ((1, xyz[0]), (2, xyz[-1]), (4, xyz[:, 0]), (8, xyz[:, -1])):
            ok = np.isfinite(e[:, 2])
            if not ok.any():
                continue
            lo = np.nanmin(e, axis=0)
            hi = np.nanmax(e, axis=0)
            lo[2] -= depth[k]
            if view.box_visibility(lo, hi) == OUTSIDE:
                out[k] &= ~bit
    return out


def block_mesh(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray, morph: np.ndarray,
               depth: np.ndarray, sides: np.ndarray | None = None):
    """The blocks ``leaves`` as one mesh, each morphed by ``morph[k]`` towards its
    parent's surface (z − s·(z − target), :func:`coarse_target`) and hung with skirts
    ``depth[k]`` deep from the edges ``sides[k]``.

    Examples
    --------
    >>> ix = tile_index(t); top = np.flatnonzero(ix.keys[:, 0] == t.grid.top_level)
    >>> block_mesh(t, ix, top, np.zeros(1), np.zeros(1)).n_cells > 0
    True
    """
    g = terrain.grid
    heights: list = [None] * len(leaves)
    for k in np.flatnonzero(morph > 0).tolist():
        row = int(leaves[k])
        L, x, y = (int(v) for v in index.keys[row])
        if L >= g.top_level:
            continue
        z = tile_geometry(terrain, index, row)[1][:, 2].reshape(g.tile_samples, -1)
        tgt = coarse_target(z, x, y, g.t)
        tgt = np.where(np.isfinite(tgt), tgt, z)
        heights[k] = (z - morph[k] * (z - tgt)).ravel()
    return assemble(terrain, index, leaves, depth, heights, sides)


def walk(terrain: TerrainLike, view: View, error: np.ndarray, tau: float, *, rule: str,
         occlusion: bool = True) -> tuple[np.ndarray, dict]:
    """The blocks to draw: the tile quadtree walked top-down with frustum (and, with
    ``occlusion``, horizon) culling, a block refined while its ``error`` (per index row)
    breaks τ. ``rule="distance"``: the thesis's switch distance, refined while the eye is
    nearer the block's centre than D_n = error·C, C = λ/τ (seed 000 eq. 5-4/5-5, i.e.
    V_res / (2τ·tan(fov_y/2))); ``rule="box"``: refined while λ·error / D_min > τ, D_min
    the distance to the block's box, so the block's ρ ≤ τ.

    Examples
    --------
    >>> leaves, st = walk(t, View((0, -800, 400), (0, 0, 0)), block_errors(t).delta_b, 1.0,
    ...                   rule="box")
    >>> len(leaves) > 0 and st["tiles_visited"] >= len(leaves)
    True
    """
    from geoterrain.lod.occlusion import hidden_rows
    from geoterrain.lod.tiles import quadtree_leaves

    index = tile_index(terrain)
    if index.outside(view):
        return np.zeros(0, np.int64), {}
    lam, eye = view.lam, view.eye

    def refine(nodes, L):
        e = error[nodes]
        if rule == "distance":
            d = np.linalg.norm(0.5 * (index.lo[nodes] + index.hi[nodes]) - eye, axis=1)
        else:
            d = view.box_distance(index.lo[nodes], index.hi[nodes])
        with np.errstate(invalid="ignore", over="ignore"):
            return ~(lam * e <= tau * d)  # inf error (no-data mixing): always refined

    return quadtree_leaves(terrain, index, view, refine,
                           hidden_rows(terrain, view, enabled=occlusion))


def skirt_depth(edge: np.ndarray) -> np.ndarray:
    """Skirt depths from each drawn block's edge bound ``edge`` (how far its drawn edges
    may lie from the samples): its own plus the largest drawn, since two neighbours' edges
    lie at most the sum apart; 0 where the bound is not finite (level-0 data: none).

    Examples
    --------
    >>> skirt_depth(np.array([0.0, 1.0, 3.0])).tolist()
    [3.0, 4.0, 6.0]
    """
    fin = np.isfinite(edge)
    top = float(np.max(edge[fin], initial=0.0))
    return np.where(fin, edge, 0.0) + top

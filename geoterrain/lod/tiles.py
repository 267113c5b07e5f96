"""The stored tiles as arrays, shared by every strategy.

- :class:`TileIndex`: the stored tiles' keys and bounds (box, tile error, skirt
  error, max δ and r of the vertices new at the tile's level) as arrays, for
  vectorised tests before any decoding.
- :func:`quadtree_leaves`: the tile quadtree walked level by level on arrays of
  nodes, with frustum culling; the caller's rule says which nodes to refine.
- :func:`tile_geometry` / :func:`assemble`: a stored tile's uniform surface
  (union-jack triangulation, cached per terrain), and many of them, with optional
  skirts, joined into one mesh.

Derived data is cached per terrain here (weakly: it goes with the terrain); the
terrain itself is only read.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geoterrain.core.grid import level_offsets
from geoterrain.core.view import INSIDE, OUTSIDE, View
from geoterrain.lod.mesh import empty_parts, mesh_parts, orient_ccw

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


class TileIndex:
    """The stored tiles' numbers as arrays, per level, for vectorised tests.

    Rows are the tile keys ``(L, x, y)`` in sorted order; ``lo``/``hi`` (R, 3)
    are scene-frame boxes, ``error`` the tile's uniform-surface error,
    ``boundary`` its skirt error, ``delta_max``/``radius_max`` the largest δ and
    r of the vertices new at its level, ``nvalid`` its valid samples and ``zrange``
    its recorded (zmin, zmax); ``mixed_rows`` the rows whose δ_max is inf (a diamond
    mixing data and nodata).
    """

    def __init__(self, terrain: TerrainLike):
        info = terrain.tile_info
        keys = sorted(info)
        self.row = {k: n for n, k in enumerate(keys)}
        self.keys = np.array(keys, np.int64).reshape(-1, 3)
        self.top_level = terrain.grid.top_level
        rx, ry = terrain.grid.roots  # the top tiles: one, or a root grid's
        self.roots = np.array([(self.top_level, x, y) for y in range(ry) for x in range(rx)],
                              np.int64)
        names = ("zmin", "zmax", "xmin", "ymin", "xmax", "ymax", "error", "boundary_error",
                 "delta_max", "radius_max", "nvalid")
        a = np.array([[info[k][c] for c in names] for k in keys], np.float64
                     ).reshape(-1, len(names))  # one pass over the table (None → NaN)
        zmin, zmax = np.nan_to_num(a[:, 0], nan=0.0), np.nan_to_num(a[:, 1], nan=0.0)
        self.lo = np.stack([a[:, 2], a[:, 3], np.minimum(zmin, zmax)], 1)
        self.hi = np.stack([a[:, 4], a[:, 5], np.maximum(zmin, zmax)], 1)
        self.error, self.boundary = a[:, 6].copy(), a[:, 7].copy()
        self.delta_max, self.radius_max = a[:, 8].copy(), a[:, 9].copy()
        self.mixed_rows = np.flatnonzero(~np.isfinite(self.delta_max))  # δ = inf inside
        self.nvalid = a[:, 10].astype(np.int64)
        self.zrange = a[:, :2].copy()  # recorded zmin, zmax (NaN where none)

    def rows_of(self, keys: np.ndarray) -> np.ndarray:
        """Row numbers of (L, x, y) keys; -1 where the tile is not stored."""
        return np.array([self.row.get(tuple(k), -1) for k in keys.tolist()], np.int64)

    def outside(self, view: View) -> bool:
        """True when the whole terrain's box is outside the frustum (nothing to decode)."""
        top = self.rows_of(self.roots)
        top = top[top >= 0]
        if not len(top):
            return True
        return bool((view.box_visibility(self.lo[top], self.hi[top]) == 0).all())


class TileTree(NamedTuple):
    """A tile index as the compiled quadtree walks read it: the dense (level, y, x) → row
    ``table`` and its level offsets ``base`` (:func:`tile_table`; a root grid's with its
    tiles across and down, :meth:`geoterrain.core.grid.Grid.walk_table`), the ``top``
    level, and each row's box ``lo``, ``hi`` (R, 3) (:class:`TileIndex`)."""

    table: np.ndarray
    base: np.ndarray
    top: int
    lo: np.ndarray
    hi: np.ndarray


def tile_table(index: TileIndex, top: int, grid=None) -> tuple[np.ndarray, np.ndarray]:
    """A dense (level, y, x) → row table of the stored tiles (−1: not stored) and the
    offset of each level in it: row = table[base[L] + y · 2^(top − L) + x]; with a root
    ``grid``, its table (:meth:`geoterrain.core.grid.Grid.table_index`) and its
    :meth:`~geoterrain.core.grid.Grid.walk_table` as ``base``.

    Examples
    --------
    >>> ix = tile_index(t)
    >>> table, base = tile_table(ix, t.grid.top_level)
    >>> int(table[base[t.grid.top_level]]) == ix.row[(t.grid.top_level, 0, 0)]
    True
    """
    if grid is not None and not grid.square:
        table = np.full(int(grid.offsets()[-1]), -1, np.int64)
        table[grid.table_index(index.keys)] = np.arange(len(index.keys))
        return table, grid.walk_table()
    base = level_offsets(top)
    table = np.full(int(base[-1]), -1, np.int64)
    k = index.keys
    table[base[k[:, 0]] + k[:, 2] * (np.int64(1) << (top - k[:, 0])) + k[:, 1]] = \
        np.arange(len(k))
    return table, base


def tile_index(terrain: TerrainLike) -> TileIndex:
    """The :class:`TileIndex` of ``terrain``, built once and cached with the terrain."""
    return terrain.derived(f"{__name__}.index", lambda: TileIndex(terrain))


def union_jack_faces(t: int) -> np.ndarray:
    """Local faces (F, 3) of a (2^t+1)² tile's uniform surface (conventions: union jack).

    Tiles start at even cell indices, so one template serves every tile.

    Examples
    --------
    >>> union_jack_faces(1).shape
    (8, 3)
    """
    T = (1 << t) + 1
    a, b = np.meshgrid(np.arange(T - 1), np.arange(T - 1), indexing="ij")
    a, b = a.ravel(), b.ravel()
    v00, v01 = a * T + b, a * T + b + 1
    v10, v11 = (a + 1) * T + b, (a + 1) * T + b + 1
    # the diagonal joins the cell corner whose row and column are both odd to its opposite
    ci = np.where(a % 2 == 1, a, a + 1)
    cj = np.where(b % 2 == 1, b, b + 1)
    diag_main = (ci - a) == (cj - b)  # that corner is (a, b) or (a+1, b+1): diagonal 00–11
    f1 = np.where(diag_main[:, None], np.stack([v00, v11, v01], 1), np.stack([v01, v10, v00], 1))
    f2 = np.where(diag_main[:, None], np.stack([v00, v10, v11], 1), np.stack([v01, v11, v10], 1))
    return np.concatenate([f1, f2])


Refine = Callable[[np.ndarray, np.ndarray], np.ndarray]


def quadtree_leaves(terrain: TerrainLike, index: TileIndex, view: View, refine: Refine,
                    hidden: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Leaf tiles (rows into ``index``) to draw, walking the tile quadtree top-down.

    ``refine(nodes, L)`` gets the visible nodes' rows and levels and returns which
    to replace by their stored children (level 0 is never refined). A node fully
    inside the frustum passes that to its children, which are not tested again; a
    node ``hidden`` behind nearer terrain (per index row, e.g.
    :func:`~geoterrain.lod.occlusion.hidden_rows`) is dropped with its subtree.
    Returns the leaves and ``tiles_visited`` / ``tiles_culled`` / ``tiles_hidden``
    counts.
    """
    nodes = index.rows_of(index.roots)
    nodes = nodes[nodes >= 0]
    inside = np.zeros(len(nodes), bool)
    if hidden is None:
        hidden = np.zeros(len(index.keys), bool)
    leaves, visited, culled, n_hidden = [], 0, 0, 0
    while len(nodes):
        visited += len(nodes)
        lo, hi = index.lo[nodes], index.hi[nodes]
        vis = np.where(inside, INSIDE, view.box_visibility(lo, hi))
        keep = vis != OUTSIDE
        culled += int((~keep).sum())
        n_hidden += int((keep & hidden[nodes]).sum())
        keep &= ~hidden[nodes]
        nodes, vis = nodes[keep], vis[keep]
        L = index.keys[nodes, 0]
        split = (L > 0) & refine(nodes, L)
        leaves.append(nodes[~split])
        par = index.keys[nodes[split]]
        par_inside = vis[split] == INSIDE
        if not len(par):
            break
        kids = np.repeat(par, 4, axis=0)
        kids[:, 0] -= 1
        kids[:, 1] = kids[:, 1] * 2 + np.tile([0, 1, 0, 1], len(par))
        kids[:, 2] = kids[:, 2] * 2 + np.tile([0, 0, 1, 1], len(par))
        rows = index.rows_of(kids)
        ok = rows >= 0
        nodes, inside = rows[ok], np.repeat(par_inside, 4)[ok]
    leaves = np.concatenate(leaves) if leaves else np.zeros(0, np.int64)
    return leaves, {"tiles_visited": visited, "tiles_culled": culled, "tiles_hidden": n_hidden}


def tile_geometry(terrain: TerrainLike, index: TileIndex, row: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cached geometry of one stored tile: ij (V, 2), xyz (V, 3), valid (V,), faces.

    Faces are the union-jack triangles whose three corners are valid, wound
    counter-clockwise seen from above.
    """
    cache = terrain.derived(f"{__name__}.geometry",
                            lambda: {"faces": union_jack_faces(terrain.grid.t)})
    if row in cache:
        return cache[row]
    g = terrain.grid
    L, x, y = (int(v) for v in index.keys[row])
    tile = terrain.tile(L, x, y)
    ii, jj = np.meshgrid(g.tile_rows(L, y), g.tile_cols(L, x), indexing="ij")
    ij = np.stack([ii.ravel(), jj.ravel()], 1)
    X, Y = terrain.frame.xy(ij[:, 0], ij[:, 1])
    xyz = np.stack([X, Y, terrain.frame.z(tile.heights.ravel())], 1)
    valid = tile.valid.ravel()
    f = cache["faces"]
    faces = orient_ccw(ij, f[valid[f].all(1)])
    out = cache[row] = (ij, xyz, valid, faces)
    return out


def _skirts(terrain: TerrainLike, index: TileIndex, row: int, xyz: np.ndarray, valid: np.ndarray,
            depth: float, sides: int = 15) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Skirt vertices, faces (local indices ≥ len(xyz)) and the edge sample of each
    skirt vertex, hanging ``depth`` below the tile's inner edges (seed 000 §skirts);
    ``sides``: a bit mask of the edges that may get one (1 top, 2 bottom, 4 left,
    8 right), the edges on the domain's border never do."""
    g = terrain.grid
    T = g.tile_samples
    L, x, y = (int(v) for v in index.keys[row])
    across, down = g.tiles(L)
    idx = np.arange(T * T).reshape(T, T)
    edges = []
    if y > 0 and sides & 1:
        edges.append(idx[0])
    if y < down - 1 and sides & 2:
        edges.append(idx[-1])
    if x > 0 and sides & 4:
        edges.append(idx[:, 0])
    if x < across - 1 and sides & 8:
        edges.append(idx[:, -1])
    if not edges:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    e = np.stack(edges)  # (E, T) edge vertex indices
    base = len(xyz)
    sk_xyz = xyz[e.ravel()].copy()
    sk_xyz[:, 2] -= depth
    sk = base + np.arange(e.size).reshape(e.shape)
    a, b = e[:, :-1].ravel(), e[:, 1:].ravel()
    sa, sb = sk[:, :-1].ravel(), sk[:, 1:].ravel()
    ok = valid[a] & valid[b]
    faces = np.concatenate([np.stack([a, sb, b], 1)[ok], np.stack([a, sa, sb], 1)[ok]])
    return sk_xyz, faces, e.ravel()


def assemble(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray,
             skirt_depth: np.ndarray | None = None, heights: list | None = None,
             sides: np.ndarray | None = None):
    """One mesh of the stored tiles ``leaves``, each with skirts ``skirt_depth[k]`` deep
    (none where the depth is 0, or when ``skirt_depth`` is None).

    ``heights[k]`` (T², scene z) replaces leaf k's heights where not None (a morphing
    tile); ``sides[k]`` is the bit mask of the edges leaf k may hang a skirt from (see
    :func:`_skirts`; all four by default). Cell data ``skirt`` (1 on skirt triangles)
    and ``level``; vertices that no triangle uses (nodata) are dropped.
    """
    ijs, xyzs, faces, skirt, level = [], [], [], [], []
    off = 0
    for k, row in enumerate(leaves.tolist()):
        ij, xyz, valid, f = tile_geometry(terrain, index, row)
        if heights is not None and heights[k] is not None:
            xyz = xyz.copy()
            xyz[:, 2] = heights[k]
        L = int(index.keys[row, 0])
        ijs.append(ij)
        xyzs.append(xyz)
        faces.append(f + off)
        skirt.append(np.zeros(len(f), np.uint8))
        level.append(np.full(len(f), L, np.int16))
        n = len(xyz)
        if skirt_depth is not None and skirt_depth[k] > 0:
            sxyz, sf, src = _skirts(terrain, index, row, xyz, valid, skirt_depth[k],
                                    15 if sides is None else int(sides[k]))
            ijs.append(ij[src])
            xyzs.append(sxyz)
            faces.append(sf + off)
            skirt.append(np.ones(len(sf), np.uint8))
            level.append(np.full(len(sf), L, np.int16))
            n += len(sxyz)
        off += n
    if not ijs:
        return empty_parts()
    xyz, ij, faces = np.concatenate(xyzs), np.concatenate(ijs), np.concatenate(faces)
    used = np.zeros(len(xyz), bool)  # drop the vertices no triangle uses (nodata)
    used[faces] = True
    faces = (np.cumsum(used) - 1)[faces]
    return mesh_parts(xyz[used], faces, ij[used],
                    {"skirt": np.concatenate(skirt), "level": np.concatenate(level)})

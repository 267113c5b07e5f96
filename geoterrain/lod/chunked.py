"""Strategies ``chunked`` (seed 000 GPU-Terrain-Rendering / Ulrich's chunked LOD) and
``bruteforce`` (every full-resolution tile in view).

The tile quadtree is walked level by level on arrays of nodes. A node is
refined while λ·ε_tile / D_min > τ, with D_min the distance from the eye to the
tile's 3-D box; a node fully inside the frustum passes that to its children
without testing them again. Cracks between tiles of different levels are
closed with skirts (seed 000 §skirts) hanging below the tile's edges.
"""

from __future__ import annotations

import numpy as np

from geoterrain.view import INSIDE, OUTSIDE, View


class TileIndex:
    """The stored tiles' numbers as arrays, per level, for vectorised tests."""

    def __init__(self, terrain):
        self.terrain = terrain
        info = terrain.tile_info
        keys = np.array(sorted(info), np.int64).reshape(-1, 3)
        self.keys = keys
        self.row = {tuple(k): n for n, k in enumerate(keys.tolist())}
        col = lambda name: np.array([info[tuple(k)][name] for k in keys.tolist()], np.float64)  # noqa: E731
        zmin = np.nan_to_num(col("zmin"), nan=0.0)
        zmax = np.nan_to_num(col("zmax"), nan=0.0)
        self.lo = np.stack([col("xmin"), col("ymin"), np.minimum(zmin, zmax)], 1)
        self.hi = np.stack([col("xmax"), col("ymax"), np.maximum(zmin, zmax)], 1)
        self.error = col("error")
        self.boundary = col("boundary_error")
        self.delta_max = col("delta_max")
        self.radius_max = col("radius_max")

    def rows_of(self, keys: np.ndarray) -> np.ndarray:
        """Row numbers of (L, x, y) keys; -1 where the tile is not stored."""
        return np.array([self.row.get(tuple(k), -1) for k in keys.tolist()], np.int64)


def union_jack_faces(t: int) -> np.ndarray:
    """Local faces (F, 3) of a (2^t+1)² tile's uniform surface (conventions: union jack).

    Tiles start at even cell indices, so one template serves every tile.
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


def select_tiles(terrain, index: TileIndex, view: View, tau: float, brute: bool = False
                 ) -> tuple[np.ndarray, dict]:
    """Leaf tiles (rows into ``index``) to draw, and visit/cull counts."""
    g = terrain.grid
    lam = view.lam
    top = np.array([[g.top_level, 0, 0]])
    nodes = index.rows_of(top)
    nodes = nodes[nodes >= 0]
    inside = np.zeros(len(nodes), bool)
    leaves, visited, culled = [], 0, 0
    while len(nodes):
        visited += len(nodes)
        lo, hi = index.lo[nodes], index.hi[nodes]
        vis = np.where(inside, INSIDE, view.box_visibility(lo, hi))
        keep = vis != OUTSIDE
        culled += int((~keep).sum())
        nodes, vis = nodes[keep], vis[keep]
        L = index.keys[nodes, 0]
        if brute:
            refine = L > 0
        else:
            dmin = view.box_distance(index.lo[nodes], index.hi[nodes])
            err = index.error[nodes]
            with np.errstate(invalid="ignore"):
                refine = (L > 0) & ((lam * err > tau * dmin) | ((dmin == 0) & (err > 0)))
        leaves.append(nodes[~refine])
        par = index.keys[nodes[refine]]
        par_inside = vis[refine] == INSIDE
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
    return leaves, {"tiles_visited": visited, "tiles_culled": culled}

"""Level-of-detail selection: one ``select(view, τ)`` interface over every strategy.

- ``rtin``: LP/RTIN vertex refinement (seed 002), crack-free by construction.
- ``chunked``: the stored tile quadtree with skirts (seed 000 GTR / chunked LOD).
- ``bruteforce``: every full-resolution tile in the frustum (the baseline).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pyvista as pv

from geoterrain.lod.chunked import TileIndex, select_tiles, union_jack_faces
from geoterrain.lod.kernels import extract
from geoterrain.lod.mesh import orient_ccw, polydata
from geoterrain.lod.rtin import static_active, view_active
from geoterrain.view import View

STRATEGIES = ("rtin", "chunked", "bruteforce")


@dataclass
class Selection:
    """A selected mesh and what it cost.

    ``mesh`` has float64 points in the scene frame of ``Terrain.scene_xyz()``,
    point data ``grid_ij`` (row, column of each vertex's sample) and cell data
    ``skirt`` (1 on skirt triangles) and ``level`` (pyramid level).
    """

    mesh: pv.PolyData
    stats: dict = field(default_factory=dict)

    @property
    def ij(self) -> np.ndarray:
        if "grid_ij" not in self.mesh.point_data:
            return np.zeros((0, 2))
        return np.asarray(self.mesh.point_data["grid_ij"])

    @property
    def faces(self) -> np.ndarray:
        if self.mesh.n_cells == 0:
            return np.zeros((0, 3), np.int64)
        return self.mesh.faces.reshape(-1, 4)[:, 1:]

    def surface_faces(self) -> np.ndarray:
        """Faces of the terrain surface (skirts removed)."""
        f = self.faces
        if len(f) and "skirt" in self.mesh.cell_data:
            return f[np.asarray(self.mesh.cell_data["skirt"]) == 0]
        return f


class Selector:
    """Per-terrain LOD state: the tile index, cached tile meshes, the last selection."""

    def __init__(self, terrain):
        self.terrain = terrain
        self._index: TileIndex | None = None
        self._tile_mesh: dict[tuple, tuple] = {}
        self._faces_template = union_jack_faces(terrain.grid.t)
        self._last: tuple | None = None
        self._vid: np.ndarray | None = None
        # invalid samples' stand-in height in the nested spheres: the middle of the valid
        # range, as errors.vertex_radii uses, so a sphere centred there still nests
        lo = [v["zmin"] for v in terrain.tile_info.values() if v["zmin"] is not None]
        hi = [v["zmax"] for v in terrain.tile_info.values() if v["zmax"] is not None]
        terrain.z_proxy = 0.5 * (min(lo) + max(hi)) if lo else 0.0

    @property
    def index(self) -> TileIndex:
        if self._index is None:
            self._index = TileIndex(self.terrain)
        return self._index

    # ------------------------------------------------------------------ rtin
    def _rtin(self, active_set, view: View | None = None) -> tuple[pv.PolyData, dict]:
        t = self.terrain
        N = t.grid.size
        if self._vid is None:
            self._vid = np.full(N * N, -1, np.int32)
        faces, flat = extract(active_set.active, active_set.mixed, self._vid)
        ij = np.stack([flat // N, flat % N], 1)
        g = t.gather(ij[:, 0], ij[:, 1], ("height", "x", "y"))
        h, X, Y = g["height"], g["x"], g["y"]
        xyz = np.stack([X, Y, t.frame.z(h)], 1)
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
        lvl = t.vertex_level(ij[:, 0], ij[:, 1])
        level = np.minimum(np.minimum(lvl[faces[:, 0]], lvl[faces[:, 1]]), lvl[faces[:, 2]])
        mesh = polydata(xyz, faces, ij, {"skirt": np.zeros(len(faces), np.uint8),
                                         "level": level.astype(np.int16)})
        return mesh, {}

    def _terrain_outside(self, view: View) -> bool:
        """True when the whole terrain's box is outside the frustum (nothing to decode)."""
        ix = self.index
        top = ix.rows_of(np.array([[self.terrain.grid.top_level, 0, 0]]))
        if top[0] < 0:
            return True
        return bool(view.box_visibility(ix.lo[top], ix.hi[top])[0] == 0)

    # --------------------------------------------------------------- tiles
    def tile_mesh(self, row: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cached geometry of one stored tile: ij (V, 2), xyz (V, 3), valid (V,), faces."""
        if row in self._tile_mesh:
            return self._tile_mesh[row]
        t, g = self.terrain, self.terrain.grid
        L, x, y = (int(v) for v in self.index.keys[row])
        tile = t.tile(L, x, y)
        ii, jj = np.meshgrid(g.tile_rows(L, y), g.tile_cols(L, x), indexing="ij")
        ij = np.stack([ii.ravel(), jj.ravel()], 1)
        X, Y = t.frame.xy(ij[:, 0], ij[:, 1])
        xyz = np.stack([X, Y, t.frame.z(tile.heights.ravel())], 1)
        valid = tile.valid.ravel()
        f = self._faces_template
        faces = orient_ccw(ij, f[valid[f].all(1)])
        out = (ij, xyz, valid, faces)
        self._tile_mesh[row] = out
        return out

    def _skirts(self, row, xyz, valid, depth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Skirt vertices, faces (local indices ≥ len(xyz)) and the edge sample of each
        skirt vertex, along the tile's inner edges."""
        g = self.terrain.grid
        T = g.tile_samples
        L, x, y = (int(v) for v in self.index.keys[row])
        n_side = g.tiles_per_side(L)
        idx = np.arange(T * T).reshape(T, T)
        edges = []
        if y > 0:
            edges.append(idx[0])
        if y < n_side - 1:
            edges.append(idx[-1])
        if x > 0:
            edges.append(idx[:, 0])
        if x < n_side - 1:
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

    def _tiles(self, view: View, tau: float, brute: bool) -> tuple[pv.PolyData, dict]:
        leaves, stats = select_tiles(self.terrain, self.index, view, tau, brute=brute)
        depth = 0.0
        if not brute and len(leaves):
            bnd = self.index.boundary[leaves]
            depth_all = float(np.max(bnd[np.isfinite(bnd)], initial=0.0))
        ijs, xyzs, faces, skirt, level = [], [], [], [], []
        off = 0
        for row in leaves.tolist():
            ij, xyz, valid, f = self.tile_mesh(row)
            L = int(self.index.keys[row, 0])
            ijs.append(ij)
            xyzs.append(xyz)
            faces.append(f + off)
            skirt.append(np.zeros(len(f), np.uint8))
            level.append(np.full(len(f), L, np.int16))
            n = len(xyz)
            if not brute:
                be = self.index.boundary[row]
                depth = (be if np.isfinite(be) else 0.0) + depth_all
                if depth > 0:
                    sxyz, sf, src = self._skirts(row, xyz, valid, depth)
                    ijs.append(ij[src])
                    xyzs.append(sxyz)
                    faces.append(sf + off)
                    skirt.append(np.ones(len(sf), np.uint8))
                    level.append(np.full(len(sf), L, np.int16))
                    n += len(sxyz)
            off += n
        if not ijs:
            return polydata(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), stats
        xyz, ij, faces = np.concatenate(xyzs), np.concatenate(ijs), np.concatenate(faces)
        used = np.zeros(len(xyz), bool)  # drop the vertices no triangle uses (nodata)
        used[faces] = True
        faces = (np.cumsum(used) - 1)[faces]
        mesh = polydata(xyz[used], faces, ij[used],
                        {"skirt": np.concatenate(skirt), "level": np.concatenate(level)})
        return mesh, stats

    # ----------------------------------------------------------------- API
    def select(self, view: View, pixel_error: float = 1.0, strategy: str = "rtin") -> Selection:
        if strategy not in STRATEGIES:
            raise ValueError(f"unknown strategy {strategy!r}; use one of {', '.join(STRATEGIES)}")
        if not pixel_error > 0:
            raise ValueError(f"pixel_error must be > 0, got {pixel_error}")
        key = (view.look_from, view.look_at, view.up, view.fov_y_deg, view.size, view.near,
               view.far, float(pixel_error), strategy)
        if self._last is not None and self._last[0] == key:
            sel = self._last[1]
            return Selection(sel.mesh, {**sel.stats, "reused": True, "select_ms": 0.0,
                                        "tiles_decoded": 0})
        t0 = time.perf_counter()
        dec0 = self.terrain.decoded_tiles
        if strategy == "rtin":
            if self._terrain_outside(view):
                mesh, stats = polydata(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), {}
            else:
                act = view_active(self.terrain, self.index, view, pixel_error)
                mesh, stats = self._rtin(act, view)
        else:
            mesh, stats = self._tiles(view, pixel_error, brute=strategy == "bruteforce")
        sel = self._finish(mesh, stats, strategy, t0, dec0)
        sel.stats["pixel_error"] = float(pixel_error)
        self._last = (key, sel)
        return sel

    def static(self, max_error: float) -> Selection:
        if not max_error >= 0:
            raise ValueError(f"max_error must be ≥ 0, got {max_error}")
        t0 = time.perf_counter()
        dec0 = self.terrain.decoded_tiles
        mesh, stats = self._rtin(static_active(self.terrain, self.index, max_error))
        sel = self._finish(mesh, stats, "static", t0, dec0)
        sel.stats["max_error"] = float(max_error)
        return sel

    def _finish(self, mesh, stats, strategy, t0, dec0) -> Selection:
        ms = (time.perf_counter() - t0) * 1e3
        skirt = np.asarray(mesh.cell_data["skirt"]) if mesh.n_cells else np.zeros(0)
        stats = {"strategy": strategy, "triangles": int((skirt == 0).sum()),
                 "skirt_triangles": int((skirt == 1).sum()), "vertices": int(mesh.n_points),
                 "tiles_visited": 0, "tiles_culled": 0, **stats,
                 "tiles_decoded": int(self.terrain.decoded_tiles - dec0),
                 "select_ms": round(ms, 3), "reused": False}
        return Selection(mesh, stats)

"""Level-of-detail selection: one seam, :func:`select`, over every registered strategy.

A strategy is a module with ``select(terrain, view, tau) -> (mesh, stats)``, registered
by one line in :mod:`geoterrain.lod.registry`; the mesh is a
:class:`~geoterrain.lod.mesh.MeshParts` (numpy arrays; no VTK object, so a selection
runs on any thread), which :attr:`Selection.vtk_mesh` makes into VTK's object on the
thread that draws, and :attr:`Selection.mesh` hands to callers as a ``pyvista.PolyData``:

- ``rtin`` (:mod:`~geoterrain.lod.rtin`): LP vertex refinement (seed 002), conforming;
- ``chunked`` (:mod:`~geoterrain.lod.chunked`): the stored tile quadtree with skirts
  (seed 000);
- ``bruteforce`` (:mod:`~geoterrain.lod.bruteforce`): every full-resolution tile in view.

:func:`select` and :func:`static` do what is common to all of them once: check
the arguments (a :class:`~geoterrain.exceptions.UsageError` in API words), time
the selection, count the tiles it decoded, and hand back the previous
:class:`Selection` when the camera, τ and strategy are unchanged (``reuse=True``).
Strategies only read the terrain; what they derive from it is cached in
:mod:`geoterrain.lod.tiles` and in their own modules, weakly keyed by the terrain.

Examples
--------
>>> import geoterrain, tempfile, os
>>> from geoterrain.ingest.synth import generate, write_geotiff
>>> dem = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 65, seed=2))
>>> t = geoterrain.open(geoterrain.preprocess(dem))
>>> sel = select(t, geoterrain.View((0, -900, 500), (0, 0, 0)), pixel_error=1.0)
>>> sel.stats["strategy"], sel.stats["triangles"] > 0
('rtin', True)
>>> select(t, geoterrain.View((0, -900, 500), (0, 0, 0)), 1.0).stats["reused"]
True
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.exceptions import UsageError
from geoterrain.lod.registry import DEFAULT, REGISTRY, STRATEGIES, StrategyInfo, strategy_info

if TYPE_CHECKING:
    import pyvista as pv

    from geoterrain.terrainlike import TerrainLike

__all__ = ["DEFAULT", "REGISTRY", "STRATEGIES", "Selection", "StrategyInfo", "select", "static",
           "strategy_info"]



class Selection:
    """A selected mesh and what it cost.

    ``mesh`` (a ``pyvista.PolyData``) has float64 points in the scene frame of
    ``Terrain.scene_xyz()``, point data ``grid_ij`` (row, column of each vertex's sample)
    and ``elevation`` (metres, without vertical exaggeration; the active scalars) and cell
    data ``skirt`` (1 on skirt triangles) and ``level`` (pyramid level). ``parts`` is the
    mesh as the strategy made it (a :class:`~geoterrain.lod.mesh.MeshParts`: numpy arrays,
    no VTK object, so a selection runs and is read on any thread); ``vtk_mesh`` the same
    arrays in VTK's object (a :class:`~geoterrain.lod.mesh.TriMesh`, made on first use by
    the thread that asks: the thread that draws), what the offscreen render draws without
    importing PyVista; ``mesh`` shares its arrays (made on first use).
    ``stats`` holds ``strategy``, ``triangles`` (skirts excluded),
    ``skirt_triangles``, ``vertices``, ``tiles_visited``, ``tiles_culled``,
    ``tiles_decoded``, ``select_ms``, ``reused`` and ``pixel_error`` or ``max_error``.
    """

    __slots__ = ("stats", "parts")

    def __init__(self, mesh, stats: dict | None = None):
        # a MeshParts, or a TriMesh or pyvista.PolyData given by a caller: each reads
        # points, point_data, cell_data, n_points, n_cells and regular_faces
        self.parts = mesh
        self.stats = {} if stats is None else stats

    @property
    def vtk_mesh(self):
        """The mesh as VTK's object (a :class:`~geoterrain.lod.mesh.TriMesh`, made once,
        by the calling thread, from :attr:`parts`)."""
        from geoterrain.lod.mesh import MeshParts

        m = self.parts
        return m.trimesh() if isinstance(m, MeshParts) else m

    @property
    def mesh(self) -> pv.PolyData:
        """The mesh as a ``pyvista.PolyData`` (imports PyVista; arrays shared with
        ``vtk_mesh``; one object per mesh, whichever selection of it asks)."""
        from geoterrain.lod.mesh import TriMesh

        m = self.vtk_mesh
        if not isinstance(m, TriMesh):
            return m
        if m.shown is None:
            m.shown = m.pyvista()
        return m.shown

    def __repr__(self) -> str:
        return f"Selection({type(self.parts).__name__}, stats={self.stats!r})"

    @property
    def ij(self) -> np.ndarray:
        """(V, 2) grid row and column of each vertex."""
        m = self.parts
        if "grid_ij" not in m.point_data:
            return np.zeros((0, 2))
        return np.asarray(m.point_data["grid_ij"])

    @property
    def faces(self) -> np.ndarray:
        """(F, 3) vertex indices of every triangle, skirts included."""
        if self.parts.n_cells == 0:
            return np.zeros((0, 3), np.int64)
        return np.asarray(self.parts.regular_faces)  # every LOD mesh is all triangles

    def surface_faces(self) -> np.ndarray:
        """Faces of the terrain surface (skirts removed)."""
        f = self.faces
        if len(f) and "skirt" in self.parts.cell_data:
            return f[np.asarray(self.parts.cell_data["skirt"]) == 0]
        return f


def _view_key(view: View, tau: float, strategy: str, occlusion: bool,
              morph: bool | None) -> tuple:
    return (view.look_from, view.look_at, view.up, view.fov_y_deg, view.size, view.near,
            view.far, tau, strategy, occlusion, morph)


def select(terrain: TerrainLike, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT, *,
           reuse: bool = True, occlusion: bool = True,
           morph: bool | None = None) -> Selection:
    """The mesh of ``terrain`` for ``view`` with projected error ≤ ``pixel_error`` pixels.

    Parameters
    ----------
    terrain : geoterrain.Terrain
    view : the camera.
    pixel_error : the screen-space tolerance τ in pixels (finite, > 0).
    strategy : a name from :data:`STRATEGIES`.
    reuse : hand back the previous selection of this terrain when the camera, τ and
        strategy are unchanged (its stats say ``reused: True``, ``select_ms: 0``);
        False always selects anew (benchmarks time real selections).
    occlusion : cull tiles hidden behind nearer terrain before reading them
        (:mod:`geoterrain.lod.occlusion`; conservative: nothing visible is lost).
    morph : geomorph, for the strategies that can (rtin: seed 002's band 0.75 τ … τ;
        chunked: each chunk to its parent over the same band; geomipmap: continuous
        block levels, seed 000's trilinear geomipmapping; cdlod: seed 001's ranges);
        None: each strategy's default (rtin, chunked and geomipmap off, cdlod on).

    Examples
    --------
    >>> sel = select(t, View((0, -800, 400), (0, 0, 0)), 2.0, "chunked")  # doctest: +SKIP
    """
    info = strategy_info(strategy)
    occlusion, morph = bool(occlusion), None if morph is None else bool(morph)
    if not isinstance(view, View):
        raise UsageError(f"view must be a geoterrain.View, got {type(view).__name__}")
    try:
        tau = float(pixel_error)
    except (TypeError, ValueError):
        raise UsageError(f"pixel_error must be a number, got {pixel_error!r}") from None
    if not (math.isfinite(tau) and tau > 0):
        raise UsageError(f"pixel_error must be a finite number > 0, got {pixel_error}")
    key = _view_key(view, tau, strategy, occlusion, morph)
    last = terrain.derived(__name__, dict)  # the terrain's last selection, for reuse
    if reuse and last.get("key") == key:
        sel = last["selection"]
        return Selection(sel.parts, {**sel.stats, "reused": True, "select_ms": 0.0,
                                        "tiles_decoded": 0})
    t0, dec0 = time.perf_counter(), terrain.decoded_tiles
    mesh, stats = info.load()(terrain, view, tau, occlusion=occlusion, morph=morph)
    sel = _finish(terrain, mesh, stats, strategy, t0, dec0)
    sel.stats["pixel_error"] = tau
    last.update(key=key, selection=sel)
    return sel


def static(terrain: TerrainLike, max_error: float = 1.0, mesher: str = "rtin") -> Selection:
    """The static mesh within ``max_error`` of every valid level-0 sample.

    ``mesher``: ``"rtin"`` (the default) keeps every vertex with δ > ``max_error`` (the
    bintree cut, :func:`geoterrain.lod.rtin.static`); ``"tin"`` is the greedy-insertion
    TIN (:mod:`geoterrain.lod.tin`): fewer triangles, the whole grid read at once;
    ``"tin-full"`` the same with its collapse pass unbounded (fewer triangles still,
    about a quarter more time).

    Examples
    --------
    >>> static(t, 5.0).stats["strategy"]  # doctest: +SKIP
    'static'
    """
    from geoterrain.lod import rtin

    try:
        e = float(max_error)
    except (TypeError, ValueError):
        raise UsageError(f"max_error must be a number, got {max_error!r}") from None
    if not (e >= 0 and not math.isnan(e)):
        raise UsageError(f"max_error must be ≥ 0, got {max_error}")
    if mesher not in ("rtin", "tin", "tin-full"):
        raise UsageError(f"mesher must be 'rtin', 'tin' or 'tin-full', got {mesher!r}")
    t0, dec0 = time.perf_counter(), terrain.decoded_tiles
    if mesher != "rtin":
        from geoterrain.lod import tin

        mesh, stats = tin.static(terrain, e, mesher)
    else:
        mesh, stats = rtin.static(terrain, e)
    sel = _finish(terrain, mesh, stats, "static", t0, dec0, elevated=mesher == "rtin")
    sel.stats["max_error"] = e
    sel.stats["mesher"] = mesher
    return sel


def _finish(terrain: TerrainLike, mesh, stats: dict, strategy: str, t0: float, dec0: int,
            elevated: bool = False) -> Selection:
    from geoterrain.lod.mesh import add_elevation

    # a strategy whose mesh has its elevation, and counts its triangles, as it assembles
    # it says so (stats "elevated" and "triangles"): no pass over the mesh here
    if not (elevated or stats.pop("elevated", False)):  # (static: computed with positions)
        add_elevation(mesh, terrain.frame.z_scale)  # every strategy's mesh, skirts included
    ms = (time.perf_counter() - t0) * 1e3
    n = mesh.n_cells
    counted = {}
    if not {"triangles", "skirt_triangles"} <= stats.keys():
        skirt = np.asarray(mesh.cell_data["skirt"]) if n and "skirt" in mesh.cell_data \
            else np.zeros(0, np.uint8)
        none = not np.count_nonzero(skirt)  # one pass; most meshes have no skirt
        counted = {"triangles": n if none else int((skirt == 0).sum()),
                   "skirt_triangles": 0 if none else int((skirt == 1).sum())}
    stats = {"strategy": strategy, **counted,
             "vertices": int(mesh.n_points),
             "tiles_visited": 0, "tiles_culled": 0, **stats,
             "tiles_decoded": int(terrain.decoded_tiles - dec0),
             "select_ms": round(ms, 3), "reused": False}
    return Selection(mesh, stats)

"""Offscreen rendering of LOD terrain: the scene, single views and their PNGs
(orbits and fly-throughs: :mod:`geoterrain.rendering.animation`).

Every frame selects its own level of detail for its own camera
(``Terrain.select``) and draws the mesh in the scene frame (float64 points,
origin at the DEM centre, so large CRS coordinates never reach the GPU).

Shading (``shading=``):

- ``"normals"`` (default): elevation colours × a hillshade from the stored normal
  maps, as a view-dependent texture (:mod:`geoterrain.rendering.tiletextures`, seed 000 §2.5):
  each drawn footprint is shaded from the pyramid level whose texel projects to
  at most one pixel, built on demand for drawn tiles only and cached in the
  terrain's tile cache; one atlas per frame, mapped by texture coordinates. A
  coarse LOD mesh therefore shows the relief and colours of the data at screen
  resolution; only the silhouette moves. Against the bruteforce render of the
  same view with the whole-DEM level-0 texture (``textures="global"``), rtin at
  τ = 1 px on srtm1_japan at 1280×720 gives 37–43 dB. Texture vs geometric
  lighting was chosen by measurement: 40–46 dB vs 37–40 dB on srtm1_japan, and
  22–32 dB for per-vertex colours (Gouraud loses the detail inside coarse triangles).
- ``"elevation"``: the elevation colours of the same texture, no shading.
- ``"plain"``: one colour lit by the renderer from the mesh's own geometry:
  what a naive renderer shows (useful to look at the mesh itself).

Faces turned away (:data:`BACKFACE_CULLING`): where the eye is above the terrain's highest
point and inside its footprint (:meth:`TerrainScene.cull_faces_turned_away`), the renderer
culls the faces whose upward side faces away from it (every selection winds its faces
counter-clockwise seen from above; one with skirts, vertical faces wound either way, is
drawn whole). From there such a face lies behind a face turned towards the eye: drawn, it
only lost the depth test, or won a tie with it at a silhouette; culled, it is not
rasterised (the low flight of ``benchmarks/bench_render.py``: docs/lab/rendering-frame.md).
From outside the footprint, below its edge, a face turned away can be what the eye sees
(the underside at the terrain's open border): there every face is drawn. The frames of
:meth:`TerrainScene.draw` cull (:func:`render`, the animations, the benchmarks); the
interactive viewer and the notebook widget draw every face.

Where the palette has water (``water_level``, or the ``auto`` palette's sea at 0 m) a
flat, lit, semi-transparent water surface is drawn at its level
(:mod:`geoterrain.rendering.water`; ``water=False`` leaves the land below the level
coloured as water without it).

Examples
--------
>>> import geoterrain
>>> from geoterrain.rendering.scene import render, default_view
>>> t = geoterrain.open("dem.geoterrain")  # doctest: +SKIP
>>> stats = render(t, default_view(t), "view.png", title="My DEM")  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geoterrain import lod
from geoterrain.core.atomicfiles import write_atomic
from geoterrain.core.memory import peak_rss as _peak_rss
from geoterrain.core.threads import serial_for, serial_kernels
from geoterrain.core.view import View
from geoterrain.exaggerate import exaggerated
from geoterrain.exceptions import UsageError
from geoterrain.lod.mesh import TriMesh, polydata
from geoterrain.lod.registry import DEFAULT, strategy_info
from geoterrain.rendering.antialias import depth_buffer
from geoterrain.rendering.cameras import (  # noqa: F401 - the camera helpers are part of this API
    default_view,
    interpolate_views,
    load_cameras,
    orbit_views,
    project,
    terrain_bounds,
    to_scene,
)
from geoterrain.rendering.colours import Palette
from geoterrain.rendering.drape import Drape
from geoterrain.rendering.edgeaa import SPARSE_MAX_FACES, edge_antialias, silhouette_edges, sparse
from geoterrain.rendering.overlays import compose, layout_for
from geoterrain.rendering.shading import Light
from geoterrain.rendering.textures import SHADINGS, texture_image, texture_level
from geoterrain.rendering.tileshader import TileShader
from geoterrain.rendering.tiletextures import build_view_texture
from geoterrain.rendering.window import draw, offscreen_plotter, writable_target, write_png

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

BACKGROUND = (0.86, 0.90, 0.95)  # a pale sky
PLAIN_COLOR = (0.80, 0.78, 0.72)
# how far (pixels in the picture, at most) a perspective view's water surface may move when
# it is lifted over the terrain's coarse mesh (see TerrainScene.set_camera)
WATER_LIFT_PX = 0.5
#: The terrain's faces turned away from the eye are culled by the renderer, not drawn
#: (module docstring, "Faces turned away").
BACKFACE_CULLING = True


# -------------------------------------------------------------------------- scene
class TerrainScene:
    """One terrain actor in a PyVista plotter, updated in place with new LOD meshes.

    Shared by :func:`render`, :func:`orbit`, :func:`flythrough` and the viewer.

    Examples
    --------
    >>> import pyvista as pv
    >>> p = pv.Plotter(off_screen=True, window_size=(640, 480))  # doctest: +SKIP
    >>> scene = TerrainScene(p, t)  # doctest: +SKIP
    >>> img, stats = scene.frame(default_view(t, (640, 480)))  # doctest: +SKIP
    """

    def __init__(self, plotter, terrain: TerrainLike, shading: str = "normals",
                 cmap: str | Palette = "auto",
                 background: Sequence[float] = BACKGROUND, vertical_exaggeration: float = 1.0,
                 textures: str = "view", light: Light | None = None,
                 drape: Drape | None = None, occlusion: bool = True,
                 morph: bool | None = None, strips: bool = False, water: bool = True):
        from geoterrain.rendering import offscreen

        # VTK alone (offscreen.OffscreenPlotter: the same pictures without PyVista's
        # plotting modules), or a PyVista plotter (the viewer, notebooks)
        self._raw = isinstance(plotter, offscreen.OffscreenPlotter)
        terrain = exaggerated(terrain, vertical_exaggeration)
        self.strips = bool(strips)  # draw the mesh as seed 002's triangle strips

        if shading not in SHADINGS:
            raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
        self.plotter, self.terrain, self.shading, self.cmap = plotter, terrain, shading, cmap
        # where the first frame's bytes_read starts: at the store's opening when nothing was
        # read from it since, else now (then each frame from where the last one ended)
        read = int(getattr(terrain, "bytes_read", 0))
        opened = int(getattr(terrain, "open_bytes", -1))
        self._bytes_mark = read - opened if read == opened else read
        self.light, self.drape = light, drape
        self.occlusion, self.morph = occlusion, morph  # each frame's selection's switches
        # a mesh without holes over the box of its samples (cull_faces_turned_away)
        f, meta = getattr(terrain, "frame", None), getattr(terrain, "meta", None) or {}
        self._gapless = bool(f is not None and f.kind != "geographic"
                             and f.transform[1] == 0.0 and f.transform[3] == 0.0
                             and meta.get("valid_samples") == terrain.grid.rows
                             * terrain.grid.cols)
        self._samples = terrain.grid.rows * terrain.grid.cols  # the store's (_kernels)
        if ((light is not None and not light.is_default) or drape is not None) \
                and textures == "global":
            raise UsageError("sun, shadows, ambient occlusion and drapes need the per-view "
                             "textures")
        plotter.set_background(background)
        if not self._raw:
            plotter.theme.allow_empty_mesh = True  # a view may see no terrain at all
        self.textures = textures
        if textures not in ("view", "global"):
            raise UsageError(f"unknown textures {textures!r}; use 'view' or 'global'")
        self.level = texture_level(terrain) if textures == "global" else 0
        self.texture = None
        if shading != "plain" and textures == "global":
            self.texture = self._global_texture()
        elif shading != "plain":  # the per-view atlas replaces its image each frame
            self.shader = TileShader(terrain, shading, cmap, light, drape)
            if self._raw:
                self.texture = offscreen.texture(_image_data(np.zeros((1, 1, 3), np.uint8)))
            else:
                import pyvista as pv

                self.texture = pv.Texture(np.zeros((1, 1, 3), np.uint8))
                self.texture.interpolate = True
                self.texture.repeat = False
        self.mesh = TriMesh() if self._raw else TriMesh().pyvista()
        self.actor = None
        self.selection = None
        self._vtex = None  # the per-view atlas shown (kept while its pages stay the same)
        self.texture_stats: dict = {}
        self.water_actor = None
        self._water_pts = None
        if water and shading != "plain":
            from geoterrain.rendering.water import add_water, water_mesh, water_offset

            wm = water_mesh(terrain, cmap)
            if wm is not None:
                sun = (light.azimuth, light.elevation) if light is not None else (315.0, 45.0)
                if self._raw:
                    from geoterrain.rendering.shading import light_vector

                    self.water_actor = offscreen.water_actor(plotter, wm, light_vector(*sun))
                    water_offset(self.water_actor)
                else:
                    self.water_actor = add_water(plotter, wm, sun)
                step = max(1, wm.n_points // 4096)  # where the lift is measured
                self._water_pts = np.asarray(wm.points, np.float64)[::step]

    def retexture_all(self) -> None:
        """After the store was edited: the whole-terrain texture (``textures="global"``)
        is made again; per-view textures come from the tiles' shading, which the
        terrain's refresh dropped where the edit reached."""
        self._vtex = None  # its texels may show the data before the edit
        if self.textures == "global" and self.shading != "plain":
            self.texture = tex = self._global_texture()
            if self.actor is not None:
                self.actor.SetTexture(tex)

    def _global_texture(self):
        """The whole-terrain texture (``textures="global"``), interpolated and mipmapped."""
        img = texture_image(self.terrain, self.shading, self.cmap, self.level)
        if self._raw:
            from geoterrain.rendering import offscreen

            # pyvista.Texture's image: its last row first (v = 0 at the bottom)
            return offscreen.texture(_image_data(np.ascontiguousarray(img[::-1])),
                                     mipmap=True)
        import pyvista as pv

        tex = pv.Texture(img)
        tex.interpolate = True
        tex.mipmap = True
        tex.repeat = False
        return tex
    def _tcoords(self, ij: np.ndarray) -> np.ndarray:
        R, C = self.terrain.grid.level_shape(self.level)  # the texture_image's shape
        s = float(1 << self.level)
        tc = np.empty((len(ij), 2), np.float32)
        tc[:, 0] = (ij[:, 1] / s + 0.5) / C
        tc[:, 1] = 1.0 - (ij[:, 0] / s + 0.5) / R
        return tc

    def view_texture(self, selection, view: View, max_builds: int | None = None):
        """The per-view atlas of ``selection`` (:mod:`geoterrain.rendering.tiletextures`), or None.

        Thread-safe to call off the UI thread (it touches no VTK object); pass the
        result to :meth:`update`. ``max_builds``: at most this many tiles shaded anew,
        the rest magnified from cached ancestors
        (:func:`~geoterrain.rendering.tiletextures.build_view_texture`). Where the atlas
        shown holds the same tiles at the same places, its image is kept, and
        :meth:`update` uploads no texture.
        """
        if self.shading == "plain" or self.textures != "view":
            return None
        return build_view_texture(self.terrain, selection, view, self.shader,
                                  max_builds=max_builds, previous=self._vtex)

    def update(self, selection, view: View | None = None, vtex=None) -> None:
        """Show ``selection``'s mesh (the actor is reused).

        With per-view textures (the default), ``view`` (or a ready ``vtex`` from
        :meth:`view_texture`) chooses each footprint's texture level; without either
        the camera's current view is used.
        """
        src = selection.parts  # arrays; VTK's mesh of them is made only where drawn as it is
        mesh = TriMesh()
        if self.texture is not None and self.textures == "view" and src.n_cells:
            if vtex is None:
                vtex = self.view_texture(selection, view if view is not None else
                                         View.from_camera(self.plotter.camera,
                                                          tuple(self.plotter.window_size)))
            # fixed-size cells wrapping vtex's arrays: no legacy (3, a, b, c) cell array
            # to build and convert (3–5 ms a frame at 50 k faces); faces keep their
            # order, so the selection's cell data carries over
            mesh = polydata(vtex.points, vtex.faces, cell_arrays={
                k: np.asarray(src.cell_data[k]) for k in ("level", "skirt")
                if k in src.cell_data})
            mesh.active_texture_coordinates = vtex.tcoords  # VTK's v (ViewTexture)
            if self._vtex is None or vtex.image is not self._vtex.image:
                # shared, not copied; the same image is not given (nor uploaded) again
                self.texture.SetInputDataObject(_image_data(vtex.image))
            self._vtex = vtex
            self.texture_stats = dict(vtex.stats)
        elif src.n_points:
            self.texture_stats = {"textures_built": 0, "texture_tiles": 0}
            src = selection.vtk_mesh
            mesh.SetPoints(src.GetPoints())  # shared: the selection's mesh is not changed
            if src.n_cells:
                mesh.SetPolys(src.GetPolys())
            if self.texture is not None and self.textures == "global":
                mesh.active_texture_coordinates = self._tcoords(
                    np.asarray(src.point_data["grid_ij"]))
            for k in ("level", "skirt"):
                if k in src.cell_data:
                    mesh.cell_data[k] = src.cell_data[k]
        else:
            self.texture_stats = {"textures_built": 0, "texture_tiles": 0}
        if self.strips and mesh.n_cells and src.n_cells and "grid_ij" in src.point_data:
            from geoterrain.lod.strips import strip_mesh

            mesh = strip_mesh(mesh, src, self.terrain.grid)
        elif not self._raw:
            mesh = mesh.pyvista()  # PyVista's plotter (the viewer, notebooks)
        self.selection = selection
        if self.actor is None and self._raw:
            from geoterrain.rendering.offscreen import terrain_actor

            self.actor = terrain_actor(self.plotter, mesh, (1.0, 1.0, 1.0) if self.texture
                                       is not None else PLAIN_COLOR, self.texture is None,
                                       self.texture)
        elif self.actor is None:
            kw: dict = {"name": "terrain", "show_scalar_bar": False, "reset_camera": False}
            if self.texture is not None:
                self.actor = self.plotter.add_mesh(mesh, color="white", lighting=False, **kw)
                self.actor.SetTexture(self.texture)
            else:
                self.actor = self.plotter.add_mesh(mesh, color=PLAIN_COLOR, lighting=True,
                                                   smooth_shading=False, **kw)
            self.actor.mapper.ScalarVisibilityOff()  # colours come from the texture
        else:
            self.actor.GetMapper().SetInputData(mesh)
        self.mesh = mesh

    def cull_faces_turned_away(self, view: View) -> bool:
        """Whether the renderer may cull this frame's faces turned away from the eye of
        ``view`` (:data:`BACKFACE_CULLING`, module docstring), and set it so: a
        perspective view whose eye is above the terrain's highest point and inside its
        footprint, on a terrain without nodata in an affine, axis-aligned frame (its mesh
        covers the box of its samples without a hole), drawn without skirts. From there
        every line of sight meets the surface first from above, on a face turned towards
        the eye; a face turned away lies behind one, and culled moves only the pixels
        where the two tied.

        Examples
        --------
        >>> from geoterrain.rendering.window import offscreen_plotter
        >>> scene = TerrainScene(offscreen_plotter((64, 48)), t)
        >>> lo, hi = t.scene_box()
        >>> above = View(((lo + hi) / 2 + [0, 0, hi[2]]).tolist(), hi.tolist(), size=(64, 48))
        >>> _ = scene.frame(above)
        >>> scene.cull_faces_turned_away(above), scene.cull_faces_turned_away(default_view(t))
        (True, False)
        >>> scene.plotter.close()
        """
        cull = bool(BACKFACE_CULLING and self.actor is not None and not view.parallel
                    and self._gapless and self.selection is not None)
        if cull:
            skirt = self.selection.parts.cell_data.get("skirt")
            lo, hi = self.terrain.scene_box()
            e = np.asarray(view.eye, np.float64)
            cull = bool((skirt is None or not np.asarray(skirt).any())
                        and lo[0] <= e[0] <= hi[0] and lo[1] <= e[1] <= hi[1] and e[2] > hi[2])
        if self.actor is not None:
            prop = self.actor.GetProperty()
            if bool(prop.GetBackfaceCulling()) != cull:
                prop.SetBackfaceCulling(cull)
        return cull

    def set_camera(self, view: View) -> None:
        """Point the plotter's camera like ``view`` (and fit the clipping range).

        VTK gets the view's own orthonormal up (``View.basis``), never a view-up it
        would have to re-orthogonalise: the picture, the frustum the LOD culls with
        and :func:`project` are one camera, straight down included.
        """
        cam = self.plotter.camera
        _, u, f = view.basis()
        if self.water_actor is not None:
            # a map, seen from straight above, draws the water over the terrain whatever
            # its mesh (coarse there: vertical errors do not show), lifted above its top
            # (which moves nothing in the picture); a perspective view lifts it as far as
            # moves it by WATER_LIFT_PX in the picture at most (seen from high above, a
            # coarse mesh's vertical errors barely show either, and would hide the water
            # near the coast)
            lo, hi = self.terrain.scene_box()
            top = max(float(hi[2] - lo[2]), 1.0) * 1.01
            lift = top if view.parallel else min(top, self._water_lift(view))
            self.water_actor.SetPosition(0.0, 0.0, lift)
        if view.parallel:  # a map: the parallel projection of what the view frames
            target = np.asarray(view.look_at, np.float64)
            d = float(np.linalg.norm(view.eye - target))
            lo, hi = self.terrain.scene_box()
            near = 2.0 * float(np.linalg.norm(hi - lo)) + 1.0  # depth precision: close
            cam.SetParallelProjection(True)
            cam.SetParallelScale(d * np.tan(np.radians(view.fov_y_deg) / 2.0))
            _place(cam, tuple(target - near * f), tuple(target), tuple(u))
            self.plotter.renderer.ResetCameraClippingRange()
            return
        cam.SetParallelProjection(False)
        _place(cam, view.look_from, view.look_at, tuple(u))
        cam.SetViewAngle(view.fov_y_deg)
        self.plotter.renderer.ResetCameraClippingRange()
        if view.near is not None and view.far is not None:
            cam.SetClippingRange(view.near, view.far)

    def _water_lift(self, view: View) -> float:
        """The height (scene units) the water surface may be lifted by in the perspective
        ``view`` while no point of it moves more than ``WATER_LIFT_PX`` in the picture:
        that over the largest of its points' picture motion per unit of height (the
        derivative of the projection along z)."""
        pts = self._water_pts
        if pts is None or not len(pts):
            return 0.0
        r, u, f = view.basis()
        rel = pts - np.asarray(view.look_from, np.float64)
        d = rel @ f  # depth along the view direction
        front = d > 1e-9
        if not front.any():
            return 0.0
        d, x, y = d[front], rel[front] @ r, rel[front] @ u
        k = view.lam  # pixels per unit across at depth 1
        # a point at (x, y) across and d along the view sits at k·(x, y)/d px from the
        # centre; moving it up by one unit changes x, y, d by r_z, u_z, f_z
        dx = k * (r[2] * d - x * f[2]) / d**2
        dy = k * (u[2] * d - y * f[2]) / d**2
        rate = float(np.sqrt(dx * dx + dy * dy).max())
        return WATER_LIFT_PX / rate if rate > 0 else float("inf")

    def frame(self, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT,
              ) -> tuple[np.ndarray, dict]:
        """Select the LOD for ``view``, draw it and return the image (H, W, 3) uint8 and stats.

        The stats count what the whole frame did (selection and texture):
        ``tiles_decoded`` (heights), ``normals_decoded``, ``bounds_decoded`` (δ, r),
        ``textures_built``, ``atlas_reused`` (the atlas shown before was kept: no texel
        copied or uploaded), ``bytes_read`` and ``peak_rss_mb`` (the process's peak
        resident memory so far), besides the selection's own stats. ``bytes_read`` is every
        byte read from the store file since the scene's previous frame, as the operating
        system counts them (:attr:`geoterrain.terrain.Terrain.bytes_read`); the first frame's
        count starts where the scene was made, or where the store was opened when nothing
        was read from it since (then it includes the opening), so the frames' counts add up
        to what the process read from the store. Times: ``select_ms``,
        ``texture_ms``, ``render_ms`` (the draw and read-back) and ``frame_ms``, wall
        clock; ``cpu_ms`` and ``render_cpu_ms``, the process's CPU time over the frame
        and over the draw, the renderer's threads included (a software renderer draws
        on every core, so ``render_cpu_ms`` can exceed ``render_ms``).
        ``anti_aliasing`` is the one the picture got (under ``auto``: ``edges`` or
        ``msaa``, :meth:`_anti_aliasing`); ``render_ms`` includes finding and blending
        the edges.
        """
        p = self.prepare(view, pixel_error, strategy)
        return self.draw(p.selection, p.view, p.started, p.vtex, read=p.read)

    def prepare(self, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT
                ) -> Prepared:
        """The store's half of :meth:`frame`: the selection for ``view`` and its atlas
        (:meth:`view_texture`), read in one snapshot of the store (one read transaction:
        its version checked once, not at every blob). It makes no VTK object (the
        selection's mesh is :class:`~geoterrain.lod.mesh.MeshParts`, the atlas numpy
        arrays), so it may run on a worker thread while the picture before is drawn
        (:meth:`frames`), once that picture's mesh is shown (its atlas is the one this
        atlas may keep): a VTK object made there while this thread frees one could
        deadlock the two threads (VTK's garbage collector's lock and the GIL).

        Examples
        --------
        >>> p = scene.prepare(default_view(t, (320, 240)))  # doctest: +SKIP
        >>> img, st = scene.draw(p.selection, p.view, p.started, p.vtex,  # doctest: +SKIP
        ...                      read=p.read)
        """
        t = self.terrain
        if view.near is None or view.far is None:  # the picture's own clipping planes
            view = view.clipped_to(*t.scene_box())
        c0 = io_counters(t)
        t0, p0 = time.perf_counter(), time.process_time()
        with self._kernels(), store_snapshot(t):
            sel = lod.select(t, view, pixel_error=pixel_error, strategy=strategy,
                             occlusion=self.occlusion, morph=self.morph)
            vtex = self.view_texture(sel, view)
        return Prepared(view, sel, vtex, (t0, p0, c0), io_counters(t))

    def frames(self, views: Sequence[View], pixel_error: float = 1.0,
               strategy: str = DEFAULT, overlap: bool = False
               ) -> Iterator[tuple[np.ndarray, dict]]:
        """:meth:`frame` of each of ``views`` in turn (a flight: every camera known
        beforehand), yielded as each picture is done.

        ``overlap``: view n + 1's :meth:`prepare` (selection and atlas, compiled passes
        that release the GIL, and the store's reads) runs on a worker thread while view n
        is drawn, where the renderer's own threads leave a core idle; the draw stays on
        this thread (VTK's). The pictures are :meth:`frame`'s, byte for byte (the same
        steps in the same order on the same data: view n + 1's atlas is made once view n's
        is shown, as without overlap). A picture comes out no later than without it, but
        each camera must be known one frame before its picture is drawn. Besides
        :meth:`frame`'s stats (whose ``frame_ms`` and ``cpu_ms`` then run from its
        prepare's start, on the worker, to its picture: the latency), ``interval_ms`` and
        ``interval_cpu_ms`` are the wall and process CPU time since the previous picture
        (the throughput; the first from the call).

        Examples
        --------
        >>> for img, st in scene.frames(orbit_views(t, 8)):  # doctest: +SKIP
        ...     print(st["interval_ms"])
        """
        views = list(views)
        last = (time.perf_counter(), time.process_time())

        def stamp(st: dict) -> dict:
            nonlocal last
            now = (time.perf_counter(), time.process_time())
            st["interval_ms"] = round((now[0] - last[0]) * 1e3, 3)
            st["interval_cpu_ms"] = round((now[1] - last[1]) * 1e3, 3)
            last = now
            return st

        if not overlap or len(views) < 2:
            for v in views:
                img, st = self.frame(v, pixel_error, strategy)
                yield img, stamp(st)
            return
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(1, thread_name_prefix="geoterrain-prepare") as ex:
            nxt = ex.submit(self.prepare, views[0], pixel_error, strategy)
            for k in range(len(views)):
                p = nxt.result()
                after = None
                if k + 1 < len(views):
                    def after(v=views[k + 1]):  # view n's mesh and atlas are shown
                        nonlocal nxt
                        nxt = ex.submit(self.prepare, v, pixel_error, strategy)
                img, st = self.draw(p.selection, p.view, p.started, p.vtex, read=p.read,
                                    before_render=after)
                yield img, stamp(st)


    def draw(self, sel: lod.Selection, view: View, started: tuple | None = None,
             vtex=None, *, read: dict | None = None, before_render=None
             ) -> tuple[np.ndarray, dict]:
        """Draw a selection made for ``view`` (by :meth:`frame`, or by a strategy called
        with arguments of its own, as the benchmark experiments do) and return the image
        and the stats of :meth:`frame`; ``started``: (wall clock, process clock, io
        counters) when the selection began, else the draw's own start. ``vtex``: its
        atlas, made already (:meth:`prepare`), and ``read``: the io counters at the end
        of the reads (else they are taken after the draw). ``before_render``: called once
        the mesh is shown and the camera set, before the renderer draws (:meth:`frames`
        starts the next view's :meth:`prepare` there).

        Examples
        --------
        >>> img, stats = scene.draw(sel, view)  # doctest: +SKIP
        """
        t = self.terrain
        if view.near is None or view.far is None:
            view = view.clipped_to(*t.scene_box())
        t1 = time.perf_counter()
        t0, p0, c0 = started if started is not None else (t1, time.process_time(),
                                                         io_counters(t))
        with self._kernels():
            self.update(sel, view, vtex)
            self.set_camera(view)
            self.cull_faces_turned_away(view)
            t2, p2 = time.perf_counter(), time.process_time()
            edges, aa = self._anti_aliasing()
            if before_render is not None:
                before_render()
            img = draw(self.plotter)
            if edges is not None:
                img = edge_antialias(img, depth_buffer(self.plotter), edges)
        t3, p3 = time.perf_counter(), time.process_time()
        c1 = dict(read) if read is not None else io_counters(t)
        c0["bytes_read"], self._bytes_mark = self._bytes_mark, c1["bytes_read"]
        stats = {**sel.stats, "select_tiles_decoded": sel.stats.get("tiles_decoded", 0),
                 **{k: c1[k] - c0[k] for k in c0},
                 "textures_built": int(self.texture_stats.get("textures_built", 0)),
                 "texture_tiles": int(self.texture_stats.get("texture_tiles", 0)),
                 "texture_ms": float(self.texture_stats.get("texture_ms", 0.0)),
                 "atlas_reused": bool(self.texture_stats.get("atlas_reused", False)),
                 "peak_rss_mb": round(peak_rss() / 2**20, 1),
                 "update_ms": round((t2 - t1) * 1e3, 3),
                 "render_ms": round((t3 - t2) * 1e3, 3),
                 "frame_ms": round((t3 - t0) * 1e3, 3),
                 "anti_aliasing": aa,
                 "cpu_ms": round((p3 - p0) * 1e3, 3),
                 "render_cpu_ms": round((p3 - p2) * 1e3, 3)}
        return img, stats

    def _kernels(self) -> AbstractContextManager:
        """Where a frame's compiled kernels run: on the calling thread (their serial
        twins, :func:`~geoterrain.core.threads.serial_kernels`) for a store of fewer
        than :data:`~geoterrain.core.threads.PARALLEL_MIN_SAMPLES` samples, whose whole
        frame is small work (:func:`~geoterrain.core.threads.cores_for`'s line), else as
        each call chooses. The same pixels either way; a small store's first render then
        compiles the twins only, not the threaded kernels as well.

        Examples
        --------
        >>> with scene._kernels():  # doctest: +SKIP
        ...     pass
        """
        if serial_for(self._samples):
            return serial_kernels()
        return contextlib.nullcontext()

    def _anti_aliasing(self):
        """This frame's anti-aliasing, chosen before it is drawn: (the silhouette edges
        to blend after the draw, or None; the mode's name for the stats).

        ``auto`` (the default) finds the selection mesh's silhouette edges through the
        camera VTK draws with and, where they are sparse
        (:func:`geoterrain.rendering.edgeaa.sparse`), draws without multisampling and blends
        them; otherwise it draws with MSAA. ``edges`` always blends them.
        """
        p = self.plotter
        mode = getattr(p, "_geoterrain_aa", "msaa")
        if mode == "auto" and self.water_actor is not None:
            mode = "msaa"  # the water surface's edges are not the mesh's: multisampling
            rw = p.render_window
            if rw.GetMultiSamples() != p._geoterrain_samples:
                rw.SetMultiSamples(p._geoterrain_samples)
        if mode not in ("auto", "edges"):
            return None, mode
        mesh = self.selection.parts if self.selection is not None else None
        edges = None
        if mesh is not None and mesh.n_cells and (
                mode == "edges" or mesh.n_cells <= SPARSE_MAX_FACES):
            w, h = p.render_window.GetSize()
            m = p.camera.GetCompositeProjectionTransformMatrix(w / h, -1, 1)
            proj = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])
            faces = np.asarray(mesh.regular_faces)
            edges = silhouette_edges(np.asarray(mesh.points), faces, proj, (w, h),
                                     p.camera.position)
        if mode == "auto":
            if edges is not None and not sparse(edges):
                edges = None
            rw = p.render_window
            want = 0 if edges is not None else p._geoterrain_samples
            if rw.GetMultiSamples() != want:
                rw.SetMultiSamples(want)
        return edges, "edges" if edges is not None else "msaa"

    def terrain_fraction(self) -> float:
        """Fraction of the last image's pixels covered by terrain (its depth buffer, read
        without rendering again)."""
        if self.mesh.n_cells == 0:
            return 0.0
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

        f = vtkWindowToImageFilter()
        f.SetInput(self.plotter.render_window)
        f.ShouldRerenderOff()
        f.ReadFrontBufferOff()
        f.SetInputBufferTypeToZBuffer()
        f.Update()
        z = vtk_to_numpy(f.GetOutput().GetPointData().GetScalars())
        return float((z < 1.0).mean())


class Prepared(NamedTuple):
    """What :meth:`TerrainScene.prepare` made for a picture: its ``view`` (with clipping
    planes), ``selection``, atlas ``vtex`` (None without per-view textures), ``started``
    (wall clock, process clock, io counters at its start) and ``read`` (the io counters
    at its end)."""

    view: View
    selection: lod.Selection
    vtex: object
    started: tuple
    read: dict


def store_snapshot(terrain: TerrainLike) -> AbstractContextManager:
    """``terrain``'s :meth:`~geoterrain.terrain.Terrain.snapshot` (one read transaction:
    the store's version read once, not at every blob), or nothing for a terrain without
    one.

    Examples
    --------
    >>> with store_snapshot(t):
    ...     sel = lod.select(t, default_view(t, (320, 240)))  # doctest: +SKIP
    """
    snap = getattr(terrain, "snapshot", None)
    return snap() if snap is not None else contextlib.nullcontext()


def _place(cam, position, focal_point, up) -> None:
    """Point ``cam`` (a VTK camera; PyVista's through its properties, which also mark it
    as set, so its plotter's first render keeps it) from ``position`` at ``focal_point``."""
    if hasattr(cam, "is_set"):  # a pyvista.Camera
        cam.position, cam.focal_point, cam.up = position, focal_point, up
        return
    cam.SetPosition(*position)
    cam.SetFocalPoint(*focal_point)
    cam.SetViewUp(*up)


def _image_data(img: np.ndarray):
    """A vtkImageData sharing (not copying) a C-contiguous (H, W, 3) uint8 ``img``, its
    row 0 at v = 0 (as :class:`geoterrain.rendering.tiletextures.ViewTexture` maps it); ``img``
    must stay unchanged while it is shown."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    h, w = img.shape[:2]
    out = vtkImageData()
    out.SetDimensions(w, h, 1)
    arr = numpy_to_vtk(np.ascontiguousarray(img).reshape(-1, 3), deep=False)
    arr.SetName("atlas")
    out.GetPointData().SetScalars(arr)
    return out


def io_counters(terrain: TerrainLike) -> dict:
    """The terrain's running counts of decoded tiles (by kind) and store bytes read."""
    return {"tiles_decoded": int(terrain.decoded_tiles),
            "normals_decoded": int(getattr(terrain, "decoded_normals", 0)),
            "bounds_decoded": int(getattr(terrain, "decoded_bounds", 0)),
            "bytes_read": int(getattr(terrain, "bytes_read", 0))}


def peak_rss() -> int:
    """Peak resident memory of this process in bytes (:func:`geoterrain.core.memory.peak_rss`)."""
    return _peak_rss()


# ---------------------------------------------------------------------- top level
def overview(terrain: TerrainLike, size: tuple[int, int] = (1280, 720), azimuth: float = 190.0,
             elevation: float = 40.0, distance: float | None = None, fov_y_deg: float = 30.0,
             *, shading: str = "normals", cmap: str | Palette = "auto",
             title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
             north_arrow: bool = True, vertical_exaggeration: float = 1.0) -> View:
    """:func:`default_view` framed into the rectangle the overlays leave free.

    The framing is of the terrain drawn with ``vertical_exaggeration``.

    Examples
    --------
    >>> v = overview(t, (640, 480), title="demo")
    >>> v.size
    (640, 480)
    """
    terrain = exaggerated(terrain, vertical_exaggeration)
    lay = layout_for(terrain, size, shading=shading, cmap=cmap, title=title,
                     colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
    return default_view(terrain, size, azimuth, elevation, distance, fov_y_deg,
                        fit_rect=lay.free)


def render_array(terrain: TerrainLike, view: View, *, pixel_error: float = 1.0,
                 strategy: str = DEFAULT,
                 shading: str = "normals", cmap: str | Palette = "auto", scene=None,
                 vertical_exaggeration: float = 1.0, light: Light | None = None,
                 drape: Drape | None = None, occlusion: bool = True, morph: bool | None = None,
                 anti_aliasing: str = "auto", strips: bool = False, lines: list | None = None,
                 line_widths: list | None = None, water: bool = True) -> tuple[np.ndarray, dict]:
    """The rendered image (H, W, 3) uint8 of ``view`` without overlays, and its stats
    (the arguments are :func:`render`'s; ``scene``: draw with this
    :class:`TerrainScene` rather than a new one, whose own settings then apply). ``lines``
    (scene polylines, (n, 3) each, heights as drawn) are drawn where the terrain shows
    them (:func:`geoterrain.rendering.overlays.draw_lines`).

    Examples
    --------
    >>> img, stats = render_array(t, default_view(t, (320, 240)))  # doctest: +SKIP
    >>> img.shape  # doctest: +SKIP
    (240, 320, 3)
    """
    strategy_info(strategy)
    own = scene is None
    if own:
        scene = TerrainScene(offscreen_plotter(view.size, anti_aliasing), terrain, shading, cmap,
                             vertical_exaggeration=vertical_exaggeration, light=light,
                             drape=drape, occlusion=occlusion, morph=morph, strips=strips,
                             water=water)
    try:
        img, stats = scene.frame(view, pixel_error, strategy)
        stats["terrain_fraction"] = round(scene.terrain_fraction(), 4)
        if lines:
            from geoterrain.rendering.antialias import depth_buffer
            from geoterrain.rendering.overlays import draw_lines

            seen = view if view.near is not None and view.far is not None \
                else view.clipped_to(*scene.terrain.scene_box())  # the frame's planes
            img = draw_lines(img, seen, lines, depth_buffer(scene.plotter),
                             widths=line_widths)
    finally:
        if own:
            scene.plotter.close()
    return img, stats


def render(terrain: TerrainLike, view: View | None, path: str | Path, *, pixel_error: float = 1.0,
           strategy: str = DEFAULT, shading: str = "normals", cmap: str | Palette = "auto",
           title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
           north_arrow: bool = True, stats_path: str | Path | None = None,
           vertical_exaggeration: float = 1.0, overwrite: bool = True,
           light: Light | None = None, drape: Drape | None = None, occlusion: bool = True,
           morph: bool | None = None, anti_aliasing: str = "auto",
           strips: bool = False, lines: list | None = None,
           line_widths: list | None = None, water: bool = True) -> dict:
    """Render one view of the terrain to a PNG, with its own level of detail.

    ``overwrite=False`` refuses an existing ``path`` or ``stats_path`` (checked before
    rendering).

    Parameters
    ----------
    terrain : Terrain
    view : View, or None for :func:`overview` at 1280×720.
    path : PNG file to write.
    pixel_error : τ, the screen-space error bound in pixels.
    strategy : a name from :data:`geoterrain.lod.STRATEGIES` (default ``rtin``).
    shading : ``"normals"`` (hillshade from full-resolution normal maps × elevation
        colours), ``"elevation"`` (colours only) or ``"plain"`` (geometric lighting).
    cmap : matplotlib colormap of elevations.
    title, colorbar, scale_bar, north_arrow : overlays.
    stats_path : also write the stats as JSON there.
    vertical_exaggeration : heights × N at view time (the stored ``z_scale`` is kept);
        the LOD bounds scale with it, and the scale bar's box says "VE ×N".
    light : a :class:`~geoterrain.rendering.shading.Light`: the sun's direction, a
        multidirectional hillshade, cast shadows and ambient occlusion (``"normals"``
        shading); None is the classic north-west sun at 45°.
    drape : a :class:`~geoterrain.rendering.drape.Drape`: a georeferenced image (any CRS) over
        the colour map, or blended with it; its nodata shows the colour map.
    occlusion, morph : the selection's horizon culling and geomorphing
        (:func:`geoterrain.lod.select`).
    anti_aliasing : ``"auto"`` (edges where the picture's silhouettes are sparse, else
        MSAA; MSAA with a water surface), ``"msaa"``, ``"edges"``, ``"fxaa"`` or
        ``"none"`` (:func:`pyvista_plotter`).
    strips : draw the mesh as seed 002's triangle strips (:mod:`geoterrain.lod.strips`)
        instead of triangle lists: the same picture; on VTK's software renderer no faster
        to draw (docs/benchmarks.md, "Editing a store, and triangle strips"), hence off by
        default.
    lines, line_widths : polylines in the scene frame of the stored terrain ((n, 3) each,
        such as contour lines; their heights are exaggerated with the terrain's) drawn
        where the terrain shows them, and their widths in pixels.
    water : draw a flat, lit, semi-transparent water surface where the palette has
        water (:mod:`geoterrain.rendering.water`).

    Returns
    -------
    dict
        Selection stats (triangles, vertices, tiles, select_ms, ...) plus update_ms,
        render_ms, frame_ms, terrain_fraction, size and path.

    Examples
    --------
    >>> from geoterrain.core.view import View
    >>> stats = render(t, View((0, -3000, 2000), (0, 0, 500)), "view.png")  # doctest: +SKIP
    >>> stats["triangles"] > 0  # doctest: +SKIP
    True
    """
    writable_target(Path(path), overwrite)
    if stats_path is not None:
        writable_target(Path(stats_path), overwrite, option="--stats")
    terrain = exaggerated(terrain, vertical_exaggeration)
    if view is None:
        view = overview(terrain, shading=shading, cmap=cmap, title=title, colorbar=colorbar,
                        scale_bar=scale_bar, north_arrow=north_arrow)
    if shading not in SHADINGS:
        raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
    if lines and vertical_exaggeration != 1.0:
        lines = [np.asarray(p, np.float64) * (1.0, 1.0, vertical_exaggeration) for p in lines]
    img, stats = render_array(terrain, view, pixel_error=pixel_error, strategy=strategy,
                              shading=shading, cmap=cmap, light=light, drape=drape,
                              occlusion=occlusion, morph=morph, anti_aliasing=anti_aliasing,
                              strips=strips, lines=lines, line_widths=line_widths,
                              water=water)
    img = compose(img, view, terrain, shading=shading, cmap=cmap, title=title,
                  colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
    write_png(path, img, overwrite)
    stats.update(size=[int(view.size[0]), int(view.size[1])], path=str(path),
                 shading=shading, look_from=list(view.look_from), look_at=list(view.look_at))
    if stats_path is not None:
        write_atomic(stats_path, json.dumps(stats, indent=2, default=float), overwrite)
    return stats

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

import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.atomicfiles import write_atomic
from geoterrain.core.view import View
from geoterrain.exaggerate import exaggerated
from geoterrain.exceptions import UsageError
from geoterrain.lod.mesh import TriMesh, polydata
from geoterrain.lod.registry import DEFAULT, strategy_info
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
from geoterrain.rendering.edgeaa import SPARSE_MAX_FACES, silhouette_edges, sparse
from geoterrain.rendering.overlays import compose, layout_for
from geoterrain.rendering.scene_camera import WATER_LIFT_PX, SceneCamera, _place  # noqa: F401
from geoterrain.rendering.scene_frames import (  # noqa: F401 - this module's names before the split
    Prepared,
    SceneFrames,
    io_counters,
    peak_rss,
    store_snapshot,
)
from geoterrain.rendering.scene_textures import SceneTextures, _image_data
from geoterrain.rendering.shading import Light
from geoterrain.rendering.textures import SHADINGS, texture_level
from geoterrain.rendering.tileshader import TileShader
from geoterrain.rendering.window import offscreen_plotter, writable_target, write_png

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

BACKGROUND = (0.86, 0.90, 0.95)  # a pale sky
PLAIN_COLOR = (0.80, 0.78, 0.72)
#: The terrain's faces turned away from the eye are culled by the renderer, not drawn
#: (module docstring, "Faces turned away").
BACKFACE_CULLING = True


# -------------------------------------------------------------------------- scene
class TerrainScene(SceneTextures, SceneCamera, SceneFrames):
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

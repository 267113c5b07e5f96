"""Offscreen rendering of LOD terrain: single views, orbits and fly-throughs.

Every frame selects its own level of detail for its own camera
(``Terrain.select``) and draws the mesh in the scene frame (float64 points,
origin at the DEM centre, so large CRS coordinates never reach the GPU).

Shading (``shading=``):

- ``"normals"`` (default): elevation colours × a hillshade baked into a texture
  from the stored *full-resolution* normal maps (``Terrain.tile_normals``) and the
  level-0 heights, mapped by texture coordinates from each vertex's ``grid_ij``.
  A coarse LOD mesh therefore shows the same relief and colours as the full DEM;
  only the silhouette moves. Chosen by measurement (rtin vs bruteforce render of
  the same view, same shading): on srtm1_japan at 1280×720, τ = 1 px gives
  40–46 dB with this texture vs 37–40 dB with geometric lighting; on a rough
  1025² fbm at 640×360, 33–41 dB vs 30–39 dB, and 22–32 dB for per-vertex
  colours from the same normal map (Gouraud loses the detail inside coarse
  triangles).
- ``"elevation"``: the elevation colours of the same texture, no shading.
- ``"plain"``: one colour lit by the renderer from the mesh's own geometry:
  what a naive renderer shows (useful to look at the mesh itself).

Examples
--------
>>> import geoterrain
>>> from geoterrain.rendering import render, default_view
>>> t = geoterrain.open("dem.geoterrain")  # doctest: +SKIP
>>> stats = render(t, default_view(t), "view.png", title="My DEM")  # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from geoterrain import lod
from geoterrain.cameras import (  # noqa: F401 - the camera helpers are part of this API
    default_view,
    interpolate_views,
    load_cameras,
    orbit_views,
    project,
    terrain_bounds,
    to_scene,
)
from geoterrain.colours import Palette
from geoterrain.exaggerate import exaggerated
from geoterrain.exceptions import UsageError, WriteError, exists_error
from geoterrain.lod.registry import DEFAULT, strategy_info
from geoterrain.overlays import compose, layout_for
from geoterrain.store import partial_path, publish, remove_stale_partials, write_atomic
from geoterrain.textures import SHADINGS, texture_image, texture_level
from geoterrain.view import View

BACKGROUND = (0.86, 0.90, 0.95)  # a pale sky
PLAIN_COLOR = (0.80, 0.78, 0.72)

Progress = Callable[[int, int], None]


def _prefer_egl() -> None:
    """Use the EGL (headless) OpenGL window when there is no display, before VTK makes one."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
            and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


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

    def __init__(self, plotter, terrain, shading: str = "normals", cmap: str | Palette = "auto",
                 background: Sequence[float] = BACKGROUND, vertical_exaggeration: float = 1.0):
        import pyvista as pv

        terrain = exaggerated(terrain, vertical_exaggeration)

        if shading not in SHADINGS:
            raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
        self.plotter, self.terrain, self.shading, self.cmap = plotter, terrain, shading, cmap
        plotter.set_background(background)
        plotter.theme.allow_empty_mesh = True  # a view may see no terrain at all
        self.level = texture_level(terrain)
        self.texture = None
        if shading != "plain":
            tex = pv.Texture(texture_image(terrain, shading, cmap, self.level))
            tex.interpolate = True
            tex.mipmap = True
            tex.repeat = False
            self.texture = tex
        self.mesh = pv.PolyData()
        self.actor = None
        self.selection = None

    def _tcoords(self, ij: np.ndarray) -> np.ndarray:
        S = self.terrain.grid.level_size(self.level)
        s = float(1 << self.level)
        tc = np.empty((len(ij), 2), np.float32)
        tc[:, 0] = (ij[:, 1] / s + 0.5) / S
        tc[:, 1] = 1.0 - (ij[:, 0] / s + 0.5) / S
        return tc

    def update(self, selection) -> None:
        """Show ``selection.mesh`` (the actor and its texture are reused)."""
        import pyvista as pv

        src = selection.mesh
        mesh = pv.PolyData()
        if src.n_points:
            mesh.points = src.points
            if src.n_cells:
                mesh.faces = src.faces
            if self.texture is not None:
                mesh.active_texture_coordinates = self._tcoords(
                    np.asarray(src.point_data["grid_ij"]))
            for k in ("level", "skirt"):
                if k in src.cell_data:
                    mesh.cell_data[k] = src.cell_data[k]
        self.selection = selection
        if self.actor is None:
            kw: dict = {"name": "terrain", "show_scalar_bar": False, "reset_camera": False}
            if self.texture is not None:
                self.actor = self.plotter.add_mesh(mesh, color="white", lighting=False, **kw)
                self.actor.SetTexture(self.texture)
            else:
                self.actor = self.plotter.add_mesh(mesh, color=PLAIN_COLOR, lighting=True,
                                                   smooth_shading=False, **kw)
            self.actor.mapper.ScalarVisibilityOff()  # colours come from the texture
        else:
            self.actor.mapper.SetInputData(mesh)
        self.mesh = mesh

    def set_camera(self, view: View) -> None:
        """Point the plotter's camera like ``view`` (and fit the clipping range).

        VTK gets the view's own orthonormal up (``View.basis``), never a view-up it
        would have to re-orthogonalise: the picture, the frustum the LOD culls with
        and :func:`project` are one camera, straight down included.
        """
        cam = self.plotter.camera
        _, u, _ = view.basis()
        cam.position, cam.focal_point, cam.up = view.look_from, view.look_at, tuple(u)
        cam.view_angle = view.fov_y_deg
        self.plotter.renderer.ResetCameraClippingRange()
        if view.near is not None and view.far is not None:
            cam.clipping_range = (view.near, view.far)

    def frame(self, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT,
              ) -> tuple[np.ndarray, dict]:
        """Select the LOD for ``view``, draw it and return the image (H, W, 3) uint8 and stats."""
        t0 = time.perf_counter()
        sel = lod.select(self.terrain, view, pixel_error=pixel_error, strategy=strategy)
        t1 = time.perf_counter()
        self.update(sel)
        self.set_camera(view)
        t2 = time.perf_counter()
        self.plotter.render()
        img = np.asarray(self.plotter.screenshot(return_img=True))[..., :3]
        t3 = time.perf_counter()
        stats = {**sel.stats, "update_ms": round((t2 - t1) * 1e3, 3),
                 "render_ms": round((t3 - t2) * 1e3, 3),
                 "frame_ms": round((t3 - t0) * 1e3, 3)}
        return img, stats

    def terrain_fraction(self) -> float:
        """Fraction of the last image's pixels covered by terrain (from the depth buffer)."""
        if self.mesh.n_cells == 0:
            return 0.0
        depth = self.plotter.get_image_depth(fill_value=np.nan)
        return float(np.isfinite(depth).mean())


def _plotter(size: tuple[int, int], anti_aliasing: bool = True):
    """An offscreen plotter (EGL when there is no display); MSAA unless turned off."""
    _prefer_egl()
    import pyvista as pv

    p = pv.Plotter(off_screen=True, window_size=list(size))
    if not anti_aliasing:
        p.disable_anti_aliasing()
    return p


# ---------------------------------------------------------------------- top level
MAX_FRAMES = 100_000  # an animation longer than this is a mistake (about 3 h at 10 fps)
ANIMATION_SUFFIXES = (".gif", ".mp4")


def _writable_target(path: Path, overwrite: bool) -> None:
    """Refuse an existing ``path`` without ``overwrite``, or a missing parent folder."""
    if path.exists() and not overwrite:
        raise exists_error(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"{parent}: no such directory; create it first or choose another "
                         "output path", cli=f"{parent}: no such directory; create it first or "
                         "choose another -o path")


def _write_png(path: str | Path, img: np.ndarray, overwrite: bool = True) -> None:
    """Write a PNG to a hidden partial file, then publish it (never a half-written PNG)."""
    import imageio.v3 as iio

    path = Path(path)
    _writable_target(path, overwrite)
    remove_stale_partials(path.parent)
    tmp = partial_path(path)
    try:
        iio.imwrite(tmp, img, extension=".png")
        publish(tmp, path, overwrite)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise WriteError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def overview(terrain, size: tuple[int, int] = (1280, 720), azimuth: float = 190.0,
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


def render_array(terrain, view: View, *, pixel_error: float = 1.0, strategy: str = DEFAULT,
                 shading: str = "normals", cmap: str | Palette = "auto", scene=None,
                 vertical_exaggeration: float = 1.0) -> tuple[np.ndarray, dict]:
    """The rendered image (H, W, 3) uint8 of ``view`` without overlays, and its stats.

    Examples
    --------
    >>> img, stats = render_array(t, default_view(t, (320, 240)))  # doctest: +SKIP
    >>> img.shape  # doctest: +SKIP
    (240, 320, 3)
    """
    strategy_info(strategy)
    own = scene is None
    if own:
        scene = TerrainScene(_plotter(view.size), terrain, shading, cmap,
                             vertical_exaggeration=vertical_exaggeration)
    try:
        img, stats = scene.frame(view, pixel_error, strategy)
        stats["terrain_fraction"] = round(scene.terrain_fraction(), 4)
    finally:
        if own:
            scene.plotter.close()
    return img, stats


def render(terrain, view: View | None, path: str | Path, *, pixel_error: float = 1.0,
           strategy: str = DEFAULT, shading: str = "normals", cmap: str | Palette = "auto",
           title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
           north_arrow: bool = True, stats_path: str | Path | None = None,
           vertical_exaggeration: float = 1.0, overwrite: bool = True) -> dict:
    """Render one view of the terrain to a PNG, with its own level of detail.

    ``overwrite=False`` refuses an existing ``path`` (checked before rendering).

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

    Returns
    -------
    dict
        Selection stats (triangles, vertices, tiles, select_ms, ...) plus update_ms,
        render_ms, frame_ms, terrain_fraction, size and path.

    Examples
    --------
    >>> from geoterrain.view import View
    >>> stats = render(t, View((0, -3000, 2000), (0, 0, 500)), "view.png")  # doctest: +SKIP
    >>> stats["triangles"] > 0  # doctest: +SKIP
    True
    """
    _writable_target(Path(path), overwrite)
    terrain = exaggerated(terrain, vertical_exaggeration)
    if view is None:
        view = overview(terrain, shading=shading, cmap=cmap, title=title, colorbar=colorbar,
                        scale_bar=scale_bar, north_arrow=north_arrow)
    if shading not in SHADINGS:
        raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
    img, stats = render_array(terrain, view, pixel_error=pixel_error, strategy=strategy,
                              shading=shading, cmap=cmap)
    img = compose(img, view, terrain, shading=shading, cmap=cmap, title=title,
                  colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
    _write_png(path, img, overwrite)
    stats.update(size=[int(view.size[0]), int(view.size[1])], path=str(path),
                 shading=shading, look_from=list(view.look_from), look_at=list(view.look_at))
    if stats_path is not None:
        write_atomic(stats_path, json.dumps(stats, indent=2, default=float))  # never half
    return stats


def check_animation_output(out: str | Path, fps: float, overwrite: bool = True) -> None:
    """Refuse a bad animation target before any frame is rendered.

    ``out`` is a .gif, a .mp4, or a folder (no suffix) of PNG frames; ``fps``
    a finite number in (0, 1000].

    Examples
    --------
    >>> try:
    ...     check_animation_output("fly.webm", 10)
    ... except UsageError as e:
    ...     print(str(e).split(";")[0])
    fly.webm: unknown animation format '.webm'
    """
    out = Path(out)
    ext = out.suffix.lower()
    if ext and ext not in ANIMATION_SUFFIXES and not out.is_dir():
        raise UsageError(f"{out}: unknown animation format {ext!r}; use .gif, .mp4 or a folder "
                         "name without a suffix (PNG frames)")
    if not (isinstance(fps, int | float) and math.isfinite(fps) and 0 < fps <= 1000):
        raise UsageError(f"fps must be a number in (0, 1000], got {fps}",
                         cli=f"--fps must be a number in (0, 1000], got {fps}")
    _writable_target(out, overwrite)


def _animation_writer(out: str | Path, fps: float, overwrite: bool = True):
    """(append(frame), close(), publish()) writing a .gif, .mp4 or PNG folder to a partial.

    ``close`` finishes the partial; ``publish`` then moves it into place. Until
    then nothing appears at ``out``, and an error leaves nothing behind.
    """
    out = Path(out)
    check_animation_output(out, fps, overwrite)
    ext = out.suffix.lower()
    remove_stale_partials(out.parent if str(out.parent) else Path("."))
    tmp = partial_path(out)
    if ext in ANIMATION_SUFFIXES:
        import imageio.v2 as iio2

        tmp = tmp.with_name(tmp.name + ext)  # the writer picks its format by suffix
        if ext == ".mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError:
                raise UsageError("writing .mp4 needs the imageio-ffmpeg package "
                                 "(pip install imageio-ffmpeg); or use -o frames.gif") from None
            w = iio2.get_writer(tmp, fps=fps, macro_block_size=1)
            return w.append_data, w.close, lambda: publish(tmp, out, overwrite), tmp
        from geoterrain.gifstream import GifStream  # frame by frame: memory flat in frames

        g = GifStream(tmp, fps)
        return g.append, g.close, lambda: publish(tmp, out, overwrite), tmp
    tmp.mkdir()
    counter = iter(range(MAX_FRAMES))

    def append(img):
        _write_png(tmp / f"frame_{next(counter):05d}.png", img)

    return append, lambda: None, lambda: publish(tmp, out, overwrite), tmp


def animate(terrain, views: Sequence[View], out: str | Path, *, pixel_error: float = 1.0,
            strategy: str = DEFAULT, shading: str = "normals", cmap: str | Palette = "auto",
            title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
            north_arrow: bool = True, fps: float = 10.0, progress: Progress | None = None,
            vertical_exaggeration: float = 1.0, overwrite: bool = True) -> list[dict]:
    """Render each view (each with its own LOD selection) into a GIF, MP4 or PNG folder.

    Returns the per-frame stats. The output is written to a hidden partial and
    moved into place only when every frame is done; ``overwrite=False`` refuses
    an existing ``out``.

    Examples
    --------
    >>> stats = animate(t, orbit_views(t, 12), "orbit.gif")  # doctest: +SKIP
    """
    strategy_info(strategy)
    if not views:
        raise UsageError("no views to render")
    if len(views) > MAX_FRAMES:
        raise UsageError(f"{len(views)} frames is more than the {MAX_FRAMES} an animation may "
                         "have; use fewer cameras or orbit frames")
    size = views[0].size
    if any(v.size != size for v in views):
        raise UsageError("every frame of an animation must have the same size")
    terrain = exaggerated(terrain, vertical_exaggeration)
    append, close, done, tmp = _animation_writer(out, fps, overwrite)
    all_stats = []
    ok = False
    try:
        scene = TerrainScene(_plotter(size), terrain, shading, cmap)
        try:
            for k, v in enumerate(views):
                img, st = scene.frame(v, pixel_error, strategy)
                img = compose(img, v, terrain, shading=shading, cmap=cmap, title=title,
                              colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
                append(img)
                all_stats.append(st)
                if progress is not None:
                    progress(k + 1, len(views))
        finally:
            scene.plotter.close()
        close()
        done()
        ok = True
    finally:
        if not ok:  # an error at any frame leaves nothing that looks like a result
            try:
                close()
            except Exception:  # noqa: BLE001 - the writer of a failed run
                pass
            if tmp.is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                tmp.unlink(missing_ok=True)
    return all_stats


def orbit(terrain, out: str | Path, n_frames: int = 36, *, size: tuple[int, int] = (1280, 720),
          azimuth: float = 190.0, elevation: float = 40.0, distance: float | None = None,
          fov_y_deg: float = 30.0, **kw) -> list[dict]:
    """A full turn around the terrain centre, ``n_frames`` frames, to a .gif/.mp4/folder.

    Every frame selects the LOD for its own camera. Keyword arguments go to
    :func:`animate` (pixel_error, strategy, shading, fps, progress, ...).

    Examples
    --------
    >>> stats = orbit(t, "orbit.gif", 24, size=(640, 360))  # doctest: +SKIP
    >>> len(stats)  # doctest: +SKIP
    24
    """
    terrain = exaggerated(terrain, kw.pop("vertical_exaggeration", 1.0))
    lay = layout_for(terrain, size, shading=kw.get("shading", "normals"),
                     cmap=kw.get("cmap", "auto"), title=kw.get("title"),
                     colorbar=kw.get("colorbar", True), scale_bar=kw.get("scale_bar", True),
                     north_arrow=kw.get("north_arrow", True))
    views = orbit_views(terrain, n_frames, size, azimuth, elevation, distance, fov_y_deg,
                        fit_rect=lay.free)
    return animate(terrain, views, out, **kw)


def flythrough(terrain, cameras_json: str | Path, out: str | Path, *,
               size: tuple[int, int] = (1280, 720), fov_y_deg: float = 30.0,
               frames_between: int = 0, **kw) -> list[dict]:
    """Fly along the cameras of a JSON file (see :func:`load_cameras`).

    The cameras are keyframes: ``frames_between`` eased frames on a smooth spline
    go between each pair (:func:`interpolate_views`). Every frame selects the LOD
    for its own camera. Keyword arguments go to :func:`animate`.

    Examples
    --------
    >>> stats = flythrough(t, "cameras.json", "fly.gif", progress=print)  # doctest: +SKIP
    """
    terrain = exaggerated(terrain, kw.pop("vertical_exaggeration", 1.0))
    views = interpolate_views(load_cameras(terrain, cameras_json, size, fov_y_deg),
                              frames_between)
    return animate(terrain, views, out, **kw)

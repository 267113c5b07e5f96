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
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from geoterrain.exceptions import UsageError
from geoterrain.view import View, load_views

SHADINGS = ("normals", "elevation", "plain")
BACKGROUND = (0.86, 0.90, 0.95)  # a pale sky
PLAIN_COLOR = (0.80, 0.78, 0.72)
SUN_AZIMUTH = 315.0  # degrees clockwise from north: light from the north-west (cartography)
SUN_ALTITUDE = 45.0
AMBIENT = 0.35
MAX_TEXTURE = 8193  # samples per side; a larger DEM's texture comes from a coarser level

Progress = Callable[[int, int], None]


def _prefer_egl() -> None:
    """Use the EGL (headless) OpenGL window when there is no display, before VTK makes one."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
            and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


# --------------------------------------------------------------------------- views
def terrain_bounds(terrain) -> tuple[np.ndarray, np.ndarray]:
    """Scene-frame box (lo, hi) of the terrain's valid data, from the top tile's bounds."""
    g = terrain.grid
    info = terrain.tile_info[(g.top_level, 0, 0)]
    z0, z1 = info["zmin"], info["zmax"]
    z0 = 0.0 if z0 is None or not np.isfinite(z0) else z0
    z1 = z0 if z1 is None or not np.isfinite(z1) else z1
    lo = np.array([info["xmin"], info["ymin"], z0], np.float64)
    hi = np.array([info["xmax"], info["ymax"], z1], np.float64)
    return lo, hi


def default_view(terrain, size: tuple[int, int] = (1280, 720), azimuth: float = 190.0,
                 elevation: float = 40.0, distance: float | None = None,
                 fov_y_deg: float = 30.0, look_at: Sequence[float] | None = None) -> View:
    """An oblique overview of the whole terrain.

    Parameters
    ----------
    terrain : Terrain
    size : (width, height) in pixels.
    azimuth : compass bearing of the camera *from* the target, degrees clockwise from
        north (190: from just west of south, looking north).
    elevation : angle of the camera above the horizon at the target, degrees.
    distance : eye–target distance in metres; default: the whole terrain fits the frame.
    fov_y_deg : vertical field of view.
    look_at : target point (scene frame); default: the centre of the terrain's box.

    Returns
    -------
    View

    Examples
    --------
    >>> v = default_view(t, (800, 600), azimuth=180, elevation=30)  # doctest: +SKIP
    >>> v.look_at  # doctest: +SKIP
    (0.0, 0.0, 812.5)
    """
    lo, hi = terrain_bounds(terrain)
    c = 0.5 * (lo + hi) if look_at is None else np.asarray(look_at, np.float64)
    if look_at is None:
        c[2] = lo[2] + 0.35 * (hi[2] - lo[2])
    az, el = math.radians(azimuth), math.radians(elevation)
    d = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    if distance is None:
        radius = max(float(np.linalg.norm(0.5 * (hi - lo))), 1e-6)
        ty = math.tan(math.radians(fov_y_deg) / 2)
        distance = radius / math.sin(math.atan(min(ty, ty * size[0] / size[1])))
        # shrink to the projected box of the data (a few perspective iterations)
        corners = _coarse_points(terrain)
        for _ in range(4):
            v = View(tuple(c + distance * d), tuple(c), (0.0, 0.0, 1.0), fov_y_deg, tuple(size))
            px, depth = project(v, corners)
            if np.any(depth <= 0):
                break
            f = max(np.abs(px[:, 0] - size[0] / 2).max() / (size[0] / 2),
                    np.abs(px[:, 1] - size[1] / 2).max() / (size[1] / 2))
            distance *= f / 0.94
    eye = c + distance * d
    return View(tuple(eye), tuple(c), (0.0, 0.0, 1.0), fov_y_deg, tuple(size))


def _coarse_points(terrain) -> np.ndarray:
    """Scene positions of the valid samples of the top pyramid tile (the terrain's shape)."""
    g = terrain.grid
    L = g.top_level
    h = terrain.tile(L, 0, 0).heights
    ii, jj = np.meshgrid(g.tile_rows(L, 0), g.tile_cols(L, 0), indexing="ij")
    ok = np.isfinite(h)
    X, Y = terrain.frame.xy(ii[ok], jj[ok])
    return np.stack([X, Y, terrain.frame.z(h[ok])], 1)


def orbit_views(terrain, n_frames: int, size: tuple[int, int] = (1280, 720),
                azimuth: float = 190.0, elevation: float = 40.0,
                distance: float | None = None, fov_y_deg: float = 30.0) -> list[View]:
    """``n_frames`` views evenly spaced on a full turn around the terrain centre.

    Examples
    --------
    >>> len(orbit_views(t, 8))  # doctest: +SKIP
    8
    """
    if n_frames < 1:
        raise UsageError(f"an orbit needs at least 1 frame, got {n_frames}")
    return [default_view(terrain, size, azimuth + 360.0 * k / n_frames, elevation, distance,
                         fov_y_deg) for k in range(n_frames)]


def load_cameras(terrain, path: str | Path, size: tuple[int, int] = (1280, 720),
                 fov_y_deg: float = 30.0) -> list[View]:
    """Views from a cameras JSON file, CRS cameras placed in ``terrain``'s frame.

    See :func:`geoterrain.view.load_views` for the format.

    Examples
    --------
    >>> views = load_cameras(t, "cameras.json")  # doctest: +SKIP
    """
    return load_views(path, size, fov_y_deg, terrain.frame)


def to_scene(terrain, p: Sequence[float]) -> np.ndarray:
    """Source-CRS (x, y, height in metres) → scene frame (z-scale applied)."""
    return np.array(terrain.frame.crs_point_to_scene(p))


def project(view: View, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (x right, y down) and depth of scene points seen by ``view``."""
    r, u, f = view.basis()
    d = np.atleast_2d(pts) - view.eye
    z = d @ f
    lam = view.lam
    x = view.size[0] / 2 + lam * (d @ r) / z
    y = view.size[1] / 2 - lam * (d @ u) / z
    return np.stack([x, y], -1), z


# ------------------------------------------------------------------------ texture
def _hillshade(normals: np.ndarray) -> np.ndarray:
    az, alt = math.radians(SUN_AZIMUTH), math.radians(SUN_ALTITUDE)
    light = np.array([math.sin(az) * math.cos(alt), math.cos(az) * math.cos(alt),
                      math.sin(alt)], np.float32)
    lam = np.clip(normals @ light, 0.0, 1.0) / light[2]  # flat ground: 1
    return np.minimum(AMBIENT + (1.0 - AMBIENT) * lam, 1.25)


def texture_level(terrain, max_size: int = MAX_TEXTURE) -> int:
    """The finest pyramid level whose grid fits a ``max_size`` texture."""
    g = terrain.grid
    for L in g.levels:
        if g.level_size(L) <= max_size:
            return L
    return g.top_level


def elevation_range(terrain) -> tuple[float, float]:
    """(min, max) elevation in metres (no vertical exaggeration) of the valid data."""
    lo, hi = terrain_bounds(terrain)
    zs = terrain.frame.z_scale or 1.0
    a, b = float(lo[2] / zs), float(hi[2] / zs)
    return (a, b) if b > a else (a - 0.5, a + 0.5)


def build_texture_image(terrain, shading: str, cmap: str = "gist_earth",
                        level: int | None = None) -> np.ndarray:
    """RGB uint8 image (S, S, 3) of the level-L grid: elevation colour × hillshade.

    Hillshade from the stored normal maps of level L (computed from the
    full-resolution geometry), colours from the level's heights. Row 0 is grid row 0.

    Examples
    --------
    >>> img = build_texture_image(t, "normals")  # doctest: +SKIP
    """
    import matplotlib

    g = terrain.grid
    L = texture_level(terrain) if level is None else level
    S, T, step = g.level_size(L), g.tile_samples, 1 << g.t
    shade = np.ones((S, S), np.float32)
    h = np.zeros((S, S), np.float64)
    for (lv, x, y) in terrain.tile_info:
        if lv != L:
            continue
        sl = (slice(y * step, y * step + T), slice(x * step, x * step + T))
        if shading == "normals":
            shade[sl] = _hillshade(terrain.tile_normals(lv, x, y))
        h[sl] = np.nan_to_num(terrain.tile(lv, x, y).heights, nan=0.0)
    z0, z1 = elevation_range(terrain)
    zm = terrain.frame.z_to_m
    rgb = matplotlib.colormaps[cmap](np.clip((h * zm - z0) / (z1 - z0), 0, 1),
                                     bytes=False)[..., :3].astype(np.float32)
    rgb *= shade[..., None]
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


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

    def __init__(self, plotter, terrain, shading: str = "normals", cmap: str = "gist_earth",
                 background: Sequence[float] = BACKGROUND):
        import pyvista as pv

        if shading not in SHADINGS:
            raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
        self.plotter, self.terrain, self.shading, self.cmap = plotter, terrain, shading, cmap
        plotter.set_background(background)
        plotter.theme.allow_empty_mesh = True  # a view may see no terrain at all
        self.level = texture_level(terrain)
        self.texture = None
        if shading != "plain":
            cache = terrain.__dict__.setdefault("_render_textures", {})
            key = (shading, cmap, self.level)
            if key not in cache:
                cache[key] = build_texture_image(terrain, shading, cmap, self.level)
            tex = pv.Texture(cache[key])
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
        """Point the plotter's camera like ``view`` (and fit the clipping range)."""
        cam = self.plotter.camera
        cam.position, cam.focal_point, cam.up = view.look_from, view.look_at, view.up
        cam.view_angle = view.fov_y_deg
        self.plotter.renderer.ResetCameraClippingRange()
        if view.near is not None and view.far is not None:
            cam.clipping_range = (view.near, view.far)

    def frame(self, view: View, pixel_error: float = 1.0, strategy: str = "rtin",
              ) -> tuple[np.ndarray, dict]:
        """Select the LOD for ``view``, draw it and return the image (H, W, 3) uint8 and stats."""
        t0 = time.perf_counter()
        sel = self.terrain.select(view, pixel_error=pixel_error, strategy=strategy)
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


# ---------------------------------------------------------------------- overlays
def _nice(x: float) -> float:
    e = 10 ** math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * e <= x:
            return m * e
    return e


def _fmt_len(m: float) -> str:
    return f"{m / 1000:g} km" if m >= 1000 else f"{m:g} m"


def compose(img: np.ndarray, view: View, terrain, *, shading: str = "normals",
            cmap: str = "gist_earth", title: str | None = None, colorbar: bool = True,
            scale_bar: bool = True, north_arrow: bool = True) -> np.ndarray:
    """Draw the title, colour bar, scale bar and north arrow over a rendered image.

    Examples
    --------
    >>> out = compose(img, view, t, title="Fuji")  # doctest: +SKIP
    """
    if not (title or (colorbar and shading != "plain") or scale_bar or north_arrow):
        return img
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    H, W = img.shape[:2]
    dpi = 100.0
    fig = Figure(figsize=(W / dpi, H / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(img, interpolation="nearest")
    ax.set_xlim(-0.5, W - 0.5)
    ax.set_ylim(H - 0.5, -0.5)
    ax.axis("off")
    fs = max(7.0, min(W, H) / 55)
    box = dict(boxstyle="round,pad=0.3", fc="white", ec="0.6", alpha=0.8)
    if title:
        ax.text(W / 2, 0.03 * H, title, ha="center", va="top", fontsize=1.4 * fs,
                weight="bold", bbox=box)
    if colorbar and shading != "plain":
        z0, z1 = elevation_range(terrain)
        cax = fig.add_axes((0.93, 0.2, 0.018, 0.6))
        norm = matplotlib.colors.Normalize(z0, z1)
        cb = fig.colorbar(matplotlib.cm.ScalarMappable(norm, matplotlib.colormaps[cmap]),
                          cax=cax)
        cb.set_label("elevation (m)", fontsize=fs)
        cb.ax.tick_params(labelsize=0.85 * fs)
        cb.ax.yaxis.set_ticks_position("left")
        cb.ax.yaxis.set_label_position("left")
    target = np.asarray(view.look_at, np.float64)
    r, _, f = view.basis()
    if scale_bar:
        # a horizontal segment through the target, across the view: metres per pixel there
        rh = np.array([r[0], r[1], 0.0])
        if np.linalg.norm(rh) > 1e-9:
            rh /= np.linalg.norm(rh)
            dist = float(np.linalg.norm(target - view.eye))
            m_per_px = max(dist / view.lam, 1e-12)
            length = _nice(0.2 * W * m_per_px)
            (a, b), _ = project(view, np.stack([target, target + length * rh]))
            px = float(np.linalg.norm(b - a))
            if np.isfinite(px) and 4 < px < W:
                x0, y0 = 0.04 * W, 0.93 * H
                ax.add_patch(matplotlib.patches.FancyBboxPatch(
                    (x0 - 8, y0 - 2.6 * fs), px + 16, 3.4 * fs,
                    boxstyle="round,pad=2", fc="white", ec="0.6", alpha=0.8))
                ax.plot([x0, x0 + px], [y0, y0], color="black", lw=3, solid_capstyle="butt")
                ax.plot([x0, x0], [y0 - 5, y0 + 5], color="black", lw=1.5)
                ax.plot([x0 + px, x0 + px], [y0 - 5, y0 + 5], color="black", lw=1.5)
                ax.text(x0 + px / 2, y0 - 6, f"{_fmt_len(length)} at view centre",
                        ha="center", va="bottom", fontsize=0.85 * fs)
    if north_arrow:
        (a, b), z = project(view, np.stack([target, target + np.array([0, 1.0, 0]) *
                                            max(1e-3, 0.05 * np.linalg.norm(target - view.eye))]))
        d = b - a
        if np.all(z > 0) and np.linalg.norm(d) > 1e-6:
            d = d / np.linalg.norm(d)
            c = np.array([0.07 * W, 0.1 * H + 2 * fs])
            L = 2.6 * fs
            ax.add_patch(matplotlib.patches.Circle(c, 1.6 * L, fc="white", ec="0.6", alpha=0.8))
            ax.annotate("", xy=c + L * d, xytext=c - L * d,
                        arrowprops=dict(arrowstyle="-|>", lw=2, color="black",
                                        mutation_scale=2 * fs))
            ax.text(*(c + 1.35 * L * d), "N", ha="center", va="center", fontsize=fs,
                    weight="bold")
    fig.canvas.draw()
    out = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    return out


# ---------------------------------------------------------------------- top level
def _check_strategy(strategy: str) -> None:
    from geoterrain.lod import STRATEGIES

    if strategy not in STRATEGIES:
        raise UsageError(f"unknown strategy {strategy!r}; use one of {', '.join(STRATEGIES)}")


def _write_png(path: str | Path, img: np.ndarray) -> None:
    import imageio.v3 as iio

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, img)


def render_array(terrain, view: View, *, pixel_error: float = 1.0, strategy: str = "rtin",
                 shading: str = "normals", cmap: str = "gist_earth", scene=None
                 ) -> tuple[np.ndarray, dict]:
    """The rendered image (H, W, 3) uint8 of ``view`` without overlays, and its stats.

    Examples
    --------
    >>> img, stats = render_array(t, default_view(t, (320, 240)))  # doctest: +SKIP
    >>> img.shape  # doctest: +SKIP
    (240, 320, 3)
    """
    _check_strategy(strategy)
    own = scene is None
    if own:
        scene = TerrainScene(_plotter(view.size), terrain, shading, cmap)
    try:
        img, stats = scene.frame(view, pixel_error, strategy)
        stats["terrain_fraction"] = round(scene.terrain_fraction(), 4)
    finally:
        if own:
            scene.plotter.close()
    return img, stats


def render(terrain, view: View | None, path: str | Path, *, pixel_error: float = 1.0,
           strategy: str = "rtin", shading: str = "normals", cmap: str = "gist_earth",
           title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
           north_arrow: bool = True, stats_path: str | Path | None = None) -> dict:
    """Render one view of the terrain to a PNG, with its own level of detail.

    Parameters
    ----------
    terrain : Terrain
    view : View, or None for :func:`default_view` at 1280×720.
    path : PNG file to write.
    pixel_error : τ, the screen-space error bound in pixels.
    strategy : ``"rtin"``, ``"chunked"`` or ``"bruteforce"``.
    shading : ``"normals"`` (hillshade from full-resolution normal maps × elevation
        colours), ``"elevation"`` (colours only) or ``"plain"`` (geometric lighting).
    cmap : matplotlib colormap of elevations.
    title, colorbar, scale_bar, north_arrow : overlays.
    stats_path : also write the stats as JSON there.

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
    if view is None:
        view = default_view(terrain)
    if shading not in SHADINGS:
        raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
    img, stats = render_array(terrain, view, pixel_error=pixel_error, strategy=strategy,
                              shading=shading, cmap=cmap)
    img = compose(img, view, terrain, shading=shading, cmap=cmap, title=title,
                  colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
    _write_png(path, img)
    stats.update(size=[int(view.size[0]), int(view.size[1])], path=str(path),
                 shading=shading, look_from=list(view.look_from), look_at=list(view.look_at))
    if stats_path is not None:
        Path(stats_path).write_text(json.dumps(stats, indent=2, default=float))
    return stats


def _animation_writer(out: str | Path, fps: float):
    """(append(frame), close()) for a .gif, .mp4 or a directory of PNG frames."""
    out = Path(out)
    ext = out.suffix.lower()
    if ext in (".gif", ".mp4"):
        import imageio.v2 as iio2

        if ext == ".mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError:
                raise UsageError("writing .mp4 needs the imageio-ffmpeg package "
                                 "(pip install imageio-ffmpeg); or use -o frames.gif") from None
            w = iio2.get_writer(out, fps=fps, macro_block_size=1)
        else:
            w = iio2.get_writer(out, mode="I", duration=1000.0 / fps, loop=0)
        return w.append_data, w.close
    if ext == ".png":
        raise UsageError(f"{out}: an animation goes to a .gif, a .mp4 or a directory")
    out.mkdir(parents=True, exist_ok=True)
    counter = iter(range(10**9))

    def append(img):
        _write_png(out / f"frame_{next(counter):05d}.png", img)

    return append, lambda: None


def animate(terrain, views: Sequence[View], out: str | Path, *, pixel_error: float = 1.0,
            strategy: str = "rtin", shading: str = "normals", cmap: str = "gist_earth",
            title: str | None = None, colorbar: bool = True, scale_bar: bool = False,
            north_arrow: bool = True, fps: float = 10.0, progress: Progress | None = None
            ) -> list[dict]:
    """Render each view (each with its own LOD selection) into a GIF, MP4 or PNG folder.

    Returns the per-frame stats.

    Examples
    --------
    >>> stats = animate(t, orbit_views(t, 12), "orbit.gif")  # doctest: +SKIP
    """
    _check_strategy(strategy)
    if not views:
        raise UsageError("no views to render")
    size = views[0].size
    if any(v.size != size for v in views):
        raise UsageError("every frame of an animation must have the same size")
    append, close = _animation_writer(out, fps)
    scene = TerrainScene(_plotter(size), terrain, shading, cmap)
    all_stats = []
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
        close()
        scene.plotter.close()
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
    views = orbit_views(terrain, n_frames, size, azimuth, elevation, distance, fov_y_deg)
    return animate(terrain, views, out, **kw)


def flythrough(terrain, cameras_json: str | Path, out: str | Path, *,
               size: tuple[int, int] = (1280, 720), fov_y_deg: float = 30.0, **kw
               ) -> list[dict]:
    """Fly along the cameras of a JSON file (see :func:`load_cameras`), one frame each.

    Every frame selects the LOD for its own camera. Keyword arguments go to
    :func:`animate`.

    Examples
    --------
    >>> stats = flythrough(t, "cameras.json", "fly.gif", progress=print)  # doctest: +SKIP
    """
    views = load_cameras(terrain, cameras_json, size, fov_y_deg)
    return animate(terrain, views, out, **kw)

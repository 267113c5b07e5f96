"""Offscreen pictures of a :class:`~geoterrain.globe.Globe`, drawn relative to the eye.

The frame's mesh (:meth:`Globe.select`) is float32 relative to the camera (the floating
origin of :mod:`geoterrain.globe.cdlod`), so VTK's camera sits at the origin and looks
along the view's direction: no float32 world coordinate of 6 378 km ever reaches the GPU.
Colours are the project's elevation palette (:func:`~geoterrain.rendering.colours.
colorize`), lit by the payloads' normals (the morphed normal maps).

Examples
--------
>>> from geoterrain.globe import Globe
>>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
>>> img = render_globe_array(g, g.camera(0.0, 0.0, 2.0e7, size=(64, 48)))
>>> img.shape, img.dtype
((48, 64, 3), dtype('uint8'))
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geoterrain.core.view import View
from geoterrain.exceptions import UsageError
from geoterrain.rendering.colours import Palette, as_palette, colorize
from geoterrain.rendering.window import draw, pyvista_plotter, write_png

__all__ = ["render_globe_array", "render_globe", "compose_globe", "globe_mesh", "place_camera",
           "data_range", "SHADINGS"]


SHADINGS = ("normals", "elevation", "plain")
SEA_TOLERANCE = 0.05  # metres: heights this close to the water level are its surface


def data_range(globe) -> tuple[float, float] | None:
    """The stores' (min, max) elevation in metres (unexaggerated), or None without stores:
    the colours' range, the same in every view (a frame's own range would recolour the
    planet as the camera moves)."""
    from geoterrain.rendering.textures import elevation_range

    rs = [elevation_range(s.terrain) for s in globe.stores]
    if not rs:
        return None
    return min(r[0] for r in rs), max(r[1] for r in rs)


def _colours(sel, palette: Palette, rng: tuple[float, float] | None) -> np.ndarray:
    h = sel.elevation.astype(np.float64)
    if rng is None:
        rng = (float(h.min()), float(h.max())) if h.size else (0.0, 1.0)
    if rng[1] <= rng[0]:
        rng = (rng[0], rng[0] + 1.0)
    # the bare ellipsoid's 0 m comes back from the float64 placement within millimetres:
    # within SEA_TOLERANCE of the water level it is the water's surface, not a speckle
    return (colorize(h, palette, rng, tolerance=SEA_TOLERANCE) * 255).astype(np.uint8)


def globe_mesh(sel, palette: Palette, rng: tuple[float, float] | None = None):
    """The frame's ``pyvista.PolyData`` (eye-relative float32) with its ``rgb`` colours and
    the payloads' normals as the active normals."""
    m = sel.polydata()
    if sel.triangles:
        m.point_data["rgb"] = _colours(sel, palette, rng)
        m.point_data.active_normals = sel.normals
    return m


def place_camera(cam, view: View, sel) -> None:
    """VTK's camera at the origin of the eye-relative mesh, looking along ``view``."""
    eye = np.asarray(view.eye, np.float64)
    fwd = np.asarray(view.look_at, np.float64) - eye
    cam.position = (0.0, 0.0, 0.0)
    cam.focal_point = tuple(fwd / np.linalg.norm(fwd))
    cam.up = tuple(view.up)
    cam.view_angle = float(view.fov_y_deg)
    if len(sel.points):
        d = np.linalg.norm(sel.points, axis=1)
        near = max(float(d.min()) * 0.5, 0.05)
        cam.clipping_range = (near, float(d.max()) * 1.01)


def render_globe_array(globe, view: View, *, pixel_error: float = 1.0,
                       cmap: str | Palette = "auto", wait: bool = True,
                       shading: str = "normals",
                       stats: dict | None = None) -> np.ndarray:
    """An (H, W, 3) uint8 picture of ``globe`` (a :class:`~geoterrain.globe.Globe`) from
    ``view`` (ECEF, :meth:`Globe.camera`); ``wait``: the converged mesh (every payload the
    view needs generated first). ``shading``: ``"normals"`` (elevation colours lit by the
    payloads' normal maps), ``"elevation"`` (colours only) or ``"plain"`` (lit by the
    mesh's own geometry). ``stats``, when given, is filled with the selection's.

    Examples
    --------
    >>> from geoterrain.globe import Globe
    >>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
    >>> render_globe_array(g, g.camera(0.0, 0.0, 2.0e7, size=(32, 24))).shape
    (24, 32, 3)
    """
    if shading not in SHADINGS:
        raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
    sel = globe.select(view, pixel_error, wait=wait)
    if stats is not None:
        stats.update(sel.stats)
    W, H = view.size
    p = pyvista_plotter((W, H))
    try:
        p.set_background("white")
        if sel.triangles:
            m = globe_mesh(sel, as_palette(cmap), data_range(globe))
            if shading == "plain":
                m = m.compute_normals(cell_normals=False, split_vertices=False)
            p.add_mesh(m, scalars="rgb", rgb=True, smooth_shading=shading != "elevation",
                       lighting=shading != "elevation")
        place_camera(p.camera, view, sel)
        return draw(p)
    finally:
        p.close()


def compose_globe(img: np.ndarray, *, title: str | None = None,
                  palette: str | Palette = "auto",
                  limits: tuple[float, float] | None = None) -> np.ndarray:
    """The title and the elevation colour bar (``limits``: its range in metres; None: no
    bar) drawn over a globe picture, on the flat pictures' opaque boxes
    (:func:`geoterrain.rendering.overlays.plan`).

    Examples
    --------
    >>> img = np.full((120, 160, 3), 255, np.uint8)
    >>> compose_globe(img, title="Earth", limits=(0.0, 3000.0)).shape
    (120, 160, 3)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    from geoterrain.rendering.colours import colorbar_map
    from geoterrain.rendering.overlays import DPI, canvas_over, plan

    H, W = img.shape[:2]
    lay = plan((W, H), title=title, limits=limits, scale_bar=False, north_arrow=False)
    if not lay.boxes:
        return img
    fig = Figure(figsize=(W / DPI, H / DPI), dpi=DPI, facecolor="none")
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.axis("off")
    fs, pt = lay.fs, 72.0 / DPI
    pad = 0.5 * fs
    for name, (x0, y0, x1, y1) in lay.boxes.items():
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc="white", ec="0.55", lw=0.8,
                               zorder=2))
        if name == "title":
            ax.text(0.5 * (x0 + x1), 0.5 * (y0 + y1), title, ha="center", va="center",
                    fontsize=1.3 * fs * pt, weight="bold", zorder=4)
        elif name == "colorbar" and limits is not None:
            cm, (lo, hi) = colorbar_map(as_palette(palette), limits)
            bx1 = x1 - pad
            bx0 = bx1 - 0.9 * fs
            by0, by1 = y0 + pad + 0.5 * fs, y1 - pad - 0.5 * fs
            ax.imshow(np.linspace(1, 0, 256)[:, None], cmap=cm, vmin=0, vmax=1,
                      aspect="auto", extent=(bx0, bx1, by1, by0), zorder=3)
            for v, s in lay.ticks:
                yy = by1 - (v - lo) / (hi - lo) * (by1 - by0)
                ax.plot([bx0 - 0.3 * fs, bx0], [yy, yy], color="0.2", lw=0.8, zorder=3)
                ax.text(bx0 - 0.45 * fs, yy, s, ha="right", va="center",
                        fontsize=0.85 * fs * pt, zorder=4)
            if not lay.compact:
                ax.text(x0 + pad + 0.6 * fs, 0.5 * (by0 + by1), "elevation (m)", rotation=90,
                        ha="center", va="center", fontsize=fs * pt, zorder=4)
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    fig.canvas.draw()
    return canvas_over(fig, img)


def render_globe(globe, view: View, path: str | Path, *, pixel_error: float = 1.0,
                 cmap: str | Palette = "auto", overwrite: bool = False,
                 shading: str = "normals", title: str | None = None, colorbar: bool = False,
                 stats: dict | None = None) -> Path:
    """Write the picture of :func:`render_globe_array` to ``path`` (.png, atomically), with
    a ``title`` and the stores' elevation ``colorbar`` (:func:`compose_globe`).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.globe import Globe
    >>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
    >>> out = os.path.join(tempfile.mkdtemp(), "g.png")
    >>> render_globe(g, g.camera(0.0, 0.0, 2.0e7, size=(32, 24)), out).name
    'g.png'
    """
    img = render_globe_array(globe, view, pixel_error=pixel_error, cmap=cmap,
                             shading=shading, stats=stats)
    pal = as_palette(cmap)
    limits = None
    if colorbar and shading != "plain":
        rng = data_range(globe)
        if rng is not None:
            limits = pal.clim or rng
    if title or limits is not None:
        img = compose_globe(img, title=title, palette=pal, limits=limits)
    write_png(path, img, overwrite)
    return Path(path)

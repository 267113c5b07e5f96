"""Notebook conventions: a terrain's HTML summary with a thumbnail, and ``plot``.

``Terrain._repr_html_`` and ``Terrain.plot`` forward here (imported on first use,
so opening a store never loads VTK or matplotlib).

- :func:`repr_html`: a table of extent, CRS, size, levels, tiles and codec, and a
  thumbnail (elevation colours × hillshade of a coarse pyramid level).
- :func:`plot`: the picture ``geoterrain render`` makes (framed into the room its colour
  bar, scale bar and north arrow leave, with them), as a ``PIL.Image``, which notebooks
  show inline; ``map=True`` for the map view, and the render's colours, light, drape and
  exaggeration. ``interactive=True`` uses PyVista's notebook backend where one is usable
  (``pyvista.global_theme.jupyter_backend`` set and its package installed, inside a
  Jupyter kernel). With trame's server-side rendering (the ``trame`` and ``server``
  backends, ``pip install 'geoterrain[notebook]'``) the viewer's controller drives the
  plot, as in ``view --web``: the LOD follows the camera.

Examples
--------
>>> "<table" in repr_html(t) and "data:image/png;base64," in repr_html(t)
True
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.textures import build_texture_image, texture_level

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

THUMBNAIL = 257  # samples per side of the thumbnail at most


def thumbnail_png(terrain: TerrainLike, max_size: int = THUMBNAIL,
                  shading: str = "normals") -> bytes:
    """PNG bytes of the shaded texture of the finest level that fits ``max_size``,
    cropped to the data (no padding).

    Examples
    --------
    >>> thumbnail_png(t)[:4]
    b'\\x89PNG'
    """
    from PIL import Image

    L = texture_level(terrain, max_size)
    img = build_texture_image(terrain, shading, level=L)
    s = 1 << L
    H, W = -(-terrain.grid.rows // s), -(-terrain.grid.cols // s)
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img[:H, :W])).save(buf, format="PNG")
    return buf.getvalue()


def repr_html(terrain: TerrainLike) -> str:
    """An HTML summary of ``terrain`` (extent, CRS, size, levels, codec) and a thumbnail."""
    info = terrain.info()
    ex = info["extent_m"]
    w = ex["x"][1] - ex["x"][0]
    h = ex["y"][1] - ex["y"][0]
    tiles = sum(info["tiles_per_level"].values())
    lo, hi = info["height_range"]
    rows = [
        ("store", Path(info["path"]).name),
        ("CRS", f"{info['crs']} ({info['frame']})"),
        ("extent", f"{w / 1000:.3f} km × {h / 1000:.3f} km"),
        ("size", f"{info['grid'][1]} × {info['grid'][0]} samples (width × height; "
                 f"padded {info['padded'][0]}), {info['size_bytes'] / 2**20:.1f} MiB"),
        ("heights", f"{lo:.6g} … {hi:.6g} (nodata {100 * info['nodata_fraction']:.1f} %)"),
        ("levels", f"{info['levels']} levels, {tiles} tiles of {info['tile_samples']}²"),
        ("codec", info["codec"]),
    ]
    body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                   f"<td style='text-align:left'>{html.escape(str(v))}</td></tr>"
                   for k, v in rows)
    png = base64.b64encode(thumbnail_png(terrain)).decode()
    return ("<div style='display:flex;gap:1em;align-items:flex-start'>"
            f"<img src='data:image/png;base64,{png}' style='max-width:256px' "
            "alt='shaded thumbnail'/>"
            f"<table><caption style='text-align:left'><b>geoterrain.Terrain</b></caption>"
            f"{body}</table></div>")


def notebook_backend() -> str | None:
    """PyVista's notebook backend when it can be used here, else None."""
    import importlib.util

    try:
        from IPython import get_ipython
    except ImportError:
        return None
    ip = get_ipython()
    if ip is None or "IPKernelApp" not in getattr(ip, "config", {}):
        return None
    import pyvista as pv

    backend = pv.global_theme.jupyter_backend
    if not backend or backend in ("none", "static"):
        return None
    pkg = "trame" if backend.startswith(("trame", "client", "server", "html")) else backend
    return backend if importlib.util.find_spec(pkg) is not None else None


def plot(terrain: TerrainLike, view=None, *, shading: str = "normals", pixel_error: float = 1.0,
         strategy: str | None = None, size: tuple[int, int] = (960, 540),
         cmap="auto", title: str | None = None, overlays: bool = True, map: bool = False,
         vertical_exaggeration: float = 1.0, light=None, drape=None, water: bool = True,
         interactive: bool = False, **kwargs):
    """Show the terrain: the picture ``geoterrain render`` makes, as a ``PIL.Image``.

    ``view`` defaults to the overview framed into the room the overlays leave (the
    colour bar, scale bar and north arrow, drawn unless ``overlays=False``, and ``title``);
    ``map=True`` draws the map view (orthographic, north up, with its graticule or grid).
    ``cmap`` is a colormap name or a :class:`~geoterrain.rendering.colours.Palette`
    (``Palette("auto", clim=(0, 1200), water_level=40)``: a flood at 40 m); ``light``, a
    :class:`~geoterrain.rendering.shading.Light`; ``drape``, a
    :class:`~geoterrain.rendering.drape.Drape`; ``water``, the water surface. With
    ``interactive=True`` PyVista's notebook backend shows it (where one is usable;
    ``kwargs`` go to ``Plotter.show``), else the picture is returned. Where the pictures
    are rendered in the kernel (the ``trame`` and ``server`` backends) the LOD is selected
    again as the camera moves (:func:`live_plot`).

    Examples
    --------
    >>> img = plot(t, size=(320, 180), title="Demo")
    >>> img.size
    (320, 180)
    """
    from geoterrain.exaggerate import exaggerated
    from geoterrain.lod.registry import DEFAULT
    from geoterrain.rendering.overlays import compose
    from geoterrain.rendering.scene import TerrainScene, overview, render_array

    strategy = strategy or DEFAULT
    terrain = exaggerated(terrain, vertical_exaggeration)
    ov = dict(title=title, colorbar=overlays, scale_bar=overlays, north_arrow=overlays)
    if view is None and map:
        from geoterrain.rendering.mapview import map_view

        view = map_view(terrain, size, shading=shading, cmap=cmap, **ov)
    elif view is None:
        view = overview(terrain, size, shading=shading, cmap=cmap, **ov)
    backend = notebook_backend() if interactive else None
    if backend is not None:
        import pyvista as pv

        from geoterrain import lod

        p = pv.Plotter(notebook=True, window_size=list(view.size))
        if backend in LIVE_BACKENDS:
            live_plot(p, terrain, view, shading=shading, pixel_error=pixel_error,
                      strategy=strategy, cmap=cmap, light=light, drape=drape, water=water)
        else:
            scene = TerrainScene(p, terrain, shading, cmap, light=light, drape=drape,
                                 water=water)
            scene.update(lod.select(terrain, view, pixel_error, strategy))
            scene.set_camera(view)
        return p.show(jupyter_backend=backend, **kwargs)
    from PIL import Image

    img, _ = render_array(terrain, view, pixel_error=pixel_error, strategy=strategy,
                          shading=shading, cmap=cmap, light=light, drape=drape, water=water)
    if overlays or title:
        img = compose(img, view, terrain, shading=shading, cmap=cmap, **ov)
    return Image.fromarray(img)


# trame backends that render in the kernel: the mouse reaches the plotter's interactor
LIVE_BACKENDS = ("trame", "server")


def live_plot(plotter, terrain: TerrainLike, view=None, *, shading: str = "normals",
              pixel_error: float = 1.0, strategy: str | None = None, cmap: str = "auto",
              light=None, drape=None, water: bool = True):
    """Put the viewer's controller on ``plotter`` (off screen, its interactor fed by a
    remote view) so that the LOD follows the camera; returns the controller.

    Examples
    --------
    >>> import pyvista as pv
    >>> p = pv.Plotter(off_screen=True, window_size=(320, 180))
    >>> c = live_plot(p, t)
    >>> n = c.selections
    >>> p.camera.position = tuple(np.add(p.camera.position, (0.0, 0.0, 2000.0)))
    >>> _ = p.iren.interactor.InvokeEvent("EndInteractionEvent")  # the mouse released
    >>> c.selections > n
    True
    >>> c.close(); p.close()
    """
    from geoterrain.lod.registry import DEFAULT
    from geoterrain.rendering.viewer import ViewerController

    ctl = ViewerController(plotter, terrain, strategy or DEFAULT, pixel_error, shading, cmap,
                           throttle_ms=150.0, background=False, light=light, drape=drape,
                           water=water, keys=False)
    if view is not None:
        ctl.scene.set_camera(view)
        ctl.on_camera_changed(force=True)
    plotter.enable_terrain_style()  # no roll, as in the desktop viewer
    ctl.follow(plotter.iren.interactor, lambda final: plotter.render() if final else None)
    plotter._geoterrain_viewer = ctl  # noqa: SLF001 - kept alive as long as the plot
    return ctl

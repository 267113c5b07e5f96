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
from geoterrain.rendering.colours import as_palette, colorize
from geoterrain.rendering.scene import _draw, _plotter, _write_png

__all__ = ["render_globe_array", "render_globe"]


def render_globe_array(globe, view: View, *, pixel_error: float = 1.0, cmap: str = "auto",
                       wait: bool = True) -> np.ndarray:
    """An (H, W, 3) uint8 picture of ``globe`` (a :class:`~geoterrain.globe.Globe`) from
    ``view`` (ECEF, :meth:`Globe.camera`); ``wait``: the converged mesh (every payload the
    view needs generated first).

    Examples
    --------
    >>> from geoterrain.globe import Globe
    >>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
    >>> render_globe_array(g, g.camera(0.0, 0.0, 2.0e7, size=(32, 24))).shape
    (24, 32, 3)
    """
    sel = globe.select(view, pixel_error, wait=wait)
    W, H = view.size
    p = _plotter((W, H))
    p.set_background("white")
    if sel.triangles:
        m = sel.polydata()
        h = sel.elevation.astype(np.float64)
        rng = (float(h.min()), float(h.max())) if h.size else (0.0, 1.0)
        if rng[1] <= rng[0]:
            rng = (rng[0], rng[0] + 1.0)
        m.point_data["rgb"] = (colorize(h, as_palette(cmap), rng) * 255).astype(np.uint8)
        m.point_data.active_normals = sel.normals
        p.add_mesh(m, scalars="rgb", rgb=True, smooth_shading=True)
    cam = p.camera
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
    return _draw(p)


def render_globe(globe, view: View, path: str | Path, *, pixel_error: float = 1.0,
                 cmap: str = "auto", overwrite: bool = False) -> Path:
    """Write the picture of :func:`render_globe_array` to ``path`` (.png, atomically).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.globe import Globe
    >>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
    >>> out = os.path.join(tempfile.mkdtemp(), "g.png")
    >>> render_globe(g, g.camera(0.0, 0.0, 2.0e7, size=(32, 24)), out).name
    'g.png'
    """
    img = render_globe_array(globe, view, pixel_error=pixel_error, cmap=cmap)
    _write_png(path, img, overwrite)
    return Path(path)

"""A picture of an export: the model as a slicer or a 3-D viewer shows it.

:func:`preview_image` draws what :func:`~geoterrain.export.formats.export_mesh` writes: the
textured surface (its colours × hillshade, unlit, as in the file) and, for a solid, its
walls and flat bottom in their plain lit material, seen obliquely from the south-west on a
white ground, offscreen. ``geoterrain export --preview PNG`` writes it beside the export.

Examples
--------
>>> from geoterrain.exaggerate import exaggerated
>>> e = exaggerated(t, 2.0)
>>> img = preview_image(e, e.static_selection(5.0), size=(320, 200), print_size=100.0)
>>> img.shape, img.dtype.name
((200, 320, 3), 'uint8')
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.export.formats import (
    TEXTURE_SIZE,
    WALL_COLOUR,
    _tcoords,
    _texture,
)
from geoterrain.export.meshdata import mesh_arrays
from geoterrain.export.solids import solid

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

GROUND = (1.0, 1.0, 1.0)


def preview_image(terrain: TerrainLike, selection, *, size: tuple[int, int] = (960, 540),
                  base_height: float | None = None, print_size: float | None = None,
                  shading: str = "normals", cmap: str = "auto",
                  texture_size: int = TEXTURE_SIZE, drape: str | Path | None = None,
                  azimuth: float = 225.0, elevation: float = 30.0) -> np.ndarray:
    """The export of ``selection`` as a picture (H, W, 3) uint8: a solid when
    ``base_height`` or ``print_size`` is given (as :func:`export_mesh` makes it), else the
    surface; seen from ``azimuth`` (degrees clockwise from north) and ``elevation`` above
    the horizon, the model filling the frame."""
    import pyvista as pv

    from geoterrain.lod.mesh import polydata
    from geoterrain.rendering.window import draw, pyvista_plotter

    m = mesh_arrays(terrain, selection, skirts=base_height is None and print_size is None)
    img, L = _texture(terrain, shading, cmap, texture_size, drape)
    uv = _tcoords(terrain, m.ij, L, flip=True)
    closed = base_height is not None or print_size is not None
    sol = solid(terrain, m, base_height, print_size) if closed else None
    top = m.xyz if sol is None else sol.points[:len(m.xyz)]
    surface = polydata(top, m.faces)
    surface.active_texture_coordinates = uv
    p = pyvista_plotter(tuple(size), "msaa")
    try:
        p.set_background(GROUND)
        tex = pv.Texture(np.ascontiguousarray(img))  # row 0 at the top, as uv (v up) maps it
        tex.interpolate = True
        p.add_mesh(surface, texture=tex, lighting=False, show_scalar_bar=False)
        if sol is not None:
            sides = sol.sides(terrain)
            p.add_mesh(polydata(sides.xyz, sides.faces), color=WALL_COLOUR, lighting=True,
                       ambient=0.35, diffuse=0.7, specular=0.0,
                       smooth_shading=False, show_scalar_bar=False)
        pts = top if sol is None else sol.points
        v = _fit(pts.min(0), pts.max(0), tuple(size), azimuth, elevation)
        p.camera.position, p.camera.focal_point = v.look_from, v.look_at
        p.camera.up = (0.0, 0.0, 1.0)
        p.camera.view_angle = v.fov_y_deg
        p.renderer.ResetCameraClippingRange()
        return draw(p)
    finally:
        p.close()


def _fit(lo: np.ndarray, hi: np.ndarray, size: tuple[int, int], azimuth: float,
         elevation: float, fill: float = 0.92):
    """A camera from ``azimuth``/``elevation`` whose picture holds the box (lo, hi),
    centred, its projection spanning ``fill`` of the frame."""
    from geoterrain.core.view import View
    from geoterrain.rendering.cameras import project

    az, el = math.radians(azimuth), math.radians(elevation)
    d = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    c = 0.5 * (lo + hi)
    dist = 2.0 * float(np.linalg.norm(hi - lo)) + 1e-9
    W, H = size
    for _ in range(12):  # slide the target to centre the box, scale the distance to fit
        v = View(tuple(c + dist * d), tuple(c), (0.0, 0.0, 1.0), 30.0, size)
        px, depth = project(v, corners)
        if np.any(depth <= 0):
            dist *= 2.0
            continue
        (x0, y0), (x1, y1) = px.min(0), px.max(0)
        r, u, _ = v.basis()
        m_per_px = dist / v.lam
        c = c + ((0.5 * (x0 + x1) - W / 2) * r - (0.5 * (y0 + y1) - H / 2) * u) * m_per_px
        dist *= max((x1 - x0) / W, (y1 - y0) / H) / fill
    return View(tuple(c + dist * d), tuple(c), (0.0, 0.0, 1.0), 30.0, size)


def write_preview(terrain: TerrainLike, selection, path: str | Path, *,
                  overwrite: bool = False, **kw) -> Path:
    """:func:`preview_image` written to the PNG ``path`` (never half-written)."""
    from geoterrain.rendering.window import write_png

    out = Path(path)
    from geoterrain.exceptions import UsageError

    if out.suffix.lower() != ".png":
        raise UsageError(f"{out}: a preview is a .png picture",
                         cli=f"--preview {out}: give a .png path")
    write_png(out, preview_image(terrain, selection, **kw), overwrite)
    return out

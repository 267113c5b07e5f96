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
    mesh_arrays,
    solid,
)

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
    from geoterrain.rendering.scene import _draw, _plotter

    m = mesh_arrays(terrain, selection, skirts=base_height is None and print_size is None)
    img, L = _texture(terrain, shading, cmap, texture_size, drape)
    uv = _tcoords(terrain, m.ij, L, flip=True)
    closed = base_height is not None or print_size is not None
    sol = solid(terrain, m, base_height, print_size) if closed else None
    top = m.xyz if sol is None else sol.points[:len(m.xyz)]
    surface = polydata(top, m.faces)
    surface.active_texture_coordinates = uv
    p = _plotter(tuple(size), "msaa")
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
        az, el = math.radians(azimuth), math.radians(elevation)
        d = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
        lo = (top if sol is None else sol.points).min(0)
        hi = (top if sol is None else sol.points).max(0)
        c = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        p.camera.focal_point = tuple(c)
        p.camera.position = tuple(c + 4.0 * radius * d)
        p.camera.up = (0.0, 0.0, 1.0)
        p.camera.view_angle = 30.0
        p.reset_camera(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        p.camera.zoom(1.5)
        return _draw(p)
    finally:
        p.close()


def write_preview(terrain: TerrainLike, selection, path: str | Path, *,
                  overwrite: bool = False, **kw) -> Path:
    """:func:`preview_image` written to the PNG ``path`` (never half-written)."""
    from geoterrain.rendering.scene import _write_png

    out = Path(path)
    from geoterrain.exceptions import UsageError

    if out.suffix.lower() != ".png":
        raise UsageError(f"{out}: a preview is a .png picture",
                         cli=f"--preview {out}: give a .png path")
    _write_png(out, preview_image(terrain, selection, **kw), overwrite)
    return out

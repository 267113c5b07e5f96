"""Water that reads as water: a flat, lit, semi-transparent surface at the water level.

Where the palette has water (``--water-level H``, or the ``auto`` palette's sea at 0 m
where the data reaches it; :func:`geoterrain.rendering.colours.water_level`) the scene
draws, over the terrain, a flat surface at that level (× the vertical exaggeration, so
``-z`` keeps it flat instead of sinking the sea into a basin), as rayshader's
``add_water`` does:

- it is lit by the sun (a directional light from the picture's sun, with a specular
  glint), in one colour;
- it is semi-transparent, the more so the shallower the water (its opacity rises from
  ``ALPHA_MIN`` at the shore to ``ALPHA_MAX`` at ``DEPTH_FADE`` of the deepest water), so
  the terrain's own colours below it, which the palette ramps by depth, show through:
  the depth is coloured under the surface;
- its coast is the terrain texture's: the texture classifies the heights interpolated at
  its texels (:mod:`geoterrain.rendering.tileshader`), and the surface fades out toward
  the shore, so the coastline follows the interpolated DEM's contour, antialiased by the
  texture's filtering, not the mesh's intersection with a plane;
- where the water reaches the edge of the data it has sides down to the terrain, as a
  block of water (rayshader's water sides), so an exaggerated sea is a body of water, not
  a surface floating over a pit;
- it is drawn with a polygon offset toward the camera, so a sea of exact zeros (SRTM)
  under a surface at 0 m does not flicker;
- where the terrain's mesh is coarse because its vertical errors barely show (seen from
  high above), the mesh near the coast can rise above the level and hide the water: a
  map lifts the surface above the terrain's top, a perspective view as far as moves it
  half a pixel at most in the picture (``WATER_LIFT_PX`` in
  :mod:`geoterrain.rendering.scene_camera`).

The surface is a grid over the data at the finest pyramid level of at most
``MAX_SIDE`` samples a side, keeping the cells under water at all four corners; each
vertex's opacity comes from the water's depth at its sample, and is 0 on the vertices next
to dry land, so the surface fades out within one of its cells of the shore and never lies
over land, however coarse the terrain's mesh there (a map view's mesh, seen from straight
above, is very coarse: vertical errors do not show); the shore itself is the texture's.

Examples
--------
>>> from geoterrain.rendering.colours import Palette
>>> mesh = water_mesh(t, Palette("auto", water_level=300.0))
>>> mesh.n_cells > 0, mesh.point_data["rgba"].shape[1]
(True, 4)
>>> water_mesh(t, Palette("viridis")) is None  # no water in this palette
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.colours import Palette, water_level
from geoterrain.rendering.textures import coast_tolerance, elevation_range, terrain_palette

if TYPE_CHECKING:
    from geoterrain.lod.mesh import TriMesh
    from geoterrain.terrainlike import TerrainLike

SURFACE = (0.18, 0.40, 0.62)  # the surface's colour (lit)
ALPHA_MIN, ALPHA_MAX = 0.30, 0.80  # the surface's opacity at the shore and in deep water
DEPTH_FADE = 0.15  # the opacity reaches ALPHA_MAX at this share of the deepest water's depth
MAX_SIDE = 512  # samples a side of the surface's grid, at most (a coarser level beyond)


def water_mesh(terrain: TerrainLike, palette: str | Palette) -> TriMesh | None:
    """The water surface of ``terrain`` under ``palette`` (a
    :class:`~geoterrain.lod.mesh.TriMesh` in the scene frame, RGBA uint8 point array
    ``rgba``), or None where the palette has no water or no sample is under it;
    made once per terrain and water level (``terrain.derived``).

    Examples
    --------
    >>> from geoterrain.rendering.colours import Palette
    >>> m = water_mesh(t, Palette("auto", water_level=300.0))
    >>> bool(np.ptp(m.points[:, 2]) == 0)  # flat
    True
    """
    pal = terrain_palette(terrain, palette)
    wl = water_level(pal, elevation_range(terrain))
    if wl is None:
        return None
    cache = terrain.derived(__name__, dict)
    if wl not in cache:
        cache[wl] = _build(terrain, float(wl))
    return cache[wl]


def _level(terrain: TerrainLike) -> int:
    g = terrain.grid
    for L in g.levels:
        s = 1 << L
        if max(-(-g.rows // s), -(-g.cols // s)) <= MAX_SIDE:
            return L
    return g.top_level


def _build(terrain: TerrainLike, wl: float):
    from geoterrain.lod.mesh import polydata

    g, f = terrain.grid, terrain.frame
    L = _level(terrain)
    s = 1 << L
    H, W = -(-g.rows // s), -(-g.cols // s)
    h, valid = terrain.level_heights(L)
    h, valid = h[:H, :W] * f.z_to_m, valid[:H, :W]
    # a coarse DEM: the surface's grid finer than its samples (heights bilinear), so its
    # fade at the shore is a fraction of a sample wide
    k = 1
    while L == 0 and 2 * k * max(H, W) <= MAX_SIDE and k < 8:
        k *= 2
    if k > 1:
        h, valid = _finer(h, valid, k)
        H, W = h.shape
    s = s / k  # level-0 samples between the surface's grid points
    wet = valid & (h <= wl + coast_tolerance(terrain))
    if not wet.any():
        return None
    # cells under water at every corner
    ci, cj = np.nonzero(wet[:-1, :-1] & wet[1:, :-1] & wet[:-1, 1:] & wet[1:, 1:])
    if len(ci) == 0:
        return None
    idx = np.arange(H * W).reshape(H, W)
    a, b = idx[ci, cj], idx[ci, cj + 1]
    c, d = idx[ci + 1, cj], idx[ci + 1, cj + 1]
    # counter-clockwise from above (rows run south): a (NW), c (SW), d (SE), b (NE)
    faces = np.concatenate([np.column_stack([a, c, d]), np.column_stack([a, d, b])])
    used = np.zeros(H * W, bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    vi, vj = np.divmod(np.flatnonzero(used), W)
    X, Y = f.xy(vi * s, vj * s)  # fractional sample positions on a finer grid
    z = wl * f.z_scale  # metres → scene (× the store's z-scale and any exaggeration)
    pts = np.column_stack([X, Y, np.full(len(vi), z)])
    depth = np.where(wet, wl - h, -1.0)[vi, vj]
    deepest = max(float(np.nanmax(np.where(wet, wl - h, 0.0))), 0.0)
    fade = max(DEPTH_FADE * deepest, 1e-9)
    x = np.clip(depth / fade, 0.0, 1.0)
    # the shore: a wet sample with a dry (or missing) one among its 8 neighbours
    pad = np.pad(wet, 1, constant_values=False)
    inland = np.ones_like(wet)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inland &= pad[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
    alpha = np.where(inland[vi, vj], ALPHA_MIN + (ALPHA_MAX - ALPHA_MIN) * x * x * (3 - 2 * x),
                     0.0)
    rgba = np.empty((len(vi), 4), np.uint8)
    rgba[:, :3] = np.round(np.array(SURFACE) * 255).astype(np.uint8)
    rgba[:, 3] = np.round(alpha * 255).astype(np.uint8)
    # the sides: along the data's outer edge, from the surface down to the terrain
    bed = np.minimum(h, wl) * f.z_scale
    sides = []
    for edge, (p, q) in (((ci == 0), (a, b)), ((ci == H - 2), (d, c)),
                         ((cj == 0), (c, a)), ((cj == W - 2), (b, d))):
        for k in np.flatnonzero(edge[:len(ci)] if edge.ndim else []):
            sides.append((p[k], q[k]))
    pts_all, faces_all, rgba_all = [pts], [remap[faces]], [rgba]
    if sides:
        e = np.array(sides)
        e = e[wet.ravel()[e].all(1)]  # both ends under water
        if len(e):
            n0 = len(pts)
            ei, ej = np.divmod(e, W)
            top = pts[remap[e]]  # (E, 2, 3)
            low = top.copy()
            low[..., 2] = bed[ei, ej]
            quad = np.concatenate([top, low[:, ::-1]], axis=1).reshape(-1, 3)  # p q q' p'
            k = n0 + 4 * np.arange(len(e))[:, None]
            pts_all.append(quad)
            faces_all.append(np.concatenate([k + [0, 3, 2], k + [0, 2, 1]]))
            side = np.empty((len(quad), 4), np.uint8)
            side[:, :3] = rgba[0, :3]
            side[:, 3] = int(round(ALPHA_MAX * 255))
            rgba_all.append(side)
    mesh = polydata(np.concatenate(pts_all), np.concatenate(faces_all))
    mesh.point_data["rgba"] = np.concatenate(rgba_all)
    return mesh


def _finer(h: np.ndarray, valid: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Heights on a grid k times finer (bilinear; a point is valid where its four samples
    are), keeping the original samples as grid points."""
    H, W = h.shape
    ri = np.arange((H - 1) * k + 1) / k
    cj = np.arange((W - 1) * k + 1) / k
    i0 = np.minimum(ri.astype(int), H - 2)
    j0 = np.minimum(cj.astype(int), W - 2)
    fi, fj = (ri - i0)[:, None], (cj - j0)[None, :]
    z = np.where(valid, h, 0.0)
    a, b = z[np.ix_(i0, j0)], z[np.ix_(i0, j0 + 1)]
    c, d = z[np.ix_(i0 + 1, j0)], z[np.ix_(i0 + 1, j0 + 1)]
    out = (1 - fi) * (1 - fj) * a + (1 - fi) * fj * b + fi * (1 - fj) * c + fi * fj * d
    ok = (valid[np.ix_(i0, j0)] & valid[np.ix_(i0, j0 + 1)] & valid[np.ix_(i0 + 1, j0)]
          & valid[np.ix_(i0 + 1, j0 + 1)])
    return out, ok


def add_water(plotter, mesh, sun: tuple[float, float] = (315.0, 45.0)):
    """Add ``mesh`` (:func:`water_mesh`) to ``plotter`` as the lit, semi-transparent water
    actor, with a directional light from the sun (azimuth, elevation in degrees) for its
    diffuse light and glint (the terrain itself is unlit: its texture carries its
    shading). Returns the actor.
    """
    import pyvista as pv

    from geoterrain.rendering.shading import light_vector

    lv = np.asarray(light_vector(*sun), np.float64)
    plotter.remove_all_lights()
    plotter.add_light(pv.Light(position=tuple(lv), focal_point=(0.0, 0.0, 0.0),
                               light_type="scene light", intensity=1.0))
    actor = plotter.add_mesh(mesh.pyvista(), scalars="rgba", rgba=True, name="water",
                             show_scalar_bar=False, reset_camera=False, lighting=True,
                             smooth_shading=False, ambient=0.45, diffuse=0.55, specular=0.5,
                             specular_power=60.0)
    water_offset(actor)
    return actor


def water_offset(actor) -> None:
    """Draw the water ``actor`` a little toward the camera: a sea of zeros under a surface
    at 0 m never fights it."""
    m = actor.GetMapper()
    m.SetResolveCoincidentTopologyToPolygonOffset()
    m.SetRelativeCoincidentTopologyPolygonOffsetParameters(-2.0, -4.0)

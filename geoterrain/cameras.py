"""Cameras around a terrain: the default overview, orbits, cameras from JSON, projection.

Every camera is a :class:`geoterrain.view.View` in the scene frame (metres, origin
at the DEM centre).

Examples
--------
>>> v = default_view(t, (640, 480), azimuth=180, elevation=30)
>>> v.size, v.look_from[1] < v.look_at[1]  # from the south, looking north
((640, 480), True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from geoterrain.exceptions import UsageError
from geoterrain.view import View, load_views


def terrain_bounds(terrain) -> tuple[np.ndarray, np.ndarray]:
    """Scene-frame box (lo, hi) of the terrain's valid data (:meth:`Terrain.scene_box`)."""
    return terrain.scene_box()


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

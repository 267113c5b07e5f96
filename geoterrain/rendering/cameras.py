"""Cameras around a terrain: the default overview, orbits, cameras from JSON, projection.

Every camera is a :class:`geoterrain.core.view.View` in the scene frame (metres, origin
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
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View, load_views
from geoterrain.exceptions import UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


ORBIT_FILL = 1.08  # an orbit's central disc spans this share of the free rectangle


def terrain_bounds(terrain: TerrainLike) -> tuple[np.ndarray, np.ndarray]:
    """Scene-frame box (lo, hi) of the terrain's valid data (:meth:`Terrain.scene_box`)."""
    return terrain.scene_box()


def camera_up(azimuth: float, elevation: float) -> np.ndarray:
    """The camera's true up vector for a bearing and elevation (degrees).

    Perpendicular to the viewing direction and, at every elevation up to 90°,
    the limit of the screen's up: straight down (90°) it is the horizontal
    direction away from the camera, so the picture turns with the azimuth exactly
    as it does just below 90°. Passed to VTK as is (no view-up for VTK to guess).

    Examples
    --------
    >>> [round(float(c), 6) + 0.0 for c in camera_up(180.0, 90.0)]  # from the south: north up
    [0.0, 1.0, 0.0]
    """
    az, el = math.radians(azimuth), math.radians(elevation)
    return np.array([-math.sin(az) * math.sin(el), -math.cos(az) * math.sin(el), math.cos(el)])


def check_elevation(elevation: float) -> None:
    """Refuse a camera elevation outside (0, 90] degrees, with the reason."""
    if not (math.isfinite(elevation) and 0.0 < elevation <= 90.0):
        raise UsageError(f"elevation must be in (0, 90] degrees above the horizon (90: straight "
                         f"down), got {elevation:g}; to look up at the terrain from below, give "
                         "look_from and look_at")


def default_view(terrain: TerrainLike, size: tuple[int, int] = (1280, 720), azimuth: float = 190.0,
                 elevation: float = 40.0, distance: float | None = None,
                 fov_y_deg: float = 30.0, look_at: Sequence[float] | None = None,
                 fit_rect: Sequence[float] | None = None, fill: float | None = None,
                 centred: bool = False, fit_points: np.ndarray | None = None) -> View:
    """An oblique overview of the whole terrain.

    Parameters
    ----------
    terrain : Terrain
    size : (width, height) in pixels.
    azimuth : compass bearing of the camera *from* the target, degrees clockwise from
        north (190: from just west of south, looking north).
    elevation : angle of the camera above the horizon at the target, degrees, in (0, 90].
    distance : eye–target distance in metres; default: the whole terrain fits the frame.
    fov_y_deg : vertical field of view.
    look_at : target point (scene frame); default: the centre of the terrain's box.
    fit_rect : pixel rectangle (x0, y0, x1, y1) the terrain is fitted into (default: the
        whole frame); the camera slides sideways so the terrain's projection is centred
        in it unless ``centred``.
    fill : the share of ``fit_rect`` the terrain's projected box spans (default 0.97;
        0.94 of the whole frame, centred, without ``fit_rect``: the framing of earlier
        versions, which the LOD fidelity figures were measured with).
    fit_points : scene points to fit instead of the terrain's own (an orbit fits the
        terrain's central cylinder, :func:`orbit_views`).

    Returns
    -------
    View

    Examples
    --------
    >>> v = default_view(t, (800, 600), azimuth=180, elevation=90)
    >>> [round(c, 6) + 0.0 for c in v.up]  # straight down from the south: north is up
    [0.0, 1.0, 0.0]
    """
    check_elevation(elevation)
    lo, hi = terrain_bounds(terrain)
    c = 0.5 * (lo + hi) if look_at is None else np.asarray(look_at, np.float64)
    if look_at is None:
        c[2] = lo[2] + 0.35 * (hi[2] - lo[2])
    az, el = math.radians(azimuth), math.radians(elevation)
    d = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    up = tuple(camera_up(azimuth, elevation))
    W, H = size
    x0, y0, x1, y1 = (0.0, 0.0, float(W), float(H)) if fit_rect is None else fit_rect
    iterations = 12
    if fit_rect is None:
        centred, iterations = True, 4
    if fill is None:
        fill = 0.94 if fit_rect is None else 0.97
    if distance is None:
        radius = max(float(np.linalg.norm(0.5 * (hi - lo))), 1e-6)
        ty = math.tan(math.radians(fov_y_deg) / 2)
        distance = radius / math.sin(math.atan(min(ty, ty * W / H)))
        # fit the projected box of the data into the rectangle (perspective iterations:
        # scale the distance by the box's overshoot, slide the camera by its offset)
        corners = _coarse_points(terrain) if fit_points is None else fit_points
        for _ in range(iterations):
            v = View(tuple(c + distance * d), tuple(c), up, fov_y_deg, tuple(size))
            px, depth = project(v, corners)
            if np.any(depth <= 0):
                break
            bx0, by0 = px.min(0)
            bx1, by1 = px.max(0)
            if centred:
                f = max(np.abs(px[:, 0] - W / 2).max() / (0.5 * (x1 - x0)),
                        np.abs(px[:, 1] - H / 2).max() / (0.5 * (y1 - y0)))
            else:
                f = max((bx1 - bx0) / (x1 - x0), (by1 - by0) / (y1 - y0))
                r, u, _ = v.basis()
                m_per_px = distance / v.lam
                shift = ((0.5 * (bx0 + bx1) - 0.5 * (x0 + x1)) * r
                         - (0.5 * (by0 + by1) - 0.5 * (y0 + y1)) * u) * m_per_px
                c = c + shift
            distance *= f / fill
    eye = c + distance * d
    return View(tuple(eye), tuple(c), up, fov_y_deg, tuple(size))


def _coarse_points(terrain: TerrainLike) -> np.ndarray:
    """Scene positions of the valid samples of the top pyramid level's tiles (the
    terrain's shape): the one top tile of a square grid, every stored root of a root
    grid."""
    g = terrain.grid
    L = g.top_level
    across, down = g.roots
    pts = []
    for y in range(down):
        for x in range(across):
            if (L, x, y) not in terrain.tile_info:  # a root without data
                continue
            h = terrain.tile(L, x, y).heights
            ii, jj = np.meshgrid(g.tile_rows(L, y), g.tile_cols(L, x), indexing="ij")
            ok = np.isfinite(h)
            X, Y = terrain.frame.xy(ii[ok], jj[ok])
            pts.append(np.stack([X, Y, terrain.frame.z(h[ok])], 1))
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def orbit_views(terrain: TerrainLike, n_frames: int, size: tuple[int, int] = (1280, 720),
                azimuth: float = 190.0, elevation: float = 40.0,
                distance: float | None = None, fov_y_deg: float = 30.0,
                fit_rect: Sequence[float] | None = None) -> list[View]:
    """``n_frames`` views evenly spaced on a full turn around the terrain centre.

    Every frame is at the same distance from the same target (no "breathing"). By
    default the distance fits the terrain's central disc (:func:`central_cylinder`)
    centred in ``fit_rect``, overfilling it by ``ORBIT_FILL``: the same from every
    azimuth, so every frame is filled alike, and the terrain's corners may leave the frame
    as it turns, as an orbit is framed in film. At 480×270 the terrain covers 55–66 % of
    every frame of srtm1_japan and of the demo fBm (it covered about a third when the
    whole terrain was fitted at every azimuth).

    Examples
    --------
    >>> len(orbit_views(t, 8))  # doctest: +SKIP
    8
    """
    if n_frames < 1:
        raise UsageError(f"an orbit needs at least 1 frame, got {n_frames}")
    azs = [azimuth + 360.0 * k / n_frames for k in range(n_frames)]
    fit_rect = symmetric_rect(size, fit_rect)
    # the target: the cylinder's centre, so its picture is centred in the frame
    cyl = central_cylinder(terrain)
    target = 0.5 * (cyl.min(0) + cyl.max(0))
    if distance is None:
        # one distance for the whole turn: the one that fits the central cylinder, which
        # is the same from every azimuth
        distance = _distance(default_view(terrain, size, azimuth, elevation, None, fov_y_deg,
                                          look_at=target, fit_rect=fit_rect, centred=True,
                                          fit_points=cyl, fill=ORBIT_FILL))
    return [default_view(terrain, size, a, elevation, distance, fov_y_deg, look_at=target)
            for a in azs]


def central_cylinder(terrain: TerrainLike, n: int = 72) -> np.ndarray:
    """Scene points (n, 3) on the circle inscribed in the terrain's box (centred on it,
    radius half its shorter side) at the overview's target height (35 % up its relief):
    what an orbit keeps in the frame from every azimuth.

    Examples
    --------
    >>> central_cylinder(t, 8).shape
    (8, 3)
    """
    lo, hi = terrain_bounds(terrain)
    c = 0.5 * (lo + hi)
    r = 0.5 * float(min(hi[0] - lo[0], hi[1] - lo[1]))
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])
    return np.column_stack([ring, np.full(n, lo[2] + 0.35 * (hi[2] - lo[2]))])


def _distance(v: View) -> float:
    return float(np.linalg.norm(v.eye - np.asarray(v.look_at)))


def symmetric_rect(size: tuple[int, int], rect: Sequence[float] | None) -> tuple | None:
    """The largest rectangle centred in the frame inside ``rect`` (None: the whole frame)."""
    if rect is None:
        return None
    W, H = size
    x0, y0, x1, y1 = rect
    hx = min(W / 2 - x0, x1 - W / 2)
    hy = min(H / 2 - y0, y1 - H / 2)
    return (W / 2 - hx, H / 2 - hy, W / 2 + hx, H / 2 + hy)


def load_cameras(terrain: TerrainLike, path: str | Path, size: tuple[int, int] = (1280, 720),
                 fov_y_deg: float = 30.0) -> list[View]:
    """Views from a cameras JSON file, CRS cameras placed in ``terrain``'s frame.

    See :func:`geoterrain.core.view.load_views` for the format.

    Examples
    --------
    >>> views = load_cameras(t, "cameras.json")  # doctest: +SKIP
    """
    return load_views(path, size, fov_y_deg, terrain.frame)


def to_scene(terrain: TerrainLike, p: Sequence[float]) -> np.ndarray:
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


def interpolate_views(views: Sequence[View], frames_between: int) -> list[View]:
    """Keyframe cameras with ``frames_between`` eased frames between each pair.

    Eye and target follow uniform Catmull–Rom splines through the
    keyframes (so the path is smooth through them), and each segment is eased with
    smoothstep 3s² − 2s³ (the camera slows into and out of every keyframe).

    Examples
    --------
    >>> a = View((0, -100, 50), (0, 0, 0)); b = View((100, 0, 50), (0, 0, 0))
    >>> vs = interpolate_views([a, b], 3)
    >>> len(vs), vs[0].look_from == a.look_from, vs[-1].look_from == b.look_from
    (5, True, True)
    """
    if frames_between < 0:
        raise UsageError(f"frames_between must be ≥ 0, got {frames_between}")
    if frames_between == 0 or len(views) < 2:
        return list(views)
    E = np.array([v.look_from for v in views])
    T = np.array([v.look_at for v in views])
    out: list[View] = []
    n = len(views)
    for k in range(n - 1):
        out.append(views[k])
        for j in range(1, frames_between + 1):
            s = j / (frames_between + 1)
            s = s * s * (3 - 2 * s)
            e, t = (_catmull_rom(P, k, s) for P in (E, T))
            a, b = views[k], views[k + 1]
            up = (1 - s) * np.asarray(a.up) + s * np.asarray(b.up)
            out.append(View(tuple(e), tuple(t), tuple(up),
                            (1 - s) * a.fov_y_deg + s * b.fov_y_deg, a.size))
    out.append(views[-1])
    return out


def _catmull_rom(P: np.ndarray, k: int, s: float) -> np.ndarray:
    """Uniform Catmull–Rom between P[k] and P[k+1] (end points repeated)."""
    p0, p1 = P[max(k - 1, 0)], P[k]
    p2, p3 = P[k + 1], P[min(k + 2, len(P) - 1)]
    return 0.5 * ((2 * p1) + (-p0 + p2) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s * s
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * s ** 3)

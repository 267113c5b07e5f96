"""View: a pinhole camera in scene coordinates, its frustum and projection factor."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoterrain.exceptions import InputError

OUTSIDE, INTERSECTS, INSIDE = 0, 1, 2
NEAR_FLOOR = 1e-3  # near ≥ this × far, as VTK's own clipping range keeps it (24-bit depth)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise ValueError(f"degenerate direction {v}")
    return v / n


_NO_AXIS = np.zeros(0)


class ViewTerms(NamedTuple):
    """What the compiled selection kernels read of a view and a tolerance (seed 002 eq. 2,
    λδ > τ(d − r)): the ``eye`` (3,), the inward frustum ``planes`` (P, 4) (P = 0: no
    culling), ``lam`` (λ), ``tau`` (τ) and the eye plane ``axis``.

    ``axis`` empty: LP's distance d = ‖p − eye‖. ``axis`` (4,), (f, −f·eye) for the view
    direction f: the depth z = f·(p − eye) replaces d, as the picture divides by it
    (:meth:`View.terms` with ``depth``; ``lam`` then holds λ·k + τ, see there)."""

    eye: np.ndarray
    planes: np.ndarray
    lam: float
    tau: float
    axis: np.ndarray = _NO_AXIS


@dataclass(frozen=True)
class View:
    """A camera looking from ``look_from`` at ``look_at`` (scene coordinates, metres).

    Parameters
    ----------
    look_from, look_at, up
        Eye, target and up vector.
    fov_y_deg
        Vertical field of view in degrees (VTK's ``view_angle``).
    size
        Image (width, height) in pixels.
    near, far
        Clipping distances; ``None`` means no near plane (beyond the eye) or no far plane.
    parallel
        A map's orthographic picture: the renderer draws the parallel projection of what
        this (far, narrow) perspective view frames at its target, while the LOD selection
        and the overlays use the perspective view itself, which differs from it by less
        than the terrain's relief over the eye's distance
        (:func:`geoterrain.rendering.mapview.map_view`).

    Examples
    --------
    >>> v = View((0, -1000, 500), (0, 0, 0), size=(1280, 720), fov_y_deg=30)
    >>> round(float(v.lam), 2)  # pixels per unit of error at unit distance
    1343.54
    >>> v.planes.shape
    (6, 4)
    """

    look_from: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov_y_deg: float = 30.0
    size: tuple[int, int] = (1280, 720)
    near: float | None = None
    far: float | None = None
    parallel: bool = False
    memos: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not 0.0 < self.fov_y_deg < 180.0:
            raise ValueError(f"fov_y_deg must be in (0, 180), got {self.fov_y_deg}")
        if self.size[0] < 1 or self.size[1] < 1:
            raise ValueError(f"size must be positive, got {self.size}")
        object.__setattr__(self, "look_from", tuple(float(v) for v in self.look_from))
        object.__setattr__(self, "look_at", tuple(float(v) for v in self.look_at))
        object.__setattr__(self, "up", tuple(float(v) for v in self.up))

    @staticmethod
    def from_camera(camera, size: tuple[int, int]) -> View:
        """The view of a ``pyvista.Camera`` (or VTK camera) rendering at ``size``."""
        near, far = camera.clipping_range
        return View(tuple(camera.position), tuple(camera.focal_point), tuple(camera.up),
                    float(camera.view_angle), tuple(size), near, far)

    # ------------------------------------------------------------------ basis
    @property
    def eye(self) -> np.ndarray:
        return np.asarray(self.look_from, np.float64)

    @property
    def forward(self) -> np.ndarray:
        return _unit(np.asarray(self.look_at) - self.eye)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Right, true-up and forward unit vectors."""
        f = self.forward
        up = np.asarray(self.up, np.float64)
        r = np.cross(f, up)
        if np.linalg.norm(r) < 1e-9:  # looking along "up" (straight down): pick any right
            r = np.cross(f, [0.0, 1.0, 0.0] if abs(f[1]) < 0.9 else [1.0, 0.0, 0.0])
        r = _unit(r)
        return r, np.cross(r, f), f

    @property
    def lam(self) -> float:
        """λ: projected pixels per unit of error at unit distance, (h/2)/tan(fov_y/2)."""
        return float((self.size[1] / 2.0) / np.tan(np.radians(self.fov_y_deg) / 2.0))

    @property
    def planes(self) -> np.ndarray:
        """Six inward plane equations (a, b, c, d): a·x + b·y + c·z + d ≥ 0 inside.

        Order: left, right, bottom, top, near, far. A missing near plane passes
        through the eye; a missing far plane is (0, 0, 0, 1) (always inside).
        """
        return self.memo("planes", self._planes)

    def _planes(self) -> np.ndarray:
        r, u, f = self.basis()
        ty = np.tan(np.radians(self.fov_y_deg) / 2.0)
        tx = ty * self.size[0] / self.size[1]
        e = self.eye
        normals = [f * tx + r, f * tx - r, f * ty + u, f * ty - u]
        out = np.zeros((6, 4))
        for k, nrm in enumerate(normals):
            nrm = _unit(nrm)
            out[k, :3], out[k, 3] = nrm, -nrm @ e
        near = self.near or 0.0
        out[4, :3], out[4, 3] = f, -(f @ e) - near
        if self.far is None:
            out[5] = (0.0, 0.0, 0.0, 1.0)
        else:
            out[5, :3], out[5, 3] = -f, f @ e + self.far
        return out

    def memo(self, key, make):
        """The value ``make()`` gave for ``key`` the first time this view was asked:
        what a module derives from the camera once per view (its frustum planes, the
        occlusion test's sectors and results), held in :attr:`memos`.

        Examples
        --------
        >>> v = View((0, -1000, 500), (0, 0, 0))
        >>> v.memo("example", lambda: 1), v.memo("example", lambda: 2)
        (1, 1)
        """
        got = self.memos.get(key)
        if got is None:
            got = self.memos[key] = make()
        return got

    @property
    def lift(self) -> float:
        """k ≥ 1: the most a vertical move of δ at depth z moves its picture, in units of
        λδ/z, over the viewport.

        A point at picture coordinates (a, b) = (x, y)/z (camera right, up; z the depth
        along the view) moved by w = δ·ẑ moves by λδ·‖(w_r − a w_f, w_u − b w_f)‖ / z'
        pixels (z' the nearer of its two depths), w_r, w_u, w_f the world's up in the
        camera's basis. The norm is convex in (a, b), so its largest value over the
        viewport is at a corner, a = ±tan(fov_x/2), b = ±tan(fov_y/2): 1 for a level
        camera, a few per cent over 1 for a pitched one. Never under 1, so δ ≤ τz/λ
        still holds where the picture bound does (the frustum margin of
        :func:`geoterrain.lod.emit.cull_in_place` rests on it).

        Examples
        --------
        >>> View((0, -1000, 0), (0, 0, 0)).lift  # level: a vertical move is a picture move
        1.0
        >>> 1.0 < View((0, -1000, 500), (0, 0, 0)).lift < 1.1
        True
        """
        r, u, f = self.basis()
        ty = np.tan(np.radians(self.fov_y_deg) / 2.0)
        tx = ty * self.size[0] / self.size[1]
        wr, wu, wf = r[2], u[2], f[2]
        k = max(float(np.hypot(wr - a * wf, wu - b * wf)) for a in (-tx, tx) for b in (-ty, ty))
        return max(1.0, k)

    def terms(self, tau: float, depth: bool = False) -> ViewTerms:
        """The :class:`ViewTerms` of this view at tolerance ``tau``.

        ``depth``: the picture's bound instead of LP's eq. 2. A vertex whose sphere
        (p, r) holds every sample of its error δ is active when λkδ > τ(z − r − δ)
        (k: :attr:`lift`; z − r the sphere's nearest depth, z = f·(p − eye); − δ: the
        drawn point may lie δ nearer than the true one), i.e. (λk + τ)δ > τ(z − r), so
        ``lam`` = λk + τ and the kernels' test keeps eq. 2's form with z for d. Inactive
        then means every sample under it moves at most τ pixels in the picture. Nesting
        holds as for eq. 2 (seed 002 §3.1): depth is linear, so a child's sphere inside
        its parent's has a nearest depth z_c − r_c ≥ z_p − r_p, and δ_c ≤ δ_p.

        Examples
        --------
        >>> v = View((0, -1000, 500), (0, 0, 0))
        >>> t = v.terms(1.0); t.eye.tolist(), t.planes.shape, t.tau, t.axis.shape
        ([0.0, -1000.0, 500.0], (6, 4), 1.0, (0,))
        >>> d = v.terms(1.0, depth=True); round(d.lam - v.lam * v.lift, 6), d.axis.shape
        (1.0, (4,))
        """
        if not depth:
            return ViewTerms(self.eye, self.planes, self.lam, float(tau))
        f = self.forward
        axis = np.array([f[0], f[1], f[2], -float(f @ self.eye)])
        return ViewTerms(self.eye, self.planes, self.lam * self.lift + float(tau), float(tau),
                         axis)

    # --------------------------------------------------------------- culling
    def spheres_visible(self, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """True for each sphere that is not entirely outside one frustum plane."""
        c = np.asarray(centers, np.float64).reshape(-1, 3)
        r = np.asarray(radii, np.float64).ravel()
        ok = np.ones(len(c), bool)
        for a, b, cc, d in self.planes:  # broadcasting beats a tiny BLAS matmul here
            ok &= a * c[:, 0] + b * c[:, 1] + cc * c[:, 2] + d + r >= 0
        return ok

    def box_visibility(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """OUTSIDE / INTERSECTS / INSIDE for axis-aligned boxes (lo, hi: (..., 3))."""
        p = self.planes
        lo, hi = np.asarray(lo), np.asarray(hi)
        pos = (p[:, :3] >= 0)
        # the box corner farthest along / against each plane normal
        far = np.where(pos, hi[..., None, :], lo[..., None, :])
        near = np.where(pos, lo[..., None, :], hi[..., None, :])
        dmax = (far * p[:, :3]).sum(-1) + p[:, 3]
        dmin = (near * p[:, :3]).sum(-1) + p[:, 3]
        out = np.full(dmax.shape[:-1], INTERSECTS, np.int8)
        out[(dmin >= 0).all(-1)] = INSIDE
        out[(dmax < 0).any(-1)] = OUTSIDE
        return out

    def points_inside(self, pts: np.ndarray) -> np.ndarray:
        """Boolean mask of points inside the frustum."""
        return ((np.asarray(pts) @ self.planes[:, :3].T + self.planes[:, 3]) >= 0).all(-1)

    def box_distance(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Euclidean distance from the eye to each axis-aligned box (0 inside)."""
        e = self.eye
        d = np.maximum(np.maximum(np.asarray(lo) - e, 0.0), e - np.asarray(hi))
        return np.linalg.norm(d, axis=-1)

    def clipped_to(self, lo: np.ndarray, hi: np.ndarray, floor: float = NEAR_FLOOR) -> View:
        """This view with near and far planes around the scene box (``lo``, ``hi``), as a
        renderer sets them: far just beyond the box's deepest corner, near at its
        shallowest but not under ``floor`` × far (depth-buffer precision). The LOD
        selection and the picture then share one frustum, near plane included.

        Examples
        --------
        >>> v = View((0, -1000, 500), (0, 0, 0)).clipped_to([-100, -100, 0], [100, 100, 50])
        >>> 0 < v.near < v.far
        True
        """
        _, _, f = self.basis()
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])
        depth = (corners - self.eye) @ f
        span = max(float(np.ptp(corners, axis=0).max()), 1e-9)
        far = max(float(depth.max()), 0.0) * 1.01 + 0.01 * span  # skirts hang a little lower
        near = max(float(depth.min()) * 0.99, floor * far)
        return View(self.look_from, self.look_at, self.up, self.fov_y_deg, self.size,
                    near, far, self.parallel)


def load_views(path: str | Path, size: tuple[int, int] = (1280, 720), fov_y_deg: float = 30.0,
               frame=None) -> list[View]:
    """Views from a cameras JSON file.

    The file holds a list of cameras, or ``{"crs": true|false, "fov": deg,
    "cameras": [...]}``. Each camera is ``{"look_from": [x, y, z], "look_at":
    [x, y, z]}`` with optional ``"up"`` and ``"fov"``. Coordinates are scene
    metres, or source-CRS x, y with a height z in metres when ``"crs"`` is true
    (which needs the store's ``frame``). A bad file is an ``InputError``.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "cams.json")
    >>> _ = open(p, "w").write(json.dumps([{"look_from": [0, -10, 5], "look_at": [0, 0, 0]}]))
    >>> [v.look_from for v in load_views(p)]
    [(0.0, -10.0, 5.0)]
    """
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the cameras JSON ({exc})") from None
    crs = False
    if isinstance(doc, dict):
        crs = bool(doc.get("crs", False))
        fov_y_deg = doc.get("fov", fov_y_deg)
        doc = doc.get("cameras")
    if not isinstance(doc, list) or not doc:
        raise InputError(f"{path}: expected a non-empty list of cameras")
    if crs and frame is None:
        raise InputError(f"{path}: CRS cameras need a store to place them; give scene metres")
    views = []
    for k, cam in enumerate(doc):
        try:
            a = np.asarray(cam["look_from"], np.float64)
            b = np.asarray(cam["look_at"], np.float64)
            if a.shape != (3,) or b.shape != (3,) or not (np.isfinite(a).all()
                                                          and np.isfinite(b).all()):
                raise ValueError
            if crs:
                a, b = frame.crs_point_to_scene(a), frame.crs_point_to_scene(b)
            up = np.asarray(cam.get("up", (0.0, 0.0, 1.0)), np.float64)
            fov = float(cam.get("fov", fov_y_deg))
            if up.shape != (3,) or not np.isfinite(up).all() or not up.any() or \
                    not 0 < fov < 180:
                raise ValueError
            v = View(tuple(a), tuple(b), tuple(up), fov, tuple(size))
            v.basis()  # rejects look_from == look_at
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{path}: camera {k} needs look_from and look_at as distinct, "
                             "finite [x, y, z], a non-zero up and fov in (0, 180)") from None
        views.append(v)
    return views

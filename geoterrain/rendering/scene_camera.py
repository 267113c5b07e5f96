"""The scene's camera: the plotter's camera pointed like a view (straight down and maps
included), and the water surface lifted over the terrain's coarse mesh as far as moves
it by :data:`WATER_LIFT_PX` in the picture at most. A mixin of
:class:`geoterrain.rendering.scene.TerrainScene`, whose state it reads."""

from __future__ import annotations

import numpy as np

from geoterrain.core.view import View

__all__ = ["WATER_LIFT_PX", "SceneCamera"]

# how far (pixels in the picture, at most) a perspective view's water surface may move when
# it is lifted over the terrain's coarse mesh (see TerrainScene.set_camera)
WATER_LIFT_PX = 0.5


class SceneCamera:
    """The scene's camera (a mixin of TerrainScene)."""

    def set_camera(self, view: View) -> None:
        """Point the plotter's camera like ``view`` (and fit the clipping range).

        VTK gets the view's own orthonormal up (``View.basis``), never a view-up it
        would have to re-orthogonalise: the picture, the frustum the LOD culls with
        and :func:`project` are one camera, straight down included.
        """
        cam = self.plotter.camera
        _, u, f = view.basis()
        if self.water_actor is not None:
            # a map, seen from straight above, draws the water over the terrain whatever
            # its mesh (coarse there: vertical errors do not show), lifted above its top
            # (which moves nothing in the picture); a perspective view lifts it as far as
            # moves it by WATER_LIFT_PX in the picture at most (seen from high above, a
            # coarse mesh's vertical errors barely show either, and would hide the water
            # near the coast)
            lo, hi = self.terrain.scene_box()
            top = max(float(hi[2] - lo[2]), 1.0) * 1.01
            lift = top if view.parallel else min(top, self._water_lift(view))
            self.water_actor.SetPosition(0.0, 0.0, lift)
        if view.parallel:  # a map: the parallel projection of what the view frames
            target = np.asarray(view.look_at, np.float64)
            d = float(np.linalg.norm(view.eye - target))
            lo, hi = self.terrain.scene_box()
            near = 2.0 * float(np.linalg.norm(hi - lo)) + 1.0  # depth precision: close
            cam.SetParallelProjection(True)
            cam.SetParallelScale(d * np.tan(np.radians(view.fov_y_deg) / 2.0))
            _place(cam, tuple(target - near * f), tuple(target), tuple(u))
            self.plotter.renderer.ResetCameraClippingRange()
            return
        cam.SetParallelProjection(False)
        _place(cam, view.look_from, view.look_at, tuple(u))
        cam.SetViewAngle(view.fov_y_deg)
        self.plotter.renderer.ResetCameraClippingRange()
        if view.near is not None and view.far is not None:
            cam.SetClippingRange(view.near, view.far)

    def _water_lift(self, view: View) -> float:
        """The height (scene units) the water surface may be lifted by in the perspective
        ``view`` while no point of it moves more than ``WATER_LIFT_PX`` in the picture:
        that over the largest of its points' picture motion per unit of height (the
        derivative of the projection along z)."""
        pts = self._water_pts
        if pts is None or not len(pts):
            return 0.0
        r, u, f = view.basis()
        rel = pts - np.asarray(view.look_from, np.float64)
        d = rel @ f  # depth along the view direction
        front = d > 1e-9
        if not front.any():
            return 0.0
        d, x, y = d[front], rel[front] @ r, rel[front] @ u
        k = view.lam  # pixels per unit across at depth 1
        # a point at (x, y) across and d along the view sits at k·(x, y)/d px from the
        # centre; moving it up by one unit changes x, y, d by r_z, u_z, f_z
        dx = k * (r[2] * d - x * f[2]) / d**2
        dy = k * (u[2] * d - y * f[2]) / d**2
        rate = float(np.sqrt(dx * dx + dy * dy).max())
        return WATER_LIFT_PX / rate if rate > 0 else float("inf")


def _place(cam, position, focal_point, up) -> None:
    """Point ``cam`` (a VTK camera; PyVista's through its properties, which also mark it
    as set, so its plotter's first render keeps it) from ``position`` at ``focal_point``."""
    if hasattr(cam, "is_set"):  # a pyvista.Camera
        cam.position, cam.focal_point, cam.up = position, focal_point, up
        return
    cam.SetPosition(*position)
    cam.SetFocalPoint(*focal_point)
    cam.SetViewUp(*up)

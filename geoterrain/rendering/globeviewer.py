"""The interactive viewer on the globe: seed 001's planetary CDLOD follows the camera.

:class:`GlobeViewerController` works on any PyVista plotter (an offscreen one in the
tests), as the flat viewer's controller does: a camera change re-selects the globe's mesh
for the new eye (:meth:`~geoterrain.globe.Globe.select`, without waiting: payloads not yet
generated are requested and their parents drawn in their place), and a repeating timer
(:meth:`GlobeViewerController.poll`) selects again while payloads are still arriving.

**Floating origin.** VTK's camera and the mesh live in coordinates relative to the eye of
the last selection (float32 mesh, the camera near the origin): after each selection the
origin moves to the new eye and the camera is put back at (0, 0, 0), looking the same way.
The planet's 6 378 km never reach the GPU in float32, so the ground stays still at 2 m.

The camera moves as on a terrain (VTK's terrain interactor style, no roll); the mouse
wheel dollies toward the point looked at, which is kept on the ground. Keys: ``+``/``-``
coarser/finer detail (τ × 2 / ÷ 2), ``x`` wireframe, ``space`` freeze the LOD, ``h`` home,
``s`` screenshot, ``q`` quit. The status line says the detail, the triangles and nodes
drawn, the payloads pending, and where the camera is (longitude, latitude, height above
the ellipsoid).

Examples
--------
>>> import pyvista as pv
>>> from geoterrain.globe import Globe
>>> g = Globe(model="sphere", base="ellipsoid", node_cells=8, sync=True)
>>> p = pv.Plotter(off_screen=True, window_size=(64, 48))
>>> c = GlobeViewerController(p, g, g.camera(0.0, 0.0, 2.0e7, size=(64, 48)))
>>> c.stats["triangles"] > 0
True
>>> p.close()
"""

from __future__ import annotations

import math
import time

import numpy as np

from geoterrain.core.view import View
from geoterrain.rendering.colours import Palette, as_palette
from geoterrain.rendering.globescene import SHADINGS, data_range, globe_mesh

__all__ = ["GlobeViewerController", "show_globe"]

POLL_MS = 50.0  # how often the window looks for payloads that arrived

HELP = "keys: +/- coarser/finer  x wireframe  space freeze  h home  s screenshot  q quit"


class GlobeViewerController:
    """Re-selects the globe's mesh when the camera moves; the scene relative to the eye.

    Parameters
    ----------
    plotter : pyvista.Plotter (interactive or offscreen)
    globe : :class:`~geoterrain.globe.Globe`
    home : the first view (ECEF), :meth:`~geoterrain.globe.Globe.camera` or
        :meth:`~geoterrain.globe.Globe.default_view`
    pixel_error : τ in pixels.
    shading, cmap : as :func:`geoterrain.rendering.globescene.render_globe`'s.
    """

    def __init__(self, plotter, globe, home: View, pixel_error: float = 1.0,
                 shading: str = "normals", cmap: str | Palette = "auto"):
        from geoterrain.exceptions import UsageError

        if shading not in SHADINGS:
            raise UsageError(f"unknown shading {shading!r}; use one of {', '.join(SHADINGS)}")
        self.plotter, self.globe, self.home = plotter, globe, home
        self.pixel_error = float(pixel_error)
        self.shading = shading
        self.palette = as_palette(cmap)
        self.range = data_range(globe)
        self.origin = np.asarray(home.eye, np.float64)  # the floating origin (ECEF)
        self.frozen = self.wireframe = False
        self.selections = 0
        self.stats: dict = {}
        self.mesh = None
        self._moving = False
        self._hud = plotter.add_text("", position="lower_left", font_size=10,
                                     name="globe_status")
        plotter.set_background("white")
        self.go(home)

    # ----------------------------------------------------------------- camera
    def current_view(self) -> View:
        """The plotter's camera as an ECEF :class:`~geoterrain.core.view.View`."""
        cam = self.plotter.camera
        W, H = self.plotter.window_size
        eye = self.origin + np.asarray(cam.position, np.float64)
        look = self.origin + np.asarray(cam.focal_point, np.float64)
        return View(tuple(eye), tuple(look), tuple(cam.up), float(cam.view_angle), (W, H))

    def go(self, view: View) -> None:
        """Move the camera to ``view`` (ECEF) and select for it."""
        self.origin = np.asarray(view.eye, np.float64)
        self._set_camera(np.asarray(view.look_at, np.float64) - self.origin, view.up,
                         view.fov_y_deg)
        self.on_camera_changed(force=True)

    def _set_camera(self, focal: np.ndarray, up, fov: float) -> None:
        cam = self.plotter.camera
        self._moving = True
        try:
            cam.position = (0.0, 0.0, 0.0)
            cam.focal_point = tuple(focal)
            cam.up = tuple(up)
            cam.view_angle = float(fov)
        finally:
            self._moving = False

    def geodetic(self) -> tuple[float, float, float]:
        """The camera's longitude, latitude (degrees) and height above the ellipsoid (m)."""
        lon, lat, h = self.globe.model.to_geodetic(np.asarray(self.current_view().eye))
        return float(np.ravel(lon)[0]), float(np.ravel(lat)[0]), float(np.ravel(h)[0])

    def below_ground(self) -> float | None:
        """How far (m) the camera is under the drawn ground, or None above it."""
        lon, lat, h = self.geodetic()
        ground = float(self.globe.surface.heights(np.array([lon]), np.array([lat]),
                                                  self.globe.max_depth)[0])
        return ground - h if math.isfinite(ground) and h < ground else None

    # -------------------------------------------------------------- selection
    def on_camera_changed(self, *_args, force: bool = False) -> bool:
        """Select the mesh for the camera now (unless frozen); True when it did."""
        if self._moving or (self.frozen and not force):
            return False
        view = self.current_view()
        t0 = time.perf_counter()
        sel = self.globe.select(view, self.pixel_error)
        self.selections += 1
        # the floating origin moves to this eye; the camera back to (0, 0, 0)
        self.origin = np.asarray(sel.origin, np.float64)
        self._set_camera(np.asarray(view.look_at, np.float64) - self.origin, view.up,
                         view.fov_y_deg)
        self._apply(sel, view)
        self.stats = dict(sel.stats, frame_ms=round((time.perf_counter() - t0) * 1e3, 3))
        self._update_hud()
        return True

    def poll(self, *_args) -> bool:
        """Select again while payloads are pending (a repeating timer calls this)."""
        if self.frozen:
            return False
        q = self.globe.queue
        if self.stats.get("pending", 0) or q.queued or q.in_flight or self.stats.get(
                "requested", 0):
            changed = self.on_camera_changed()
            if changed:
                self.plotter.render()
            return changed
        return False

    def _apply(self, sel, view: View) -> None:
        p = self.plotter
        if not sel.triangles:
            if self.mesh is not None:
                p.remove_actor("globe", render=False)
                self.mesh = None
            return
        m = globe_mesh(sel, self.palette, self.range)
        if self.shading == "plain":
            m = m.compute_normals(cell_normals=False, split_vertices=False)
        p.add_mesh(m, scalars="rgb", rgb=True, name="globe", reset_camera=False,
                   smooth_shading=self.shading != "elevation",
                   lighting=self.shading != "elevation",
                   style="wireframe" if self.wireframe else "surface", render=False)
        self.mesh = m
        d = np.linalg.norm(sel.points, axis=1)
        self._moving = True
        try:
            p.camera.clipping_range = (max(float(d.min()) * 0.5, 0.05),
                                       float(d.max()) * 1.01)
        finally:
            self._moving = False

    def _update_hud(self) -> None:
        lon, lat, h = self.geodetic()
        s = self.stats
        where = (f"{lon:.4f}°, {lat:.4f}°, {h / 1e3:,.3f} km" if abs(h) >= 1e4
                 else f"{lon:.5f}°, {lat:.5f}°, {h:,.1f} m")
        below = ""
        if h < 1e5 and (d := self.below_ground()) is not None:
            below = f" UNDER THE GROUND by {d:,.1f} m"
        line = (f"globe, detail {self.pixel_error:g} px: {s.get('triangles', 0):,} triangles, "
                f"{s.get('nodes', 0)} nodes, {s.get('pending', 0)} pending"
                f"{', frozen' if self.frozen else ''} | camera {where}{below}")
        self._hud.SetText(0, line + "\n" + HELP)

    # ------------------------------------------------------------------- keys
    def tau_up(self) -> None:
        self.pixel_error *= 2.0
        self.on_camera_changed(force=True)

    def tau_down(self) -> None:
        self.pixel_error = max(self.pixel_error / 2.0, 1.0 / 64)
        self.on_camera_changed(force=True)

    def toggle_wireframe(self) -> None:
        self.wireframe = not self.wireframe
        self.on_camera_changed(force=True)

    def toggle_freeze(self) -> None:
        self.frozen = not self.frozen
        if not self.frozen:
            self.on_camera_changed(force=True)
        else:
            self._update_hud()

    def reset_view(self) -> None:
        self.go(self.home)

    def screenshot(self, path=None) -> str:
        """Save the window's picture (``globe-<time>.png`` in the working folder)."""
        from geoterrain.rendering.window import draw, write_png

        path = path or f"globe-{time.strftime('%Y%m%d-%H%M%S')}.png"
        write_png(path, draw(self.plotter), True)
        return str(path)

    def bind(self) -> None:
        """Attach the camera observer, the polling timer and the keys to the plotter."""
        p = self.plotter
        p.camera.AddObserver("ModifiedEvent", self.on_camera_changed)
        keys = {"plus": self.tau_up, "equal": self.tau_up, "KP_Add": self.tau_up,
                "minus": self.tau_down, "KP_Subtract": self.tau_down,
                "x": self.toggle_wireframe, "space": self.toggle_freeze,
                "h": self.reset_view, "s": self.screenshot}
        for k, fn in keys.items():
            p.add_key_event(k, fn)
        if p.iren is not None:
            from geoterrain.rendering.viewer_style import mute_style_timers

            p.enable_terrain_style(mouse_wheel_zooms=True)
            mute_style_timers(p.iren.interactor.GetInteractorStyle())
        if p.iren is not None and not p.off_screen:
            p.iren.add_observer("TimerEvent", self.poll)
            p.iren.create_timer(int(POLL_MS), repeating=True)


def show_globe(globe, home: View, pixel_error: float = 1.0, *, shading: str = "normals",
               cmap: str | Palette = "auto", size: tuple[int, int] = (1280, 720)
               ) -> GlobeViewerController:
    """Open an interactive window on ``globe`` from ``home``; the mesh follows the camera.

    Examples
    --------
    >>> from geoterrain.globe import Globe
    >>> g = Globe(["dem.geoterrain"])  # doctest: +SKIP
    >>> show_globe(g, g.default_view())  # doctest: +SKIP
    """
    import pyvista as pv

    p = pv.Plotter(window_size=list(size), title="geoterrain — globe")
    ctl = GlobeViewerController(p, globe, home, pixel_error, shading, cmap)
    ctl.bind()
    p.show()
    return ctl

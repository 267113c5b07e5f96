"""The interactive viewer's key handlers, plain methods (``m`` strategy, ``+``/``-``
coarser/finer, ``g`` morph, ``x`` wireframe, ``c`` colour, ``space`` freeze, ``h`` home,
``t`` timings; :meth:`~geoterrain.rendering.viewer.ViewerController.bind` attaches them).
A mixin of :class:`geoterrain.rendering.viewer.ViewerController`, whose state it changes."""

from __future__ import annotations

import numpy as np

from geoterrain.lod.registry import STRATEGIES, strategy_info

__all__ = ["COLOR_MODES", "ViewerKeys"]

COLOR_MODES = ("shading", "level", "tile")


class ViewerKeys:
    """The controller's key handlers (a mixin)."""

    def _refresh(self) -> None:
        if self.on_camera_changed(force=True) is False and self._executor is not None:
            self.pending = True
        self.plotter.render()

    def next_strategy(self) -> None:
        """Key ``m``: the next LOD strategy."""
        k = STRATEGIES.index(self.strategy) if self.strategy in STRATEGIES else -1
        self.strategy = STRATEGIES[(k + 1) % len(STRATEGIES)]
        self._refresh()

    def toggle_telemetry(self) -> None:
        """Key ``t``: the engine's figures (selection and texture times, tiles decoded) in
        the status line, or not."""
        self.telemetry = not self.telemetry
        self._update_hud()
        self.plotter.render()

    def tau_up(self) -> None:
        """Key ``+``: τ × 2 (coarser)."""
        self.pixel_error = min(self.pixel_error * 2, 256.0)
        self._refresh()

    def tau_down(self) -> None:
        """Key ``-``: τ / 2 (finer)."""
        self.pixel_error = max(self.pixel_error / 2, 0.125)
        self._refresh()

    def toggle_wireframe(self) -> None:
        """Key ``x``: wireframe on/off."""
        self.wireframe = not self.wireframe
        self._apply_style()
        self.plotter.render()

    def next_color_mode(self) -> None:
        """Key ``c``: colour by shading, LOD level or tile."""
        self.color_mode = COLOR_MODES[(COLOR_MODES.index(self.color_mode) + 1) % len(COLOR_MODES)]
        self._apply_style()
        self._update_hud()
        self.plotter.render()

    def toggle_morph(self) -> None:
        """Key ``g``: geomorphing on/off, for the strategies that morph (its default:
        off for rtin, chunked and geomipmap, on for cdlod)."""
        self.morph = not self._morphing()
        self._refresh()

    def _morphing(self) -> bool:
        """Whether the current strategy morphs now (the choice, else its default)."""
        return (self.morph if self.morph is not None
                else strategy_info(self.strategy).morph_default)

    def toggle_freeze(self) -> None:
        """Key ``space``: keep the current selection while the camera moves."""
        self.frozen = not self.frozen
        if not self.frozen:
            self.on_camera_changed(force=True)
        self._update_hud()
        self.plotter.render()

    def _go_home(self) -> None:
        self.scene.set_camera(self.home)
        # the terrain style turns about the camera's view-up: make it the vertical, so
        # drags never roll (the same camera: VTK orthogonalises it as View.basis does)
        cam = self.plotter.camera
        d = np.subtract(cam.focal_point, cam.position)
        if np.linalg.norm(d[:2]) > 1e-9 * np.linalg.norm(d):
            cam.up = (0.0, 0.0, 1.0)

    def reset_view(self) -> None:
        """Key ``h``: back to the overview."""
        self._go_home()
        self._refresh()

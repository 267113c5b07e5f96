"""The interactive viewer's picture beyond the terrain: the surface's style (shading,
wireframe, colour by LOD level or tile), the status line, the colour bar, level legend and
north arrow, and the screenshot key. A mixin of
:class:`geoterrain.rendering.viewer.ViewerController`, whose state it reads; the overlays'
VTK objects are :mod:`geoterrain.rendering.viewer_style`'s."""

from __future__ import annotations

import time

import numpy as np

from geoterrain.lod.registry import strategy_info
from geoterrain.rendering.viewer_style import Compass, cell_colours, colour_bar, level_legend

__all__ = ["HELP", "ViewerHud"]

HELP = ("keys: m strategy  +/- coarser/finer  g morph  x wireframe  c colour  space freeze  "
        "h home  s screenshot  t timings  q quit")


class ViewerHud:
    """The controller's style, status line, legends and screenshots (a mixin)."""

    def _apply_style(self) -> None:
        actor = self.scene.actor
        if actor is None:
            return
        prop = actor.GetProperty()
        prop.SetRepresentationToWireframe() if self.wireframe else prop.SetRepresentationToSurface()
        mesh, mapper = self.scene.mesh, actor.GetMapper()
        if getattr(self, "_levels", None) is not None:  # a legend for the colours shown
            self._levels.SetVisibility(self.color_mode == "level")
            if self._bar is not None:
                self._bar.SetVisibility(self.color_mode == "shading")
        if self.color_mode == "shading" or mesh.n_cells == 0:
            mapper.ScalarVisibilityOff()
            actor.SetTexture(self.scene.texture)
            prop.SetLighting(self.scene.texture is None)
            return
        vals, lut = cell_colours(self.scene.selection, self.color_mode, self.terrain.grid)
        mesh.cell_data["_color"] = vals
        mesh.set_active_scalars("_color", preference="cell")
        actor.SetTexture(None)
        rng = lut.scalar_range
        mapper.SetLookupTable(lut)
        mapper.SetScalarModeToUseCellData()
        mapper.SetScalarRange(*rng)
        mapper.ScalarVisibilityOn()
        prop.SetLighting(True)

    def _update_hud(self) -> None:
        s = self.stats
        morph = ", morphing" if self._morphing() and strategy_info(self.strategy).morphs else ""
        doing = (" · updating the view..." if self.busy and not self.refining
                 else " · sharpening textures..." if self.refining else "")
        line = (f"{self.strategy}{morph} · detail {self.pixel_error:g} px · "
                f"{s.get('triangles', 0):,} triangles · frame {self.frame_ms:.0f} ms"
                + (" · frozen" if self.frozen else "")
                + ("" if self.color_mode == "shading" else f" · coloured by {self.color_mode}")
                + doing)
        lines = [line]
        if self.telemetry:
            lines.append(f"τ {self.pixel_error:g} px · select {s.get('select_ms', 0.0):.0f} ms"
                         f" · textures {self.scene.texture_stats.get('texture_ms', 0.0):.0f} ms"
                         f" ({self.scene.texture_stats.get('textures_built', 0)} shaded) · "
                         f"tiles decoded {s.get('tiles_decoded', 0)} · UI "
                         f"{getattr(self, 'ui_ms', 0.0):.0f} ms")
        scale = self._metres_per_pixel()
        extra = f"1 px = {_length(scale)} at the view centre" if scale else ""
        if self.message:
            extra = (extra + "   " if extra else "") + self.message
        if extra:
            lines.append(extra)
        self._hud.SetText(2, "\n".join([*lines, HELP] if self.keys else lines))
        if getattr(self, "_compass", None) is not None:
            self._compass.update(self.current_view())

    def _metres_per_pixel(self) -> float:
        c = self.plotter.camera
        d = float(np.linalg.norm(np.subtract(c.position, c.focal_point)))
        H = float(self.plotter.window_size[1]) or 1.0
        return 2.0 * d * np.tan(np.radians(float(c.view_angle)) / 2.0) / H

    def _legend(self, cmap) -> None:
        """The colour bar (metres, the texture's own colours), the level legend (shown while
        the triangles are coloured by level) and the north arrow."""
        self._compass = Compass(self.plotter)
        self._bar = self._levels = None
        if self.scene.shading != "plain":
            self._bar = colour_bar(self.terrain, cmap)
            self.plotter.add_actor(self._bar, name="colour-bar", reset_camera=False)
        self._levels = level_legend(self.terrain.grid)
        self._levels.SetVisibility(False)
        self.plotter.add_actor(self._levels, name="level-legend", reset_camera=False)

    def screenshot(self, path=None) -> str:
        """Key ``s``: save the window, overlays included, as a PNG (a new name each time:
        ``geoterrain-<time>-<n>.png`` in the working folder); the status line says where."""
        from pathlib import Path

        self.settle()  # the saved picture is the anti-aliased one
        self.screenshots += 1
        if path is None:
            path = Path.cwd() / time.strftime(f"geoterrain-%Y%m%d-%H%M%S-{self.screenshots}.png")
        self.plotter.screenshot(str(path))
        self.message = f"saved {path}"
        self._update_hud()
        self.plotter.render()
        return str(path)


def _length(m: float) -> str:
    """A length for the status line: 0.42 m, 12.3 m, 1.25 km."""
    return f"{m / 1000:.3g} km" if m >= 1000 else f"{m:.3g} m"

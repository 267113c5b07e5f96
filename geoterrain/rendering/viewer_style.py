"""The interactive window's VTK pieces: the interactor style, its timers, the colour
bar, and the per-triangle colours of the viewer's ``c`` key (LOD level, tile).

Kept apart from :mod:`geoterrain.rendering.viewer`, whose controller decides *when* to select,
texture and draw; this module only builds what VTK shows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.colours import Palette, as_palette, colorbar_map

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def terrain_style():
    """The interactor style of the viewer: VTK's terrain style (azimuth about the
    vertical, elevation, no roll), so the horizon stays level.

    Examples
    --------
    >>> terrain_style().GetClassName()
    'vtkInteractorStyleTerrain'
    """
    from vtkmodules.vtkInteractionStyle import vtkInteractorStyleTerrain

    return vtkInteractorStyleTerrain()


def mute_style_timers(style) -> None:
    """Keep the window's timers from steering the camera.

    A VTK interactor style answers a timer event by repeating its current interaction:
    mid-drag, with the mouse still, ``vtkInteractorStyleTerrain`` rotates by the last
    mouse step again on every tick, so the viewer's polling timers would spin the view.
    An observer of the style's own ``TimerEvent`` takes the event instead (the style then
    skips ``OnTimer``); mouse moves still steer as before.

    Examples
    --------
    >>> mute_style_timers(terrain_style())
    """
    if style is not None:
        style.AddObserver("TimerEvent", lambda *_args: None)


def colour_bar(terrain: TerrainLike, cmap: str | Palette):
    """A ``vtkScalarBarActor`` of the terrain's elevation colours in metres, on an
    opaque box at the window's right edge.

    Examples
    --------
    >>> colour_bar(t, "auto").GetTitle()
    'elevation (m)'
    """
    import pyvista as pv
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    from geoterrain.rendering.textures import elevation_range, height_tolerance

    cm, (lo, hi) = colorbar_map(as_palette(cmap), elevation_range(terrain),
                                tolerance=height_tolerance(terrain))
    lut = pv.LookupTable(cm)
    lut.scalar_range = (lo, hi)
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("elevation (m)")
    bar.SetLabelFormat("%.0f")
    bar.SetNumberOfLabels(5)
    bar.UnconstrainedFontSizeOn()
    bar.DrawBackgroundOn()
    bar.GetBackgroundProperty().SetColor(1.0, 1.0, 1.0)
    bar.GetBackgroundProperty().SetOpacity(0.85)
    for tp, size in ((bar.GetLabelTextProperty(), 11), (bar.GetTitleTextProperty(), 12)):
        tp.SetColor(0.1, 0.1, 0.1)
        tp.SetFontSize(size)
        tp.ShadowOff()
        tp.BoldOff()
        tp.ItalicOff()
    bar.SetPosition(0.90, 0.25)
    bar.SetWidth(0.08)
    bar.SetHeight(0.5)
    return bar


def cell_colours(selection, mode: str, grid) -> tuple[np.ndarray, object]:
    """Per-triangle values and a lookup table for the ``c`` key's modes: ``level`` (the
    triangle's pyramid level) or ``tile`` (a colour per stored tile footprint).

    Examples
    --------
    >>> from geoterrain import lod
    >>> from geoterrain.core.view import View
    >>> sel = lod.select(t, View((0, -800, 400), (0, 0, 0)), 2.0)
    >>> vals, lut = cell_colours(sel, "tile", t.grid)
    >>> len(vals) == sel.mesh.n_cells, lut.scalar_range
    (True, (0.0, 19.0))
    """
    import matplotlib
    import pyvista as pv

    lvl = np.asarray(selection.mesh.cell_data["level"]).astype(np.int64)
    if mode == "level":
        vals, rng = lvl.astype(np.float64), (0.0, float(grid.top_level))
    else:
        ij = np.asarray(selection.mesh.point_data["grid_ij"]).astype(np.int64)
        f = selection.faces
        shift = grid.t + lvl
        i0, j0 = ij[f, 0].min(1) >> shift, ij[f, 1].min(1) >> shift
        vals, rng = ((i0 * 7919 + j0 * 104729 + lvl * 31) % 20).astype(np.float64), (0.0, 19.0)
    lut = pv.LookupTable(matplotlib.colormaps["tab10" if mode == "level" else "tab20"])
    lut.scalar_range = rng
    return vals, lut

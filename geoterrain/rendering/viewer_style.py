"""The interactive window's VTK pieces: the interactor style, its timers, the colour
bar, the level legend, the north arrow, and the per-triangle colours of the viewer's ``c``
key (LOD level, tile).

Kept apart from :mod:`geoterrain.rendering.viewer`, whose controller decides *when* to select,
texture and draw; this module only builds what VTK shows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.rendering.colours import Palette, colorbar_map, water_swatch

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
    opaque box at the window's right edge: labelled at the pictures' nice ticks (0, 500,
    1000, …), over the data's range only, with the water as a swatch below it where the
    data has water but no depth (:func:`~geoterrain.rendering.colours.water_swatch`).

    Examples
    --------
    >>> bar = colour_bar(t, "auto")
    >>> bar.GetTitle(), bar.GetUseCustomLabels()
    ('elevation (m)', True)
    """
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkDoubleArray
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    from geoterrain.rendering.overlays import _ticks
    from geoterrain.rendering.textures import (
        elevation_range,
        height_tolerance,
        terrain_palette,
    )

    pal, rng = terrain_palette(terrain, cmap), elevation_range(terrain)
    tol = height_tolerance(terrain)
    cm, (lo, hi) = colorbar_map(pal, rng, tolerance=tol)
    lut = pv.LookupTable(cm)
    lut.scalar_range = (lo, hi)
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("elevation (m)")
    bar.SetLabelFormat("%.0f")
    ticks = vtkDoubleArray()
    for v, _ in _ticks(lo, hi):
        ticks.InsertNextValue(v)
    bar.SetCustomLabels(ticks)
    bar.SetUseCustomLabels(True)
    swatch = water_swatch(pal, rng, tol)
    if swatch is not None:  # water without depth: a swatch, not a range
        lut.SetBelowRangeColor(*swatch, 1.0)
        lut.SetUseBelowRangeColor(True)
        bar.SetDrawBelowRangeSwatch(True)
        bar.SetBelowRangeAnnotation("water")
    _style_bar(bar)
    bar.SetPosition(0.90, 0.25)
    bar.SetWidth(0.08)
    bar.SetHeight(0.5)
    return bar


def _style_bar(bar) -> None:
    """A scalar bar in the viewer's look: a white, slightly transparent box, dark plain
    text at fixed sizes."""
    bar.UnconstrainedFontSizeOn()
    bar.DrawBackgroundOn()
    bar.GetBackgroundProperty().SetColor(1.0, 1.0, 1.0)
    bar.GetBackgroundProperty().SetOpacity(0.85)
    for tp, size in ((bar.GetLabelTextProperty(), 11), (bar.GetTitleTextProperty(), 12),
                     (bar.GetAnnotationTextProperty(), 11)):
        tp.SetColor(0.1, 0.1, 0.1)
        tp.SetFontSize(size)
        tp.ShadowOff()
        tp.BoldOff()
        tp.ItalicOff()


def level_colours(top: int) -> np.ndarray:
    """The colour (RGB in [0, 1]) of each detail level 0 … ``top`` (matplotlib's tab10,
    repeating): the ``c`` key's level colours and their legend's.

    Examples
    --------
    >>> level_colours(3).shape
    (4, 3)
    """
    import matplotlib

    tab = matplotlib.colormaps["tab10"].colors
    return np.array([tab[k % len(tab)] for k in range(top + 1)], np.float64)


def _level_lut(top: int):
    """A lookup table mapping level k (a float k) to :func:`level_colours` ``[k]``."""
    import pyvista as pv

    cols = level_colours(top)
    lut = pv.LookupTable()
    lut.n_values = top + 1
    for k, c in enumerate(cols):
        lut.SetTableValue(k, *c, 1.0)
    lut.scalar_range = (-0.5, top + 0.5)
    return lut


def level_legend(grid):
    """A legend of the detail levels' colours (``vtkScalarBarActor`` of swatches, one per
    level: 0 is the full resolution, each next level half as fine), on an opaque box at
    the window's right edge, where the elevation colour bar sits.

    Examples
    --------
    >>> bar = level_legend(t.grid)
    >>> bar.GetLookupTable().GetNumberOfAnnotatedValues() == t.grid.top_level + 1
    True
    """
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    top = grid.top_level
    lut = _level_lut(top)
    lut.SetIndexedLookup(True)
    for k in range(top + 1):
        lut.SetAnnotation(float(k), f"{k}" + (" (full res.)" if k == 0 else f" (1:{1 << k})"))
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("detail level")
    _style_bar(bar)
    bar.SetPosition(0.86, 0.25)
    bar.SetWidth(0.12)
    bar.SetHeight(0.5)
    return bar


class Compass:
    """A north arrow in the window's top-right corner that turns with the camera (the
    direction of north at the view's target, as the pictures' arrow): a ring, an arrow
    and an "N" at its tip, drawn in screen space, so nothing in the scene hides it.

    Examples
    --------
    >>> import pyvista as pv
    >>> from geoterrain.core.view import View
    >>> p = pv.Plotter(off_screen=True, window_size=(320, 240))
    >>> c = Compass(p)
    >>> c.update(View((0, -100, 100), (0, 0, 0), size=(320, 240)))
    >>> c.direction.round(3).tolist()  # north is up on the screen
    [0.0, 1.0]
    >>> p.close()
    """

    RADIUS = 26.0  # pixels
    MARGIN = 12.0

    def __init__(self, plotter):
        import pyvista as pv
        from vtkmodules.vtkRenderingCore import vtkActor2D, vtkPolyDataMapper2D, vtkTextActor

        self.plotter = plotter
        self.direction = np.array([0.0, 1.0])
        self.poly = pv.PolyData()
        mapper = vtkPolyDataMapper2D()
        mapper.SetInputData(self.poly)
        self.actor = vtkActor2D()
        self.actor.SetMapper(mapper)
        self.actor.GetProperty().SetColor(0.1, 0.1, 0.1)
        self.actor.GetProperty().SetLineWidth(2.0)
        self.text = vtkTextActor()
        self.text.SetInput("N")
        tp = self.text.GetTextProperty()
        tp.SetFontSize(14)
        tp.BoldOn()
        tp.SetColor(0.1, 0.1, 0.1)
        tp.SetJustificationToCentered()
        tp.SetVerticalJustificationToCentered()
        tp.SetBackgroundColor(1.0, 1.0, 1.0)
        tp.SetBackgroundOpacity(0.85)
        plotter.add_actor(self.actor, name="compass", reset_camera=False)
        plotter.add_actor(self.text, name="compass-n", reset_camera=False)

    def update(self, view) -> None:
        """Turn the arrow to north as ``view`` sees it (kept as it was where north has no
        direction on the screen, straight along the line of sight)."""
        from geoterrain.rendering.overlays import north_direction

        d = north_direction(view)
        if d is not None:
            self.direction = np.array([d[0], -d[1]])  # display coordinates: y up
        W, H = self.plotter.window_size
        R = self.RADIUS
        c = np.array([W - self.MARGIN - R, H - self.MARGIN - R - 18.0])
        d = self.direction
        n = np.array([-d[1], d[0]])
        ring = [c + R * np.array([np.cos(a), np.sin(a)]) for a in
                np.linspace(0, 2 * np.pi, 33)]
        tip, tail = c + 0.75 * R * d, c - 0.75 * R * d
        head = [tip, c + 0.25 * R * d + 0.3 * R * n, c + 0.25 * R * d - 0.3 * R * n]
        pts = np.array([*ring, tail, tip, *head], np.float64)
        pts = np.column_stack([pts, np.zeros(len(pts))])
        k = len(ring)
        lines = np.concatenate([[k, *range(k)], [2, k, k + 1]])
        polys = np.array([3, k + 2, k + 3, k + 4])
        self.poly.points = pts
        self.poly.lines = lines
        self.poly.faces = polys
        label = c + (R + 10.0) * d
        self.text.SetPosition(*label)


def cell_colours(selection, mode: str, grid) -> tuple[np.ndarray, object]:
    """Per-triangle values and a lookup table for the ``c`` key's modes: ``level`` (the
    triangle's pyramid level, :func:`level_colours`, as :func:`level_legend` shows them)
    or ``tile`` (a colour per stored tile footprint).

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
        return lvl.astype(np.float64), _level_lut(grid.top_level)
    ij = np.asarray(selection.mesh.point_data["grid_ij"]).astype(np.int64)
    f = selection.faces
    shift = grid.t + lvl
    i0, j0 = ij[f, 0].min(1) >> shift, ij[f, 1].min(1) >> shift
    vals, rng = ((i0 * 7919 + j0 * 104729 + lvl * 31) % 20).astype(np.float64), (0.0, 19.0)
    lut = pv.LookupTable(matplotlib.colormaps["tab20"])
    lut.scalar_range = rng
    return vals, lut

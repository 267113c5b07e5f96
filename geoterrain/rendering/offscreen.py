"""An offscreen render window on VTK alone, set up as PyVista's ``Plotter`` sets its own.

The offscreen render (``geoterrain render``, :func:`geoterrain.rendering.scene.render`,
orbits and fly-throughs) draws through :class:`OffscreenPlotter`: a render window, one
renderer, its camera and lights, and the terrain's (and water's) actors, each given the
settings PyVista's ``Plotter(off_screen=True)`` and ``add_mesh`` give them (MSAA with
PyVista's 8 samples, the light kit, flat interpolation, the texture's direct colours, the
mapper's interpolation of scalars before mapping), so the pictures are the same bytes
(``tests/rendering/test_offscreen.py`` draws the same views both ways). It imports only
``vtkmodules`` submodules: a cold render does not pay PyVista's plotting modules (nor the
``matplotlib.pyplot`` they import). The interactive viewer and notebooks keep PyVista.

Examples
--------
>>> p = OffscreenPlotter((320, 240))
>>> p.render_window.GetSize()
(320, 240)
>>> p.close()
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - VTK's OpenGL classes behind the factory
from vtkmodules.vtkRenderingCore import (
    vtkActor,
    vtkDataSetMapper,
    vtkLight,
    vtkLightKit,
    vtkRenderer,
    vtkRenderWindow,
    vtkTexture,
)


def multi_samples() -> int:
    """PyVista's default multisampling (its theme's ``multi_samples``: 8, or the
    ``PYVISTA_MULTI_SAMPLES`` environment variable)."""
    try:
        return int(os.environ.get("PYVISTA_MULTI_SAMPLES", "8"))
    except ValueError:
        return 8


def colour(rgb: Sequence[float]) -> tuple[float, float, float]:
    """``rgb`` (floats in [0, 1]) rounded to bytes, as PyVista gives every colour to VTK.

    Examples
    --------
    >>> colour((0.86, 0.90, 0.95))[0] == 219 / 255
    True
    """
    return tuple(round(255 * float(c)) / 255.0 for c in rgb[:3])


#: PyVista's default colour of a mesh ("lightblue")
DEFAULT_COLOUR = (173 / 255, 216 / 255, 230 / 255)


class OffscreenPlotter:
    """The part of a PyVista ``Plotter`` the offscreen scene uses, on plain VTK objects.

    ``render_window``, ``renderer``, ``camera``, :meth:`set_background`, :meth:`render`,
    :meth:`disable_anti_aliasing`, :meth:`close`; actors are made by :func:`terrain_actor`
    and :func:`water_actor`.
    """

    def __init__(self, size: Sequence[int], samples: int | None = None):
        rw = vtkRenderWindow()
        rw.SetMultiSamples(0)
        rw.SetBorders(True)
        ren = vtkRenderer()
        ren.SetAutomaticLightCreation(False)
        rw.AddRenderer(ren)
        rw.SetOffScreenRendering(1)
        rw.SetSize(int(size[0]), int(size[1]))
        rw.SetMultiSamples(multi_samples() if samples is None else int(samples))
        vtkLightKit().AddLightsToRenderer(ren)
        lights = ren.GetLights()
        lights.InitTraversal()
        for _ in range(lights.GetNumberOfItems()):  # their colours in bytes, as PyVista's
            light = lights.GetNextItem()
            light.SetAmbientColor(*colour(light.GetAmbientColor()))
            light.SetDiffuseColor(*colour(light.GetDiffuseColor()))
            light.SetSpecularColor(*colour(light.GetSpecularColor()))
        self.render_window, self.renderer = rw, ren
        self._first = True

    @property
    def camera(self):
        return self.renderer.GetActiveCamera()

    @property
    def window_size(self) -> list[int]:
        return list(self.render_window.GetSize())

    def set_background(self, color: Sequence[float]) -> None:
        self.renderer.SetBackground(*colour(color))

    def disable_anti_aliasing(self) -> None:
        self.render_window.SetMultiSamples(0)

    def remove_all_lights(self) -> None:
        self.renderer.RemoveAllLights()

    def _on_first_render_request(self) -> None:
        """(PyVista's name) The camera is always set before a frame: nothing to do."""
        self._first = False

    def render(self) -> None:
        self.render_window.Render()

    def close(self) -> None:
        rw = self.render_window
        if rw is not None:
            rw.Finalize()
            self.render_window = None


def _flat_actor(mesh, color: Sequence[float]):
    """A mapper, actor and property as PyVista's ``add_mesh`` makes them for ``mesh``:
    scalars interpolated before mapping, flat shading, point size 5, ``color``."""
    mapper = vtkDataSetMapper()
    mapper.SetInputData(mesh)
    mapper.SetInterpolateScalarsBeforeMapping(True)
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*colour(color))
    prop.SetInterpolationToFlat()
    prop.SetPointSize(5.0)
    return mapper, actor, prop


def terrain_actor(plotter: OffscreenPlotter, mesh, color: Sequence[float], lighting: bool,
                  texture=None) -> vtkActor:
    """The terrain's actor as ``add_mesh(mesh, color=…, lighting=…, smooth_shading=False,
    show_scalar_bar=False)`` makes it (its scalars not shown), added to the renderer."""
    mapper, actor, prop = _flat_actor(mesh, color)
    mapper.ScalarVisibilityOff()
    prop.SetSpecularPower(100.0)
    prop.SetLighting(bool(lighting))
    if texture is not None:
        actor.SetTexture(texture)
    plotter.renderer.AddActor(actor)
    return actor


def texture(image=None, interpolate: bool = True, mipmap: bool = False) -> vtkTexture:
    """A texture as ``pyvista.Texture`` makes one: direct colours, no repeat."""
    tex = vtkTexture()
    if image is not None:
        tex.SetInputDataObject(image)
    tex.SetColorModeToDirectScalars()
    tex.SetInterpolate(bool(interpolate))
    tex.SetMipmap(bool(mipmap))
    tex.SetRepeat(False)
    return tex


def water_actor(plotter: OffscreenPlotter, mesh, light_position: Sequence[float]) -> vtkActor:
    """The water's actor as :func:`geoterrain.rendering.water.add_water` makes it through
    PyVista: the lights replaced by one scene light at ``light_position`` (towards the
    origin), the mesh's ``rgba`` point colours shown directly, lit, flat."""
    ren = plotter.renderer
    ren.RemoveAllLights()
    light = vtkLight()
    light.SetLightTypeToSceneLight()
    light.SetPosition(*(float(c) for c in light_position))
    light.SetFocalPoint(0.0, 0.0, 0.0)
    light.SetIntensity(1.0)
    ren.AddLight(light)
    mesh.GetPointData().SetActiveScalars("rgba")
    # PyVista's default colour: the scalars replace its ambient and diffuse parts, not
    # the specular glint's
    mapper, actor, prop = _flat_actor(mesh, DEFAULT_COLOUR)
    mapper.SetScalarModeToUsePointData()
    mapper.SetColorModeToDirectScalars()
    mapper.ScalarVisibilityOn()
    prop.SetAmbient(0.45)
    prop.SetDiffuse(0.55)
    prop.SetSpecular(0.5)
    prop.SetSpecularPower(60.0)
    ren.AddActor(actor)
    return actor

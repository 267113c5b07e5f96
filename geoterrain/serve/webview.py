"""`geoterrain view --web`: the interactive viewer in a browser tab, through trame.

The desktop viewer's controller (:class:`geoterrain.rendering.viewer.ViewerController`:
the same LOD selection, shading, overlays and keys' actions) drives an offscreen PyVista
plotter; trame (trame-vtk's remote view) streams its pictures to the page and sends the
mouse back to the plotter's interactor, which moves the camera as on a terrain (VTK's
terrain style: no roll). The LOD follows the camera: each camera change re-selects
(throttled to one selection per ``throttle_ms`` while the mouse moves, and once more when
it is released), and the status line at the foot of the page (``#status``) says the strategy, τ, the
triangles drawn and the selection's time. Rendering is on the server (no WebGL needed in
the browser, any GPU or none on the server).

Examples
--------
>>> status_line({"triangles": 12345, "select_ms": 8.2}, "rtin", 1.0)
'rtin · τ 1 px · 12,345 triangles · select 8 ms'
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["status_line", "web_view"]


def status_line(stats: dict, strategy: str, tau: float) -> str:
    """The page's status: strategy, τ, triangles and the selection's time."""
    return (f"{strategy} · τ {tau:g} px · {int(stats.get('triangles', 0)):,} triangles · "
            f"select {stats.get('select_ms', 0.0):.0f} ms")


def web_view(terrain: TerrainLike, *, port: int = 8080, bind: str = "127.0.0.1",
             strategy: str | None = None, pixel_error: float = 1.0,
             shading: str = "normals", cmap="auto", light=None, drape=None,
             occlusion: bool = True, morph: bool | None = None,
             size: tuple[int, int] = (1280, 720), throttle_ms: float = 150.0,
             on_ready: Callable[[str], None] | None = None) -> None:
    """Serve the interactive viewer of ``terrain`` at ``http://BIND:PORT/`` until
    interrupted; ``on_ready(url)`` is called once the server listens (``port`` 0: any
    free port)."""
    from trame.app import get_server
    from trame.ui.html import DivLayout
    from trame.widgets import html
    from trame.widgets import vtk as vtk_widgets
    from vtkmodules.vtkInteractionStyle import vtkInteractorStyleTerrain
    from vtkmodules.vtkRenderingUI import vtkGenericRenderWindowInteractor

    from geoterrain.lod.registry import DEFAULT
    from geoterrain.rendering.viewer import ViewerController
    from geoterrain.rendering.window import pyvista_plotter  # offscreen, EGL without a display

    strategy = strategy or DEFAULT
    p = pyvista_plotter(tuple(size), "none")
    ctl = ViewerController(p, terrain, strategy, pixel_error, shading, cmap,
                           throttle_ms=throttle_ms, background=False, light=light,
                           drape=drape, occlusion=occlusion, morph=morph, keys=False)
    iren = vtkGenericRenderWindowInteractor()  # no window system: trame feeds it events
    iren.SetRenderWindow(p.render_window)
    iren.SetInteractorStyle(vtkInteractorStyleTerrain())
    iren.EnableRenderOff()  # trame renders and sends the pictures

    server = get_server(f"geoterrain-{id(p)}", client_type="vue3")
    state, ctrl = server.state, server.controller
    state.status = status_line(ctl.stats, ctl.strategy, ctl.pixel_error)
    state.trame__title = f"geoterrain · {terrain.path.name}"

    def show_status() -> None:
        state.status = status_line(ctl.stats, ctl.strategy, ctl.pixel_error)
        state.selections = ctl.selections
        state.flush()

    def on_update(final: bool) -> None:  # a selection during the drag, or its end
        show_status()
        if final:
            ctrl.view_update()

    ctl.follow(iren, on_update)
    state.selections = ctl.selections

    with DivLayout(server) as layout:
        layout.root.style = "position:fixed;inset:0;margin:0;overflow:hidden"
        html.Div("{{ status }}", id="status",
                 style="position:absolute;bottom:8px;left:8px;z-index:9;padding:4px 8px;"
                       "background:rgba(255,255,255,.9);font:14px system-ui,sans-serif;"
                       "border-radius:4px")
        html.Div("{{ selections }}", id="selections", style="display:none")
        view = vtk_widgets.VtkRemoteView(p.render_window, interactive_ratio=1,
                                         still_quality=90, interactive_quality=70,
                                         style="position:absolute;inset:0")
        ctrl.view_update = view.update

    def ready(**_kw) -> None:
        host = f"[{bind}]" if ":" in bind else bind
        if on_ready is not None:
            on_ready(f"http://{host}:{server.port}/")

    def bind_routes(wslink_server) -> None:
        # trame's page first asks a session launcher (POST paraview/) where its websocket
        # is, then falls back to ws://host/ws: answer it, so the page makes no failed
        # request
        from aiohttp import web

        async def launcher(_request):
            return web.json_response({"sessionURL": "ws://USE_HOST/ws"})

        wslink_server.app.router.add_post("/paraview/", launcher)

    ctrl.on_server_bind.add(bind_routes)
    ctrl.on_server_ready.add(ready)
    try:
        server.start(port=port, host=bind, open_browser=False, show_connection_info=False,
                     disable_logging=True, timeout=0)
    finally:
        ctl.close()
        p.close()

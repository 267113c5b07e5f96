"""`geoterrain view`: an interactive window whose level of detail follows the camera."""

from __future__ import annotations

from pathlib import Path

import click

from geoterrain.cli.globe import camera_option, globe_flag
from geoterrain.cli.options import (
    SIZE,
    StageBar,
    colour_options,
    drape_options,
    light_and_drape,
    light_options,
    morph_option,
    occlusion_option,
    palette,
    pixel_error_option,
    strategy_option,
    vertical_exaggeration_option,
)

#: the options `view --globe` takes (the others are the flat viewer's)
GLOBE_OPTIONS = {"globe", "geo_camera", "pixel_error", "vertical_exaggeration", "shading",
                 "cmap", "clim", "water_level", "size"}


@click.command("view")
@click.argument("sources", metavar="SOURCE...", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False))
@globe_flag
@camera_option
@strategy_option
@occlusion_option
@morph_option
@pixel_error_option
@vertical_exaggeration_option
@click.option("--shading", type=click.Choice(["normals", "elevation", "plain"]),
              default="normals", show_default=True)
@colour_options
@light_options
@drape_options
@click.option("--size", type=SIZE, default="1280x720", show_default=True,
              help="Window WIDTHxHEIGHT.")
@click.option("--rebuild", is_flag=True, help="Preprocess the DEM again even if cached.")
@click.option("--web", is_flag=True,
              help="Serve the viewer as a web page (trame; rendered on this machine, no "
                   "display needed): open the URL printed on the first line.")
@click.option("--port", type=click.IntRange(0, 65535), default=8080, show_default=True,
              help="--web: TCP port (0: any free one).")
@click.option("--bind", default="127.0.0.1", show_default=True,
              help="--web: address to listen on (0.0.0.0: your network).")
@click.pass_context
def command(ctx, sources, globe, geo_camera, strategy, occlusion, morph, pixel_error,
            vertical_exaggeration, shading, cmap, clim, water_level, water,
            sun, hillshade, shadows, ambient_occlusion, drape_path, drape_opacity,
            size, rebuild, web, port, bind):
    """Open SOURCE (a store or a DEM) in an interactive 3-D window.

    A DEM is preprocessed first into a store in the cache folder
    ($XDG_CACHE_HOME/geoterrain, default ~/.cache/geoterrain; never beside your
    data), keyed by the DEM's path, size and date; the path is printed and the
    store is reused next time (--rebuild makes it again).

    \b
    Keys:
      m      next LOD strategy
      + / -  coarser / finer detail (pixel error × 2 / ÷ 2)
      g      geomorphing on/off (rtin, chunked, geomipmap, cdlod)
      x      wireframe
      c      colour by shading / LOD level / tile
      space  freeze the LOD (fly around to inspect culling and refinement)
      s      save a screenshot (the status line says where)
      t      show or hide the engine's timings in the status line
      h      home view;  q  quit

    With --web the same viewer runs in a browser tab (PyVista's trame backend:
    `pip install 'geoterrain[web]'`): the pictures are rendered here and streamed, the
    mouse moves the camera and the LOD follows it; the status line says the strategy, the
    detail in pixels and the triangles drawn. Useful on a remote machine or a server
    without a display (forward the port, e.g. ssh -L 8080:127.0.0.1:8080).

    \b
    Examples:
      geoterrain view dem.geoterrain
      geoterrain view srtm.tif --strategy chunked --pixel-error 2
      geoterrain view dem.geoterrain --sun 250,20 --shadows
      geoterrain view dem.geoterrain --web --port 8080
      geoterrain view --globe world.geoterrain japan.geoterrain
      geoterrain view --globe japan.geoterrain --camera 138.73,35.36,12000,0,-20

    With --globe the stores (any number) are drawn on the WGS 84 globe and the detail
    follows the camera over the whole planet (keys: +/- detail, x wireframe, space
    freeze, h home, s screenshot, q quit); --camera LON,LAT,HEIGHT[,HEADING[,PITCH]]
    places the first view (default: all the stores framed from above).
    """
    import geoterrain
    from geoterrain.exceptions import GeoterrainError
    from geoterrain.preprocessing.pipeline import cached_store_path, ensure_store
    from geoterrain.rendering.viewer import show
    from geoterrain.store.schema import is_store

    quiet = (ctx.obj or {}).get("quiet", False)
    if globe:
        from geoterrain.cli import globe as G

        G.refuse_options(ctx, GLOBE_OPTIONS, "view --globe")
        return G.view(ctx, sources, geo_camera, size, pixel_error, vertical_exaggeration,
                      shading, palette(cmap, clim, water_level))
    from geoterrain.exceptions import UsageError

    if geo_camera is not None:
        raise UsageError("--camera LON,LAT,HEIGHT places the camera on the globe: add "
                         "--globe")
    if len(sources) > 1:
        raise UsageError(f"the flat viewer opens one store, got {len(sources)}; open "
                         "several on one globe with --globe")
    source = sources[0]
    lit, dr = light_and_drape(shading, sun, hillshade, shadows, ambient_occlusion,
                              drape_path, drape_opacity)  # bad values fail before any work
    src = Path(source)
    if is_store(src):
        store = src
    else:
        click.echo(f"store of {src}: {cached_store_path(src)}", err=True)
        bar = StageBar("preprocess", quiet)
        try:
            store, built = ensure_store(src, rebuild=rebuild, progress=bar)
        finally:
            bar.close()
        click.echo(f"{'preprocessed into' if built else 'using the cached store'} {store}",
                   err=True)
    if web:
        _web(store, vertical_exaggeration, port, bind, strategy=strategy,
             pixel_error=pixel_error, shading=shading, cmap=palette(cmap, clim, water_level),
             size=size, light=lit, drape=dr, occlusion=occlusion, morph=morph)
        return
    if not has_display():
        raise GeoterrainError(
            "no display to open a window on (DISPLAY is not set); use `geoterrain render` "
            "for pictures, or run under a desktop session or Xvfb")
    from geoterrain.exaggerate import exaggerated

    with geoterrain.open(store) as base:
        from geoterrain.core.frame import check_flat

        check_flat(base.frame, str(store))
        t = exaggerated(base, vertical_exaggeration)
        show(t, strategy, pixel_error, shading=shading, cmap=palette(cmap, clim, water_level),
             size=size, light=lit, drape=dr, occlusion=occlusion, morph=morph, water=water)


def _web(store, vertical_exaggeration, port, bind, **kw) -> None:
    """The viewer as a web page (geoterrain.serve.webview); the URL on the first line."""
    import sys

    import geoterrain
    from geoterrain.exaggerate import exaggerated
    from geoterrain.exceptions import UsageError

    try:
        import trame  # noqa: F401
        import trame_vtk  # noqa: F401

        from geoterrain.serve.webview import web_view
    except ImportError:
        raise UsageError("view --web needs trame and trame-vtk: pip install "
                         "'geoterrain[web]'") from None
    import socket

    try:  # a clear error for a busy port, before any work
        with socket.socket(socket.AF_INET6 if ":" in bind else socket.AF_INET) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind((bind, port))
    except (OSError, OverflowError) as exc:
        raise UsageError(f"cannot listen on {bind}:{port} ({getattr(exc, 'strerror', exc)}); "
                         "choose another --port (0: any free one) or --bind") from None

    def ready(url: str) -> None:
        click.echo(url)
        sys.stdout.flush()

    with geoterrain.open(store) as base:
        try:
            web_view(exaggerated(base, vertical_exaggeration), port=port, bind=bind,
                     on_ready=ready, **kw)
        except KeyboardInterrupt:
            pass


def has_display() -> bool:
    """True where a window can open: any non-Linux desktop, or X11/Wayland on Linux."""
    import os
    import sys

    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))

"""`geoterrain view`: an interactive window whose level of detail follows the camera."""

from __future__ import annotations

from pathlib import Path

import click

from geoterrain.cli.options import (
    StageBar,
    colour_options,
    drape_options,
    light_and_drape,
    light_options,
    morph_option,
    occlusion_option,
    palette,
    parse_size,
    pixel_error_option,
    strategy_option,
    vertical_exaggeration_option,
)


@click.command("view")
@click.argument("source", type=click.Path(exists=True, dir_okay=False))
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
@click.option("--size", callback=parse_size, default="1280x720", show_default=True,
              help="Window WIDTHxHEIGHT.")
@click.option("--rebuild", is_flag=True, help="Preprocess the DEM again even if cached.")
@click.pass_context
def command(ctx, source, strategy, occlusion, morph, pixel_error, vertical_exaggeration,
            shading, cmap, clim,
            water_level, sun, hillshade, shadows, ambient_occlusion, drape_path, drape_opacity,
            size, rebuild):
    """Open SOURCE (a store or a DEM) in an interactive 3-D window.

    A DEM is preprocessed first into a store next to it (or in
    ~/.cache/geoterrain when its folder is read-only); the path is printed
    and the store is reused next time.

    \b
    Keys:
      m      next LOD strategy
      + / -  τ × 2 / ÷ 2
      g      geomorphing on/off (rtin, chunked, geomipmap, cdlod)
      x      wireframe
      c      colour by shading / LOD level / tile
      space  freeze the LOD (fly around to inspect culling and refinement)
      h      home view;  q  quit

    \b
    Examples:
      geoterrain view dem.geoterrain
      geoterrain view srtm.tif --strategy chunked --pixel-error 2
      geoterrain view dem.geoterrain --sun 250,20 --shadows
    """
    import geoterrain
    from geoterrain.exceptions import GeoterrainError
    from geoterrain.preprocessing.pipeline import cached_store_path, ensure_store
    from geoterrain.rendering.viewer import show
    from geoterrain.store.database import is_store

    quiet = (ctx.obj or {}).get("quiet", False)
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
             size=size, light=lit, drape=dr, occlusion=occlusion, morph=morph)


def has_display() -> bool:
    """True where a window can open: any non-Linux desktop, or X11/Wayland on Linux."""
    import os
    import sys

    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))

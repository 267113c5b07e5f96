"""`geoterrain viewshed`: what an observer sees, as a GeoTIFF on the source grid."""

from __future__ import annotations

import click

from geoterrain.cli.options import FINITE, POSITIVE, points_crs_options


@click.command("viewshed")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--observer", required=True, metavar="X,Y",
              help="Where the observer stands (the DEM's CRS, or --crs / --lonlat).")
@points_crs_options
@click.option("--height", type=FINITE, default=2.0, show_default=True, metavar="H",
              help="Eye height above the ground, metres.")
@click.option("--target-height", type=FINITE, default=0.0, show_default=True, metavar="H",
              help="Height above each cell that must be seen, metres.")
@click.option("--radius", type=POSITIVE, required=True, metavar="M",
              help="How far to look, ground metres.")
@click.option("--curvature", type=FINITE, default=0.85714, show_default=True, metavar="C",
              help="Earth curvature and refraction coefficient as gdal_viewshed's -cc (heights "
                   "drop by C·d²/(2a)); 0 switches both off.")
@click.option("--mode", type=click.Choice(["edge", "diagonal", "max", "min"]), default="edge",
              show_default=True, help="How a cell's sight line is interpolated from its "
                                      "neighbours (gdal_viewshed's cell modes).")
@click.option("--level", type=click.IntRange(0), default=0, show_default=True,
              help="0: exact. L > 0: read level L (faster), cells it cannot decide are 255.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="GeoTIFF: 0 hidden, 1 visible, 255 uncertain, 254 no answer (nodata).")
@click.option("--render", "render_path", type=click.Path(dir_okay=False), metavar="PNG",
              help="Also a 3-D picture with the viewshed draped over the terrain.")
@click.option("--overwrite", is_flag=True, help="Replace the outputs if they exist.")
@click.pass_context
def command(ctx, store, observer, crs, lonlat, height, target_height, radius, curvature, mode,
            level, output, render_path, overwrite):
    """The cells of STORE within --radius of --observer that its eye sees.

    gdal_viewshed's sweep (Wang, Robinson & White's reference planes) on the full
    resolution, read from the store: tiles whose box lies below every sight line are not
    decoded. A store made with --codec-error marks the cells its error could flip as
    uncertain (255) rather than guess.

    \b
    Examples:
      geoterrain viewshed dem.geoterrain --observer 139.25,35.35 --lonlat --height 10 \\
          --radius 10000 -o vs.tif --render vs.png
    """
    from pathlib import Path

    import geoterrain
    from geoterrain.analysis import viewshed, write_viewshed
    from geoterrain.cli.options import parse_xy, points_crs
    from geoterrain.core.paths import check_output

    pcrs = points_crs(crs, lonlat)
    for path, opt in ((output, "-o"), (render_path, "--render")):
        if path is not None:  # core/paths.py: what an output may replace
            check_output(Path(path), overwrite, inputs=[store], option=opt)
    with geoterrain.open(store) as t:
        vs = viewshed(t, parse_xy(observer, "--observer"), radius, height,
                      target_height=target_height, curvature=curvature, mode=mode,
                      level=level, crs=pcrs)
        write_viewshed(vs, output, overwrite=overwrite)
        if render_path:
            from geoterrain.rendering.drape import Drape
            from geoterrain.rendering.scene import render

            render(t, None, render_path, drape=Drape(str(output), 0.65),
                   title=f"viewshed: {height:g} m eye, {radius / 1000:g} km",
                   overwrite=overwrite)
    if not ctx.obj["quiet"]:
        s = vs.stats
        click.echo(f"{s['visible']} visible, {s['hidden']} hidden, {s['uncertain']} uncertain "
                   f"of {s['cells']} cells; tiles: {s['tiles_read']} read, "
                   f"{s['tiles_skipped']} skipped of {s['tiles_in_window']} "
                   f"({s['tiles_decoded']} decodes with their ancestors, {s['bytes_read']} "
                   f"bytes), {s['seconds'] * 1e3:.0f} ms; wrote {output}"
                   + (f", {render_path}" if render_path else ""), err=True)

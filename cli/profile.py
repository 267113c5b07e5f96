"""`geoterrain profile`: heights along a line, as CSV and a drawn profile."""

from __future__ import annotations

import click

from geoterrain.cli.options import POSITIVE, points_crs_options


@click.command("profile")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--line", required=True, metavar="WKT|GEOJSON|FILE",
              help="A LINESTRING (WKT, GeoJSON, or a .wkt/.geojson file; GeoJSON is lon/lat "
                   "unless --crs says otherwise).")
@points_crs_options
@click.option("--spacing", type=POSITIVE, metavar="M",
              help="Metres along the ground between samples [default: the DEM's cell].")
@click.option("--level", type=click.IntRange(0), default=0, show_default=True,
              help="Pyramid level of the heights (with their bound in the CSV).")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="CSV: distance_m, x, y, height, bound, level.")
@click.option("--plot", type=click.Path(dir_okay=False), metavar="PNG",
              help="Draw the profile (filled ground against distance, vertices, lowest and "
                   "highest points, ascent and descent).")
@click.option("--title", help="Title of the plot.")
@click.option("--overwrite", is_flag=True, help="Replace the outputs if they exist.")
@click.pass_context
def command(ctx, store, line, crs, lonlat, spacing, level, output, plot, title, overwrite):
    """An elevation profile of STORE along a line.

    Samples every --spacing metres of ground (geodesics on a geographic grid) and at
    every vertex; heights bilinear on the DEM's samples, in its vertical unit.

    \b
    Examples:
      geoterrain profile dem.geoterrain --line "LINESTRING (139.12 35.30, 139.34 35.35)" \\
          --lonlat -o profile.csv --plot profile.png
      geoterrain profile dem.geoterrain --line route.geojson --spacing 10 -o route.csv
    """
    import geoterrain
    from geoterrain.analysis import plot_profile, profile, write_profile_csv
    from geoterrain.cli.options import points_crs, read_geometry
    from geoterrain.exceptions import UsageError

    if output is None and plot is None:
        raise UsageError("nothing to write: give -o profile.csv and/or --plot profile.png")
    pcrs = points_crs(crs, lonlat)
    geom, from_geojson = read_geometry(line, "--line")
    if geom.geom_type != "LineString" or geom.is_empty:
        raise UsageError(f"--line must be a LINESTRING, got a {geom.geom_type}"
                         + (" (empty)" if geom.is_empty else ""))
    pcrs = pcrs or ("lonlat" if from_geojson else None)
    import numpy as np

    from geoterrain.core.paths import check_output

    for path, opt in ((output, "-o"), (plot, "--plot")):
        if path is not None:  # core/paths.py: what an output may replace
            check_output(path, overwrite, inputs=[store], option=opt)
    with geoterrain.open(store) as t:
        p = profile(t, np.asarray(geom.coords)[:, :2], spacing, level=level, crs=pcrs)
    written = []
    if output:
        written.append(write_profile_csv(p, output, overwrite=overwrite))
    if plot:
        written.append(plot_profile(p, plot, title=title, overwrite=overwrite))
    if not ctx.obj["quiet"]:
        s, st = p.summary, p.stats
        click.echo(f"{s['samples']} samples over {s['length_m']:,.1f} m: {s['min']:.1f} … "
                   f"{s['max']:.1f} {p.unit}, ascent {s['ascent']:.1f}, descent "
                   f"{s['descent']:.1f} {p.unit}; {st['tiles_decoded']} tiles decoded, "
                   f"{st['seconds'] * 1e3:.0f} ms; wrote {', '.join(map(str, written))}",
                   err=True)

"""`geoterrain contours`: contour lines as a GeoPackage or GeoJSON."""

from __future__ import annotations

import click

from geoterrain.cli.options import FINITE, NON_NEGATIVE, POSITIVE


def _levels(ctx, param, value):
    if value is None:
        return None
    try:
        return [float(v) for v in value.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter(f"expected comma-separated heights, got {value!r}") from None


@click.command("contours")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--interval", type=POSITIVE, metavar="DZ",
              help="Height between contours (the DEM's vertical unit), as gdal_contour -i.")
@click.option("--base", type=FINITE, default=0.0, show_default=True,
              help="A level the contours pass through (gdal_contour -off).")
@click.option("--levels", callback=_levels, metavar="Z[,Z...]",
              help="These levels instead of an interval (gdal_contour -fl).")
@click.option("--max-error", type=NON_NEGATIVE, metavar="E",
              help="Trace the coarsest pyramid level whose error is at most E (faster; the "
                   "bound is printed).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="A GeoPackage (.gpkg) or GeoJSON (.geojson) of lines with their height "
                   "in 'elev'.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, interval, base, levels, max_error, output, overwrite):
    """Contour lines of STORE, as gdal_contour draws them on the source.

    \b
    Examples:
      geoterrain contours dem.geoterrain --interval 50 -o contours.gpkg
      geoterrain contours dem.geoterrain --interval 10 --max-error 2 -o c.geojson
    """
    import geoterrain
    from geoterrain.analysis import contours, write_contours
    from geoterrain.exceptions import UsageError

    if (interval is None) == (levels is None):
        raise UsageError("give --interval DZ or --levels Z,Z,… (one of them)")
    from geoterrain.core.paths import check_output

    check_output(output, overwrite, inputs=[store])  # core/paths.py: what -o may replace
    with geoterrain.open(store) as t:
        c = contours(t, interval, base, levels=levels, max_error=max_error)
        write_contours(c, output, t.frame.crs_wkt, overwrite=overwrite)
    if not ctx.obj["quiet"]:
        s = c.stats
        bound = "" if c.level == 0 else f" (level {c.level}, vertices within {c.bound:g})"
        click.echo(f"{len(c.lines)} lines ({int(c.closed.sum())} closed) at "
                   f"{len(set(c.heights.tolist()))} levels{bound}; {s['tiles_decoded']} tiles "
                   f"decoded, {s['tiles_skipped']} skipped, {s['seconds'] * 1e3:.0f} ms; "
                   f"wrote {output}", err=True)

"""`geoterrain export-raster`: hillshade, slope, normals, shading or error map as a GeoTIFF."""

from __future__ import annotations

import click

from geoterrain.cli.options import POSITIVE
from geoterrain.export.rasters import PRODUCTS, SLOPE_UNITS


def _parse_sun(ctx, param, value):
    if value is None:
        return None
    try:
        az, alt = (float(v) for v in str(value).split(","))
    except ValueError:
        raise click.BadParameter(f"expected AZ,ALT in degrees such as 315,45, got "
                                 f"{value!r}") from None
    return az, alt


@click.command("export-raster")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--what", type=click.Choice(PRODUCTS), required=True,
              help="hillshade: gdaldem's shaded relief (0-255 byte); slope: degrees or "
                   "percent, as gdaldem's; shade: the shading factor `render` applies; "
                   "normals: 3 bands; error: the stored per-vertex error bound in metres.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="GeoTIFF (.tif), written as a Cloud-Optimised GeoTIFF.")
@click.option("--level", type=click.IntRange(0), default=0, show_default=True,
              help="Pyramid level: every 2^LEVEL-th sample, pixels 2^LEVEL times larger.")
@click.option("--sun", callback=_parse_sun, metavar="AZ,ALT",
              help="Hillshade: sun azimuth (degrees clockwise from north) and altitude "
                   "above the horizon, as gdaldem's -az and -alt [default: 315,45].")
@click.option("--multidirectional", is_flag=True,
              help="Hillshade: suns from 225, 270, 315 and 360 degrees, weighted by the "
                   "slope's aspect (gdaldem -multidirectional; --sun gives the altitude).")
@click.option("-z", "--z-factor", type=POSITIVE, default=1.0, show_default=True, metavar="Z",
              help="Hillshade and slope: heights × Z (gdaldem -z).")
@click.option("--scale", type=POSITIVE, metavar="S",
              help="Hillshade and slope: vertical units per horizontal unit (gdaldem -s) "
                   "[default: right for the DEM; 111120 for a geographic DEM in metres, "
                   "as gdaldem's convention].")
@click.option("--slope-units", type=click.Choice(SLOPE_UNITS), default="degrees",
              show_default=True, help="Slope: degrees from the horizontal, or percent "
                                      "(gdaldem -p).")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, what, output, level, sun, multidirectional, z_factor, scale,
            slope_units, overwrite):
    """Write a 2-D product of STORE as a GeoTIFF in the source CRS and grid.

    The hillshade and slope are gdaldem's (Horn's method, edges computed), so they
    match `gdaldem hillshade` and `gdaldem slope` on the same DEM with the same sun,
    z-factor and scale. The hillshade's nodata is 0; the other products' is NaN.

    \b
    Examples:
      geoterrain export-raster dem.geoterrain --what hillshade -o shade.tif
      geoterrain export-raster dem.geoterrain --what hillshade --sun 300,30 -z 2 -o s.tif
      geoterrain export-raster dem.geoterrain --what hillshade --multidirectional -o m.tif
      geoterrain export-raster dem.geoterrain --what slope --slope-units percent -o p.tif
      geoterrain export-raster dem.geoterrain --what error --level 2 -o error_l2.tif
    """
    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.export.rasters import Relief, export_raster

    relief_opts = sun is not None or multidirectional or z_factor != 1.0 or scale is not None
    if relief_opts and what not in ("hillshade", "slope"):
        raise UsageError("--sun, --multidirectional, --z-factor and --scale apply to "
                         "--what hillshade and slope")
    if (sun is not None or multidirectional) and what != "hillshade":
        raise UsageError("--sun and --multidirectional apply to --what hillshade")
    if slope_units != "degrees" and what != "slope":
        raise UsageError("--slope-units applies to --what slope")
    az, alt = sun if sun is not None else (315.0, 45.0)
    relief = Relief(az, alt, z_factor, scale, multidirectional, slope_units)
    with geoterrain.open(store) as t:
        out = export_raster(t, what, output, level=level, overwrite=overwrite, relief=relief)
    if not ctx.obj["quiet"]:
        click.echo(f"wrote {out}")

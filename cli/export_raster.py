"""`geoterrain export-raster`: hillshade, normals, slope or error map as a GeoTIFF."""

from __future__ import annotations

import click

from geoterrain.export.rasters import PRODUCTS


@click.command("export-raster")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--what", type=click.Choice(PRODUCTS), required=True,
              help="hillshade: the renderer's shading factor; normals: 3 bands; slope: "
                   "degrees; error: the stored per-vertex error bound δ in metres.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="GeoTIFF (.tif), written as a Cloud-Optimised GeoTIFF.")
@click.option("--level", type=click.IntRange(0), default=0, show_default=True,
              help="Pyramid level: every 2^LEVEL-th sample, pixels 2^LEVEL times larger.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, what, output, level, overwrite):
    """Write a 2-D product of STORE as a GeoTIFF in the source CRS and grid.

    Nodata is NaN. The hillshade is exactly the shading `geoterrain render`
    applies (sun from the north-west at 45°).

    \b
    Examples:
      geoterrain export-raster dem.geoterrain --what hillshade -o shade.tif
      geoterrain export-raster dem.geoterrain --what error --level 2 -o delta_l2.tif
    """
    import geoterrain
    from geoterrain.export.rasters import export_raster

    with geoterrain.open(store) as t:
        out = export_raster(t, what, output, level=level, overwrite=overwrite)
    if not ctx.obj["quiet"]:
        click.echo(f"wrote {out}")

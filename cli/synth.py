"""`geoterrain synth`: deterministic fractal DEMs as GeoTIFFs (seed 000, annex A)."""

from __future__ import annotations

import click

from geoterrain.cli.options import PIXEL_SIZE, Point

KINDS = ("fbm", "ridged", "diamond-square", "fault")


@click.command("synth")
@click.argument("kind", type=click.Choice(KINDS))
@click.option("--size", default=1025, show_default=True, type=click.IntRange(2, 32769),
              help="Samples per side (2^n+1 fits the pyramid without padding).")
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed.")
@click.option("--spacing", default=10.0, show_default=True, type=PIXEL_SIZE,
              help="Metres between samples.")
@click.option("--crs", default="EPSG:32633", show_default=True,
              help="Projected CRS of the output (default UTM 33N).")
@click.option("--origin", default="500000,5000000", show_default=True,
              type=Point(2, "X,Y"),
              help="CRS coordinates X,Y of the top-left corner.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="GeoTIFF to write.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
def command(kind, size, seed, spacing, crs, origin, output, overwrite):
    """Write a synthetic KIND DEM: fbm, ridged, diamond-square or fault.

    The result is a float32 GeoTIFF with a CRS and a transform, the same for
    the same seed on every machine.

    \b
    Example:
      geoterrain synth fbm --size 1025 --seed 7 -o fbm.tif
    """
    from geoterrain.core.paths import check_output
    from geoterrain.ingest.synth import generate, write_geotiff

    check_output(output, overwrite)  # a regular file or nothing (core/paths.py)
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:  # pyproj: says nothing on stderr (GDAL would print PROJ's own error line too)
        CRS.from_user_input(crs)
    except CRSError:
        raise click.BadParameter(f"not a CRS PROJ knows: {crs!r} (e.g. EPSG:32633)",
                                 param_hint="--crs") from None
    z = generate(kind, size, seed=seed)
    write_geotiff(output, z, crs=crs, origin=origin, spacing=spacing)
    click.echo(f"wrote {output}: {kind} {size}×{size}, seed {seed}, "
               f"heights {float(z.min()):.1f} … {float(z.max()):.1f} m", err=False)

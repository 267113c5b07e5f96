"""`geoterrain synth`: deterministic fractal DEMs as GeoTIFFs."""

from __future__ import annotations

import click

from geoterrain.cli.options import PIXEL_SIZE, Point, parse_min_max

KINDS = ("fbm", "ridged", "diamond-square", "fault")


def _parse_size(ctx, param, value):
    """``N`` → (N, N); ``WxH`` → (H, W) rows and columns."""
    try:
        parts = [int(v) for v in str(value).lower().split("x")]
    except ValueError:
        raise click.BadParameter(f"expected N or WIDTHxHEIGHT, got {value!r}") from None
    if len(parts) == 1:
        parts *= 2
    if len(parts) != 2 or not all(2 <= v <= 32769 for v in parts):
        raise click.BadParameter(f"expected N or WIDTHxHEIGHT, each in 2..32769, got {value!r}")
    return parts[1], parts[0]


@click.command("synth")
@click.argument("kind", type=click.Choice(KINDS))
@click.option("--size", default="1025", show_default=True, callback=_parse_size,
              metavar="N|WxH", help="Samples per side, or WIDTHxHEIGHT (2^n+1 fits the "
                                    "pyramid without padding).")
@click.option("--heights", callback=parse_min_max, metavar="MIN,MAX",
              help="Lowest and highest height in metres [default: 0,2000]; a negative MIN "
                   "makes a topo-bathymetric DEM (the sea below 0 m).")
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
def command(kind, size, heights, seed, spacing, crs, origin, output, overwrite):
    """Write a synthetic KIND DEM: fbm, ridged, diamond-square or fault.

    The result is a float32 GeoTIFF with a CRS and a transform, the same for
    the same seed on every machine.

    \b
    Examples:
      geoterrain synth fbm --size 1025 --seed 7 -o fbm.tif
      geoterrain synth fbm --size 120x91 --heights -2500,1500 --spacing 1000 -o tb.tif
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
    lo, hi = heights if heights is not None else (0.0, 2000.0)
    z = generate(kind, size, seed=seed, base=lo, relief=hi - lo)
    write_geotiff(output, z, crs=crs, origin=origin, spacing=spacing)
    click.echo(f"wrote {output}: {kind} {size[1]} × {size[0]} (width × height), seed {seed}, "
               f"heights {float(z.min()):.1f} … {float(z.max()):.1f} m", err=False)

"""`geoterrain edit`: change a store's heights in place with a patch raster."""

from __future__ import annotations

import click


def _parse_at(ctx, param, value):
    if value is None:
        return None
    try:
        row, col = (int(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"expected ROW,COL (two integers), got {value!r}") from None
    return row, col


@click.command("edit")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--patch", "patch", required=True, type=click.Path(dir_okay=False),
              help="A raster of new heights in the DEM's height units; its nodata samples "
                   "change nothing.")
@click.option("--mode", type=click.Choice(["replace", "add", "min", "max"]), default="replace",
              show_default=True,
              help="replace: the patch's heights (over voids too); add: heights + patch (a "
                   "cut is negative); min / max: the lower / higher of the two (a cut to a "
                   "design surface, an embankment). add, min and max leave voids as they are.")
@click.option("--at", callback=_parse_at, metavar="ROW,COL",
              help="Place the patch's top-left sample at this row and column of the DEM "
                   "instead of by its georeference (needed when either has none).")
@click.option("--resampling", type=click.Choice(["nearest", "bilinear", "cubic"]),
              default="bilinear", show_default=True,
              help="How a patch that is not on the store's grid is resampled onto it.")
@click.option("--round", "round_heights", is_flag=True,
              help="Round heights a lossless store cannot hold (12.3 in an integer DEM) to "
                   "its grid, instead of refusing them.")
@click.option("--band", type=click.IntRange(min=1), help="Band to read from a multi-band patch.")
@click.pass_context
def command(ctx, store, patch, mode, at, resampling, round_heights, band):
    """Change STORE's heights in place where PATCH says: a road cut, a dam, a quarry, a
    crater, a corrected void.

    Only what the edit reaches is recomputed and rewritten (the tiles under the patch
    and their ancestors, the error bounds up to the root, the normals around it), and
    the store then holds what preprocessing the edited DEM would give. The edit is one
    transaction: if it is interrupted, the store is left as it was. A `geoterrain view`
    window showing the store redraws when the edit is done. A root-grid store (the
    default layout of a wide or tall DEM) is edited the same way when its raster fills
    its roots; one with padding, like a padded square store, is recomputed over the
    whole grid (about a preprocess's time; the summary line says why).

    \b
    Examples:
      geoterrain edit dem.geoterrain --patch road_cut.tif --mode min
      geoterrain edit dem.geoterrain --patch crater.tif --mode add
      geoterrain edit dem.geoterrain --patch void_fill.tif
      geoterrain edit tile.geoterrain --patch fix.tif --at 120,64 --round
    """
    import geoterrain

    res = geoterrain.edit(store, patch, mode, at=at, resampling=resampling,
                          round_heights=round_heights, band=band)
    if not ctx.obj["quiet"]:
        click.echo(res.summary())

"""`geoterrain tiles`: a Cesium quantized-mesh tile set of a store."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import POSITIVE


@click.command("tiles")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Folder for layer.json and {z}/{x}/{y}.terrain.")
@click.option("--format", "fmt", type=click.Choice(["quantized-mesh"]), default="quantized-mesh",
              show_default=True, help="Tile format (CesiumJS's CesiumTerrainProvider).")
@click.option("--max-zoom", type=click.IntRange(0, 22),
              help="Finest level; default: where the tile lattice matches the DEM's spacing.")
@click.option("--min-zoom", type=click.IntRange(0, 22), default=0, show_default=True)
@click.option("--max-error", type=POSITIVE, default=1.0, show_default=True, metavar="E",
              help="Vertex selection threshold at the finest level, metres (coarser "
                   "levels use Cesium's level error).")
@click.option("--geoid", type=click.Choice(["egm96"]),
              help="The DEM holds EGM96 heights (SRTM): write WGS 84 ellipsoidal heights, "
                   "as CesiumJS expects (needs PROJ's EGM96 grid: apt-get install proj-data).")
@click.option("--overwrite", is_flag=True, help="Write into OUTPUT even if it holds a layer.json.")
@click.pass_context
def command(ctx, store, output, fmt, max_zoom, min_zoom, max_error, geoid, overwrite):
    """Write a quantized-mesh-1.0 tile set (geographic tiling) of STORE for CesiumJS.

    Tiles are gzip-compressed (serve them with `Content-Encoding: gzip`), carry
    oct-encoded normals and a water mask, and share their edge vertices exactly
    with their neighbours; nodata is left out (a hole), never a spike. Each
    tile's declared error (a bound on |mesh − DEM| at every DEM sample: the
    lattice's resampling error + the vertices left out + quantisation) is in
    OUTPUT/geoterrain.json; below --max-zoom it is within Cesium's level error.

    Heights are written as the DEM holds them (e.g. EGM96 orthometric heights
    for SRTM); CesiumJS assumes ellipsoidal heights, so the terrain sits off by
    the geoid undulation (−107 to +85 m) unless --geoid egm96 converts them.

    \b
    Examples:
      geoterrain tiles dem.geoterrain -o tiles/
      geoterrain tiles dem.geoterrain -o tiles/ --max-zoom 12 --max-error 2
      geoterrain tiles srtm.geoterrain -o tiles/ --geoid egm96
    """
    import geoterrain
    from geoterrain.cli.options import StageBar
    from geoterrain.exceptions import UsageError
    from geoterrain.export.qmesh import write_tileset

    if not max_error > 0:
        raise UsageError(f"--max-error must be > 0, got {max_error}")
    bar = StageBar("tiles", ctx.obj["quiet"])
    try:
        with geoterrain.open(store) as t:
            stats = write_tileset(t, output, max_zoom=max_zoom, min_zoom=min_zoom,
                                  max_error=max_error, overwrite=overwrite, geoid=geoid,
                                  progress=bar)
    finally:
        bar.close()
    if not ctx.obj["quiet"]:
        click.echo(json.dumps(stats))

"""`geoterrain preprocess`: DEM → store."""

from __future__ import annotations

import click

from geoterrain.cli.options import (
    EXAGGERATION,
    NODATA,
    NON_NEGATIVE,
    PIXEL_SIZE,
    StageBar,
    parse_bytes,
)
from geoterrain.core.frame import Z_UNITS
from geoterrain.ingest.composite import PRIORITIES, RESAMPLINGS
from geoterrain.ingest.raster import ENCODINGS


@click.command("preprocess")
@click.argument("dem", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Store to write. Default: the DEM's path with the suffix .geoterrain "
                   "(a folder's: beside it).")
@click.option("--tile-size", default=64, show_default=True, type=click.IntRange(2, 4096),
              help="Tile edge in samples, a power of two; tiles hold (size+1)² samples.")
@click.option("--band", type=click.IntRange(1, 65535),
              help="Band to read from a multi-band raster.")
@click.option("--encoding", type=click.Choice(ENCODINGS), default="auto", show_default=True,
              help="How pixels encode heights; auto decodes Terrain-RGB/Terrarium PNG tiles.")
@click.option("--pixel-size", type=PIXEL_SIZE,
              help="Metres per sample for rasters without a CRS (PNG tiles); default 1.")
@click.option("--z-scale", type=EXAGGERATION, help="Vertical exaggeration (default 1).")
@click.option("--z-units", type=click.Choice(["auto", *Z_UNITS]), default="auto",
              show_default=True,
              help="Unit of the heights: metres, international feet or US survey feet; auto "
                   "follows the CRS (its vertical unit, else its horizontal one) and warns "
                   "when they disagree.")
@click.option("--tile", metavar="Z/X/Y",
              help="A web-map PNG tile's z/x/y: placed in Web Mercator at its true pixel size "
                   "(recognised by itself when the path ends in z/x/y.png).")
@click.option("--codec-error", type=NON_NEGATIVE, metavar="EPS",
              help="Height codec bound ε: every stored height is within EPS (height units) "
                   "of the source. Default: lossless.")
@click.option("--max-error", "old_max_error", hidden=True)
@click.option("--nodata", type=NODATA, help="The value of voids, overriding the file's "
              "(nan: only NaN). Undeclared -32768/-9999/float32-min runs are voids by default.")
@click.option("--memory-limit", callback=parse_bytes, metavar="SIZE",
              help="Memory the job may use, e.g. 2G or 800M (default: half of what is "
                   "available). A DEM too large for it (any input) is read a window at a "
                   "time, into the same store.")
@click.option("--scheduler", default="sync", show_default=True, metavar="SPEC",
              help="Where a streamed preprocess's passes run: sync, threads:N, "
                   "processes:N, dask:ADDRESS (a running dask scheduler) or dask:local:N "
                   "(N local worker processes). The store is the same on each.")
@click.option("--resume", is_flag=True,
              help="Take up a streamed preprocess of the same DEM and settings that was "
                   "killed: the passes it finished are reused, and the store is the one an "
                   "uninterrupted run writes.")
@click.option("--crs", "target_crs", metavar="CRS",
              help="Merge the sources onto a grid in this CRS (EPSG:xxxx, WKT, PROJ): sources "
                   "of different CRSs or resolutions are warped there by GDAL. Default: the "
                   "finest source's CRS.")
@click.option("--resolution", type=float, metavar="RES",
              help="Pixel size of the merged grid, in its CRS's units. Default: the finest "
                   "source's.")
@click.option("--resampling", type=click.Choice(RESAMPLINGS), default="bilinear",
              show_default=True, help="How a source is warped onto the merged grid.")
@click.option("--priority", type=click.Choice(PRIORITIES), default="finest",
              show_default=True,
              help="Where merged sources overlap: the finest valid one wins (finest), or the "
                   "first given (order); a void is filled from the next.")
@click.option("--stored-normals", is_flag=True,
              help="Store every tile's normal map whole, not just its border (the rest is "
                   "derived from the heights when a tile is shaded): a store about a third "
                   "larger on SRTM DEMs, whose new textures shade about 0.2 ms a tile faster.")
@click.option("--root-grid/--square-grid", "root_grid", default=True,
              help="Root grid (the default): a wide or tall DEM is padded to the next tile "
                   "multiple a side, under 1 × 1, 2 × 1 or 1 × 2 root tiles (a 520 × 1180 "
                   "DEM to 577 × 1217, not 2049²): less time and memory, and every command "
                   "reads it. --square-grid pads to one power-of-two square (2^n + 1 a side) "
                   "as stores made before root grids were (schema 17; a root grid is schema "
                   "18): choose it for a reader that takes square stores only. A DEM whose "
                   "root grid is its square gets the square store either way.")
@click.option("--overwrite", is_flag=True, help="Replace the store if it exists.")
@click.pass_context
def command(ctx, dem, output, tile_size, band, encoding, pixel_size, z_scale, z_units, tile,
            codec_error, old_max_error, nodata, memory_limit, scheduler, resume, target_crs,
            resolution, resampling, priority, stored_normals, root_grid, overwrite):
    """Ingest DEM into a tiled, error-annotated store (one .geoterrain file).

    DEM is any raster GDAL reads (GeoTIFF/COG, SRTM .hgt, Esri ASCII, a .vrt,
    ...) or a Terrain-RGB / Terrarium PNG tile. Several files, a quoted glob ('**'
    spans subfolders) or a folder (its .tif, .hgt, .hgt.zip, ... files, not its
    subfolders'; srtm/ writes srtm.geoterrain) are
    read as one mosaic (-o needed but for a folder); tiles of different CRSs or
    resolutions are merged onto one grid (--crs, --resolution, --resampling,
    --priority).
    The store holds a pyramid of tiles, padded to the next tile multiple under a
    grid of root tiles (--square-grid: one power-of-two square), with per-vertex and
    per-tile error bounds, residual-coded heights and normal maps. It is written
    atomically: an interrupted run leaves no store behind.

    \b
    Examples:
      geoterrain preprocess dem.tif
      geoterrain preprocess fuji.png --tile 12/3637/1612
      geoterrain preprocess tile.png --pixel-size 30 -o tile.geoterrain
      geoterrain preprocess lidar.tif --codec-error 0.05 --z-scale 2
      geoterrain preprocess srtm/            # its .hgt/.hgt.zip tiles: srtm.geoterrain
      geoterrain preprocess 'cop30/**/*_DEM.tif' -o cop30.geoterrain
      geoterrain preprocess lidar_1m.tif national_30m.tif -o merged.geoterrain
      geoterrain preprocess national_30m.tif --crs EPSG:32633 --resolution 50 -o m.geoterrain
      geoterrain preprocess lidar_county.tif --memory-limit 2G
      geoterrain preprocess lidar_county.tif --memory-limit 2G --scheduler processes:4
    """
    import geoterrain
    from geoterrain.exceptions import UsageError

    if old_max_error is not None:
        raise UsageError("preprocess --max-error is now --codec-error (the codec's ε); "
                         "--max-error belongs to `geoterrain mesh` (the static mesh's bound)")
    if tile_size < 2 or tile_size & (tile_size - 1):
        raise click.BadParameter(f"expected a power of two ≥ 2, got {tile_size}",
                                 param_hint="--tile-size")
    dem = dem[0] if len(dem) == 1 else list(dem)
    quiet = ctx.obj["quiet"]
    bar = StageBar("preprocess", quiet)
    times: dict[str, float] = {}
    try:
        out = geoterrain.preprocess(
            dem, output, tile_size=tile_size, band=band, encoding=encoding,
            pixel_size=pixel_size, z_scale=z_scale, z_units=z_units, tile=tile,
            codec_error=codec_error, overwrite=overwrite, nodata=nodata,
            memory_limit=memory_limit, scheduler=scheduler, resume=resume, progress=bar,
            derive_normals=not stored_normals, crs=target_crs, resolution=resolution,
            resampling=resampling, priority=priority, timings=times, root_grid=root_grid)
    finally:
        bar.close()
    if ctx.obj["verbose"]:  # the store holds no timings: the same DEM gives the same bytes
        click.echo("stages " + ", ".join(f"{k} {v:.2f} s" for k, v in times.items()), err=True)
    if not quiet:
        with geoterrain.open(out) as t:
            i = t.info()
        click.echo(f"wrote {out} ({i['size_bytes'] / 1e6:.2f} MB): {i['grid'][1]} × "
                   f"{i['grid'][0]} samples (width × height), {i['levels']} levels, "
                   f"{sum(i['tiles_per_level'].values())} tiles, "
                   f"{i['height_bits_per_valid_sample']:.2f} bits/sample heights")

"""`geoterrain tiles`: a Cesium quantized-mesh tile set of a store, or PMTiles archives
(Terrain-RGB/Terrarium heights and imagery) with a MapLibre page for static hosting."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import POSITIVE


@click.command("tiles")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Folder for layer.json and {z}/{x}/{y}.terrain, or for the .pmtiles "
                   "archives and index.html.")
@click.option("--format", "fmt", type=click.Choice(["quantized-mesh", "pmtiles"]),
              default="quantized-mesh", show_default=True,
              help="quantized-mesh: CesiumJS's CesiumTerrainProvider; pmtiles: archives "
                   "for MapLibre on a static host.")
@click.option("--max-zoom", type=click.IntRange(0, 22),
              help="Finest level; default: where the tiles' samples match the DEM's spacing.")
@click.option("--min-zoom", type=click.IntRange(0, 22), default=0, show_default=True)
@click.option("--max-error", type=POSITIVE, default=1.0, show_default=True, metavar="E",
              help="quantized-mesh: vertex selection threshold at the finest level, metres "
                   "(coarser levels use Cesium's level error).")
@click.option("--mesher", type=click.Choice(["tin", "rtin"]), default="tin", show_default=True,
              help="quantized-mesh: each tile's mesh, tin (a greedy TIN of the lattice, its "
                   "error measured) or rtin (the lattice's bintree cut, an a-priori bound; "
                   "about 2.3× the bytes).")
@click.option("--encoding", type=click.Choice(["terrain-rgb", "terrarium"]),
              default="terrain-rgb", show_default=True,
              help="pmtiles: how the heights are packed into PNG pixels.")
@click.option("--imagery", default="relief,hillshade", show_default=True, metavar="LIST",
              help="pmtiles: imagery archives, any of relief, hillshade, slope, error "
                   "(comma-separated; 'none' for the heights alone).")
@click.option("--image-format", type=click.Choice(["png", "webp"]), default="png",
              show_default=True, help="pmtiles: the imagery's format (lossless either way).")
@click.option("--assets", type=click.Path(file_okay=False, exists=True),
              help="pmtiles: a node_modules folder with maplibre-gl and pmtiles to copy "
                   "beside the page (default: ./node_modules, ./.browser/node_modules).")
@click.option("--geoid", type=click.Choice(["egm96"]),
              help="The DEM holds EGM96 heights (SRTM): write WGS 84 ellipsoidal heights, "
                   "as CesiumJS expects (needs PROJ's EGM96 grid: apt-get install proj-data).")
@click.option("--overwrite", is_flag=True, help="Write into OUTPUT even if it holds a layer.json.")
@click.pass_context
def command(ctx, store, output, fmt, max_zoom, min_zoom, max_error, mesher, encoding, imagery,
            image_format, assets, geoid, overwrite):
    """Write a quantized-mesh-1.0 tile set (geographic tiling) of STORE for CesiumJS,
    or PMTiles archives with a map page (--format pmtiles).

    Tiles are gzip-compressed (serve them with `Content-Encoding: gzip`), carry
    oct-encoded normals and a water mask, and share their edge vertices exactly
    with their neighbours; nodata is left out (a hole), never a spike. Each
    tile's declared error (--mesher tin: the largest |mesh − DEM| measured at the
    DEM samples it covers; rtin: a bound, the lattice's resampling error + the
    vertices left out + quantisation) is in OUTPUT/geoterrain.json; below
    --max-zoom it is within Cesium's level error.

    Heights are written as the DEM holds them (e.g. EGM96 orthometric heights
    for SRTM); CesiumJS assumes ellipsoidal heights, so the terrain sits off by
    the geoid undulation (−107 to +85 m) unless --geoid egm96 converts them.

    With --format pmtiles, OUTPUT gets NAME.terrain-rgb.pmtiles (Web Mercator,
    heights exact to 0.1 m; Terrarium: 1/256 m), one archive per --imagery, and
    index.html: a MapLibre map with 3-D terrain that reads the archives by HTTP
    range requests. Copy the folder to any static host that answers Range requests
    (S3, GCS, Azure blobs, GitHub Pages, nginx) and open index.html.

    \b
    Examples:
      geoterrain tiles dem.geoterrain -o tiles/
      geoterrain tiles dem.geoterrain -o tiles/ --max-zoom 12 --max-error 2
      geoterrain tiles srtm.geoterrain -o tiles/ --geoid egm96
      geoterrain tiles dem.geoterrain -o site/ --format pmtiles
      geoterrain tiles dem.geoterrain -o site/ --format pmtiles --imagery relief,slope
    """
    import geoterrain
    from geoterrain.cli.options import StageBar
    from geoterrain.exceptions import UsageError
    from geoterrain.export.qmesh import write_tileset

    if fmt == "pmtiles":
        if geoid is not None:
            raise UsageError("--geoid applies to quantized-mesh tiles (CesiumJS's heights); "
                             "web-map heights are the DEM's own")
        try:
            import pmtiles  # noqa: F401

            from geoterrain.serve.site import write_site
        except ImportError:
            raise UsageError("--format pmtiles needs the pmtiles package: "
                             "pip install 'geoterrain[web]'") from None
        kinds = () if imagery.strip().lower() == "none" else tuple(
            k.strip() for k in imagery.split(",") if k.strip())
        bar = StageBar("tiles", ctx.obj["quiet"])
        try:
            with geoterrain.open(store) as t:
                figs = write_site(t, output, encoding=encoding, imagery=kinds,
                                  fmt=image_format, min_zoom=min_zoom, max_zoom=max_zoom,
                                  assets=assets, overwrite=overwrite, progress=bar)
        finally:
            bar.close()
        if not ctx.obj["quiet"]:
            click.echo(json.dumps({k: v for k, v in figs.items() if k != "files"}))
            if "maplibre-gl" not in figs["lib"]:
                click.echo("index.html needs maplibre-gl and pmtiles in lib/: npm install "
                           "maplibre-gl pmtiles, then rerun with --assets node_modules",
                           err=True)
        return
    if not max_error > 0:
        raise UsageError(f"--max-error must be > 0, got {max_error}")
    bar = StageBar("tiles", ctx.obj["quiet"])
    try:
        with geoterrain.open(store) as t:
            stats = write_tileset(t, output, max_zoom=max_zoom, min_zoom=min_zoom,
                                  max_error=max_error, overwrite=overwrite, geoid=geoid,
                                  progress=bar, mesher=mesher)
    finally:
        bar.close()
    if not ctx.obj["quiet"]:
        click.echo(json.dumps(stats))

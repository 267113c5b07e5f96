"""`geoterrain serve`: terrain and imagery tiles cut on request, with a globe and a map page."""

from __future__ import annotations

import click

from geoterrain.cli.options import POSITIVE


def _parse_cache(ctx, param, value):
    import re

    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmg]?)(i?b)?\s*", str(value).lower())
    if not m:
        raise click.BadParameter(f"expected a size such as 256M or 1G, got {value!r}")
    n = int(float(m.group(1)) * 1024 ** " kmg".index(m.group(2) or " "))
    if n < 1 << 20:
        raise click.BadParameter(f"{value} is below 1M; the cache needs room for a few tiles")
    return n


@click.command("serve")
@click.argument("sources", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--port", type=click.IntRange(0, 65535), default=8000, show_default=True,
              help="TCP port (0: any free port; the first line printed says which).")
@click.option("--bind", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 shares the tiles with your network.")
@click.option("--cache", "cache_bytes", default="256M", show_default=True,
              callback=_parse_cache, metavar="SIZE",
              help="Memory for finished tiles (least recently used dropped first).")
@click.option("--assets", type=click.Path(file_okay=False, exists=True),
              help="A node_modules folder holding cesium, maplibre-gl and pmtiles "
                   "(default: ./node_modules, ./.browser/node_modules).")
@click.option("--max-error", type=POSITIVE, default=1.0, show_default=True, metavar="E",
              help="Terrain tiles: vertex threshold at the finest level, metres.")
@click.option("--mesher", type=click.Choice(["tin", "rtin"]), default="tin", show_default=True,
              help="Terrain tiles' meshes: tin (greedy TIN) or rtin (bintree cut, more "
                   "bytes), as `tiles --mesher`.")
@click.option("--geoid", type=click.Choice(["egm96"]),
              help="The DEM holds EGM96 heights (SRTM): give CesiumJS WGS 84 ellipsoidal "
                   "heights (needs PROJ's EGM96 grid: apt-get install proj-data).")
@click.option("--cmap", default="auto", show_default=True,
              help="Colour relief palette: auto or a matplotlib colormap name.")
@click.pass_context
def command(ctx, sources, port, bind, cache_bytes, assets, max_error, mesher, geoid, cmap):
    """Serve SOURCES (stores, or DEMs preprocessed into the cache) over HTTP.

    Each is served under its file name without the suffix, NAME:

    \b
      NAME/layer.json, NAME/{z}/{x}/{y}.terrain    quantized-mesh (CesiumJS)
      NAME/rgb/{z}/{x}/{y}.png                     Terrain-RGB (MapLibre, deck.gl)
      NAME/terrarium/{z}/{x}/{y}.png               Terrarium
      NAME/{relief,hillshade,slope,error}/{z}/{x}/{y}.{png,webp}   imagery (XYZ;
                                                   NAME/tms/... counts rows from the south)
      NAME/rgb.json, NAME/relief.json, ...         TileJSON
      /cesium.html, /maplibre.html                 a globe and a 3-D map of the data

    Tiles are cut from the store when first asked for (only the stored tiles under
    them are decoded) and kept in memory within --cache. Every response carries
    CORS headers, so pages served elsewhere can use the tiles. The first line
    printed is the base URL. Stop with Ctrl-C.

    The pages load CesiumJS and MapLibre GL JS from a local npm install (offline):
    `npm install cesium maplibre-gl pmtiles` in a folder, then --assets FOLDER/node_modules.

    \b
    Examples:
      geoterrain serve dem.geoterrain            # → http://127.0.0.1:8000/
      geoterrain serve a.geoterrain b.tif --port 8080 --cache 1G
      geoterrain serve srtm.geoterrain --geoid egm96 --bind 0.0.0.0
    """
    import socket
    from pathlib import Path

    from geoterrain.exceptions import UsageError

    try:
        import starlette  # noqa: F401
        import uvicorn
    except ImportError:
        raise UsageError("geoterrain serve needs Starlette and uvicorn: "
                         "pip install 'geoterrain[web]'") from None

    from geoterrain.cli.options import StageBar
    from geoterrain.preprocessing.pipeline import ensure_store
    from geoterrain.serve.app import create_app, find_assets, open_stores
    from geoterrain.store.schema import is_store

    if not max_error > 0:
        raise UsageError(f"--max-error must be > 0, got {max_error}")
    quiet = (ctx.obj or {}).get("quiet", False)
    items = []
    for src in map(Path, sources):
        if not src.is_file():
            raise UsageError(f"{src}: no such file")
        if is_store(src):
            items.append((src.stem, src))
            continue
        bar = StageBar("preprocess", quiet)
        try:
            store, built = ensure_store(src, progress=bar)
        finally:
            bar.close()
        click.echo(f"{'preprocessed into' if built else 'using the cached store'} {store}",
                   err=True)
        items.append((src.stem, store))
    stores = open_stores(items, geoid=geoid, max_error=max_error, cmap=cmap, mesher=mesher)
    app = create_app(stores, cache_bytes=cache_bytes, assets=assets)
    try:
        sock = socket.socket(socket.AF_INET6 if ":" in bind else socket.AF_INET)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((bind, port))
        sock.listen(2048)  # connections queue from now on: the URL printed works at once
    except (OSError, OverflowError) as exc:
        raise UsageError(f"cannot listen on {bind}:{port} ({getattr(exc, 'strerror', exc)}); "
                         "choose another --port (0: any free one) or --bind") from None
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    base = f"http://{shown}:{port}/"
    click.echo(base)
    if not quiet:
        for name in stores:
            click.echo(f"  {name}: {base}cesium.html?store={name}  "
                       f"{base}maplibre.html?store={name}")
        libs = find_assets(assets)
        missing = [p for p in ("cesium", "maplibre-gl", "pmtiles") if p not in libs]
        if missing:
            click.echo(f"  the pages need the npm packages {', '.join(missing)}: npm install "
                       f"{' '.join(missing)}, then --assets node_modules", err=True)
    import sys

    sys.stdout.flush()
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off")
    try:
        uvicorn.Server(config).run(sockets=[sock])
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM after uvicorn's graceful shutdown
        pass
    finally:
        for s in stores.values():
            s.terrain.close()

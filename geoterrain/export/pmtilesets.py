"""PMTiles archives of a store for static hosting: Terrain-RGB (or Terrarium) heights and
imagery, one archive each, which MapLibre reads by HTTP range requests.

``write_pmtiles(t, "site/")`` writes

- ``site/NAME.terrain-rgb.pmtiles`` (or ``NAME.terrarium.pmtiles``): the web tiles of
  :class:`geoterrain.export.webtiles.WebTiler`, zooms ``min_zoom..max_zoom``, PNG;
- ``site/NAME.relief.pmtiles`` and ``site/NAME.hillshade.pmtiles`` (``imagery``): PNG
  or WebP.

(:func:`geoterrain.serve.site.write_site` adds ``index.html``, the MapLibre page of
``geoterrain serve`` over ``pmtiles://`` sources, and the JavaScript it needs.)

The archives are written with the ``pmtiles`` package's writer (tiles in tile-id order,
clustered; identical tiles stored once), each to a hidden partial file published when
complete. Any static file host that answers ``Range`` requests serves the folder as it is
(object storage does).

Examples
--------
>>> import tempfile
>>> from pmtiles.reader import MmapSource, Reader
>>> d = tempfile.mkdtemp()
>>> figs = write_pmtiles(t, d, imagery=("relief",), max_zoom=2, name="dem")
>>> sorted(figs["archives"])
['dem.relief.pmtiles', 'dem.terrain-rgb.pmtiles']
>>> with open(f"{d}/dem.terrain-rgb.pmtiles", "rb") as fh:
...     r = Reader(MmapSource(fh)); r.header()["max_zoom"], r.metadata()["encoding"]
(2, 'mapbox')
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from geoterrain.core.atomicfiles import partial_path, publish
from geoterrain.exceptions import UsageError, WriteError, exists_error
from geoterrain.export.webtiles import ENCODINGS, IMAGERY, WebTiler, encode_image

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["write_pmtiles"]

MAPLIBRE_ENCODING = {"terrain-rgb": "mapbox", "terrarium": "terrarium"}


def _archive(path: Path, tiler: WebTiler, product: str, zooms: range, fmt: str,
             meta: dict, overwrite: bool, tick: Callable[[], None]) -> dict:
    """One archive of ``product`` (a height encoding or an imagery) → its figures."""
    from pmtiles.tile import Compression, TileType, zxy_to_tileid
    from pmtiles.writer import Writer

    if path.exists() and not overwrite:
        raise exists_error(path)
    jobs = []
    for z in zooms:
        xs, ys = tiler.tile_range(z)
        jobs += [(zxy_to_tileid(z, x, y), z, x, y) for x in xs for y in ys]
    jobs.sort()  # clustered: tile-id order
    tmp = partial_path(path)
    nbytes = 0
    try:
        with open(tmp, "wb") as fh:
            w = Writer(fh)
            for tid, z, x, y in jobs:
                if product in ENCODINGS:
                    data = encode_image(tiler.dem_tile(product, z, x, y), "png")
                else:
                    data = encode_image(tiler.image(product, z, x, y), fmt)
                w.write_tile(tid, data)
                nbytes += len(data)
                tick()
            (lon0, lat0), (west, south, east, north) = tiler.center, tiler.bounds
            w.finalize({
                "tile_type": TileType.WEBP if fmt == "webp" and product in IMAGERY
                else TileType.PNG,
                "tile_compression": Compression.NONE,
                "min_zoom": zooms.start, "max_zoom": zooms.stop - 1,
                "min_lon_e7": int(west * 1e7), "min_lat_e7": int(south * 1e7),
                "max_lon_e7": int(east * 1e7), "max_lat_e7": int(north * 1e7),
                "center_zoom": max(zooms.stop - 4, zooms.start),
                "center_lon_e7": int(lon0 * 1e7), "center_lat_e7": int(lat0 * 1e7)}, meta)
        publish(tmp, path, overwrite)
    except OSError as exc:
        raise WriteError(f"{path}: cannot write the archive ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return {"tiles": len(jobs), "bytes": path.stat().st_size, "tile_bytes": nbytes}


def write_pmtiles(terrain: TerrainLike, out_dir: str | Path, *,
                  encoding: str = "terrain-rgb",
                  imagery: Sequence[str] = ("relief", "hillshade"), fmt: str = "png",
                  min_zoom: int = 0, max_zoom: int | None = None, name: str | None = None,
                  cmap: str = "auto", overwrite: bool = False,
                  progress: Callable[[str, int, int], None] | None = None) -> dict:
    """Write the heights (``encoding``) and each of ``imagery`` as PMTiles archives in
    ``out_dir``; returns the figures (``files``: product → archive name).

    ``max_zoom``: default the first zoom whose pixels are at most the DEM's spacing
    (:attr:`WebTiler.max_zoom`); ``name``: the archives' prefix (default: the store's
    stem). :func:`geoterrain.serve.site.write_site` adds the page that shows them.
    """
    if encoding not in ENCODINGS:
        raise UsageError(f"unknown height encoding {encoding!r}; use {' or '.join(ENCODINGS)}")
    bad = [k for k in imagery if k not in IMAGERY]
    if bad:
        raise UsageError(f"unknown imagery {bad[0]!r}; use any of {', '.join(IMAGERY)}")
    if fmt not in ("png", "webp"):
        raise UsageError(f"unknown image format {fmt!r}; use png or webp")
    tiler = WebTiler(terrain, cmap)
    zmax = tiler.max_zoom if max_zoom is None else int(max_zoom)
    if not 0 <= min_zoom <= zmax <= 22:
        raise UsageError(f"zoom range {min_zoom}..{zmax} is not within 0..22")
    name = name or Path(str(terrain.path)).stem
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WriteError(f"{out}: cannot create the folder ({exc.strerror or exc})") from None
    zooms = range(min_zoom, zmax + 1)
    per = sum(len(xs) * len(ys) for xs, ys in map(tiler.tile_range, zooms))
    total, done = per * (1 + len(imagery)), [0]

    def tick() -> None:
        done[0] += 1
        if progress and (done[0] % 16 == 0 or done[0] == total):
            progress("pmtiles", done[0], total)

    t0 = time.perf_counter()
    common = {"name": name, "bounds": list(tiler.bounds), "center": list(tiler.center),
              "attribution": "geoterrain", "generator": "geoterrain"}
    archives, files = {}, {}
    for product in (encoding, *imagery):
        fname = f"{name}.{product}.pmtiles"
        meta = {**common, "type": "baselayer",
                "description": f"{name}: {product}"}
        if product in ENCODINGS:
            meta["encoding"] = MAPLIBRE_ENCODING[product]
        archives[fname] = _archive(out / fname, tiler, product, zooms, fmt, meta, overwrite,
                                   tick)
        files[product] = fname
    seconds = time.perf_counter() - t0
    return {"archives": archives, "files": files, "min_zoom": min_zoom, "max_zoom": zmax,
            "seconds": round(seconds, 2),
            "tiles": sum(a["tiles"] for a in archives.values()),
            "bytes": sum(a["bytes"] for a in archives.values())}

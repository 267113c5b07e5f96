"""A static site of a store: PMTiles archives and the MapLibre page that shows them, for
any static file host that answers ``Range`` requests (object storage does).

``write_site(t, "site/")`` writes the archives of
:func:`geoterrain.export.pmtilesets.write_pmtiles`, ``site/index.html`` (the map page of
``geoterrain serve`` with ``pmtiles://`` sources, relative URLs), ``site/NAME.json`` (the
store's bounds, zooms and files) and ``site/lib/`` with maplibre-gl and pmtiles copied
from a local npm install when one is found (else the page says how to add them).

Examples
--------
>>> import tempfile, os
>>> d = tempfile.mkdtemp()
>>> figs = write_site(t, d, imagery=("relief",), max_zoom=1, name="dem")
>>> sorted(os.listdir(d))[:3], figs["page"]
(['dem.json', 'dem.relief.pmtiles', 'dem.terrain-rgb.pmtiles'], 'index.html')
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

from geoterrain.core.atomicfiles import write_atomic
from geoterrain.exceptions import WriteError
from geoterrain.export.pmtilesets import write_pmtiles
from geoterrain.export.webtiles import IMAGERY, WebTiler
from geoterrain.serve.app import find_assets
from geoterrain.serve.pages import maplibre_page

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["write_site"]

KEEP = {"maplibre-gl": ("maplibre-gl.js", "maplibre-gl.css"), "pmtiles": ("pmtiles.js",)}


def write_site(terrain: TerrainLike, out_dir: str | Path, *, assets: str | Path | None = None,
               **kw) -> dict:
    """PMTiles archives of ``terrain`` (``kw``: :func:`write_pmtiles`'s options) and the
    map page over them in ``out_dir``; returns the figures (``page``, ``lib``: the
    packages copied)."""
    figs = write_pmtiles(terrain, out_dir, **kw)
    out = Path(out_dir)
    tiler = WebTiler(terrain)
    name = kw.get("name") or Path(str(terrain.path)).stem
    files = figs["files"]
    doc = {"name": name, "bounds": list(tiler.bounds), "center": list(tiler.center),
           "minzoom": figs["min_zoom"], "maxzoom": figs["max_zoom"],
           "encodings": {k: "pmtiles://" + v for k, v in files.items() if k not in IMAGERY},
           "imagery": {k: "pmtiles://" + v for k, v in files.items() if k in IMAGERY}}
    libs = find_assets(assets)
    copied = []
    for pkg, names in KEEP.items():
        if pkg not in libs:
            continue
        dst = out / "lib" / pkg
        try:
            dst.mkdir(parents=True, exist_ok=True)
            for f in names:
                shutil.copyfile(libs[pkg] / f, dst / f)
        except OSError as exc:
            raise WriteError(f"{dst}: cannot copy {pkg} ({exc.strerror or exc})") from None
        copied.append(pkg)
    page = maplibre_page({name: doc}, have_lib="maplibre-gl" in copied, pmtiles=True)
    write_atomic(out / "index.html", page)
    write_atomic(out / f"{name}.json", json.dumps(doc, indent=1))
    return {**figs, "page": "index.html", "lib": copied}

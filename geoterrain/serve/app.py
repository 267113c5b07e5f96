"""The HTTP tile server (Starlette): terrain and imagery tiles cut on request from stores.

Each store is served under its file name without the suffix, ``NAME``:

==========================================  ===========================================
``NAME/layer.json``                         quantized-mesh layer (CesiumTerrainProvider)
``NAME/{z}/{x}/{y}.terrain``                quantized-mesh-1.0 tile (TMS rows)
``NAME/rgb/{z}/{x}/{y}.png``                Terrain-RGB heights (XYZ; ``terrain-rgb/``
                                            is the same)
``NAME/terrarium/{z}/{x}/{y}.png``          Terrarium heights (XYZ)
``NAME/{relief,hillshade,slope,error}/      imagery, XYZ; ``NAME/tms/{product}/…``
{z}/{x}/{y}.{png,webp}``                    counts rows from the south (TMS)
``NAME/{product}.json``                     TileJSON of a raster product (MapLibre)
==========================================  ===========================================

and ``/`` (an index), ``/cesium.html``, ``/maplibre.html``, ``/stores.json``,
``/stats.json`` (cache, decodes, tiles built) and ``/lib/{cesium,maplibre-gl,pmtiles}/…``
(the JavaScript packages, from a local ``node_modules``).

Tiles are built in a worker thread under the store's lock (the terrain is not
thread-safe; a second request for the same tile waits and finds it cached), and kept in a
:class:`~geoterrain.serve.cache.ByteCache` of finished responses within a byte budget.
Every response carries CORS headers; tiles carry a strong ETag (``If-None-Match`` → 304)
and ``Cache-Control``. A path that is not one of the forms above is a 400 with one line
(a ``..`` or ``.`` segment, an encoded slash, dot or backslash, a non-integer z/x/y), a
tile outside the data or the world a 404 (a terrain tile over nodata too: the tile set
``tiles --format quantized-mesh`` writes has none there); nothing is ever read from the
file system but the stores given and the package folders, and a static path is resolved
and checked to lie inside its folder.

Examples
--------
>>> app = create_app([t.path])
>>> status, headers, body = asgi_get(app, f"/{t.path.stem}/rgb.json")
>>> status, json.loads(body)["encoding"], headers["access-control-allow-origin"]
(200, 'mapbox', '*')
>>> asgi_get(app, "/../../etc/passwd")[0]
400
"""

from __future__ import annotations

import gzip
import hashlib
import json
import logging
import math
import mimetypes
import re
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from geoterrain.exceptions import GeoterrainError, UsageError
from geoterrain.export.qmeshformat import metadata_block, split_extensions
from geoterrain.export.qmeshtiles import QuantizedMeshTiles
from geoterrain.export.webtiles import ENCODINGS, IMAGERY, WebTiler, encode_image
from geoterrain.serve.cache import ByteCache

__all__ = ["ASSET_PACKAGES", "ServedStore", "ServerApp", "asgi_get", "create_app", "find_assets",
           "negotiate_terrain", "open_stores"]

log = logging.getLogger("geoterrain.serve")

# npm package → the folder inside it that is served under /lib/PACKAGE/
ASSET_PACKAGES = {"cesium": "Build/Cesium", "maplibre-gl": "dist", "pmtiles": "dist"}
RESERVED = {"lib", "index.html", "cesium.html", "maplibre.html", "stores.json", "stats.json",
            "favicon.ico", "tms"}
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
INT_RE = re.compile(r"^[0-9]{1,9}$")
QM_TYPE = "application/vnd.quantized-mesh"
QM_EXTENSIONS = ("octvertexnormals", "watermask", "metadata")
TILE_CACHE_CONTROL = "public, max-age=3600"
CORS = {"access-control-allow-origin": "*",
        "access-control-allow-methods": "GET, HEAD, OPTIONS",
        "access-control-allow-headers": "*",
        "access-control-expose-headers": "ETag, Content-Length, Content-Encoding, "
                                         "X-Declared-Error"}
PRODUCT_ALIASES = {"rgb": "terrain-rgb", "terrain-rgb": "terrain-rgb",
                   "terrarium": "terrarium", **{k: k for k in IMAGERY}}


class HTTPProblem(Exception):
    """An answer other than 200: its status and one line."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


@dataclass
class ServedStore:
    """One store as the server holds it: its terrain, tile sources, lock and counters."""

    name: str
    terrain: object
    web: WebTiler
    qmesh: QuantizedMeshTiles
    lock: threading.Lock = field(default_factory=threading.Lock)
    built: dict = field(default_factory=dict)  # kind → tiles built

    def count(self, kind: str) -> None:
        self.built[kind] = self.built.get(kind, 0) + 1

    def describe(self) -> dict:
        """What a page needs to show the store (``/stores.json``)."""
        w = self.web
        return {"name": self.name, "bounds": list(w.bounds), "center": list(w.center),
                "minzoom": 0, "maxzoom": w.max_zoom, "terrain_maxzoom": self.qmesh.max_zoom,
                "heights": list(self.qmesh.hrange),
                "terrain": f"{self.name}/layer.json",
                "encodings": {e: f"{self.name}/{e}/{{z}}/{{x}}/{{y}}.png" for e in ENCODINGS},
                "imagery": {k: f"{self.name}/{k}/{{z}}/{{x}}/{{y}}.png" for k in IMAGERY}}


def find_assets(explicit: str | Path | None = None) -> dict[str, Path]:
    """The served folder of each JavaScript package found: ``explicit`` (a ``node_modules``
    folder), else ``$GEOTERRAIN_WEB_ASSETS``, ``./node_modules``, ``./.browser/node_modules``
    and the source checkout's ``.browser/node_modules`` (``make browser``).

    Examples
    --------
    >>> isinstance(find_assets("no-such-folder"), dict)
    True
    """
    import os

    if explicit is not None:
        roots = [Path(explicit)]
    else:
        roots = [Path(p) for p in (os.environ.get("GEOTERRAIN_WEB_ASSETS"),) if p]
        roots += [Path("node_modules"), Path(".browser") / "node_modules",
                  Path(__file__).resolve().parents[2] / ".browser" / "node_modules"]
    found: dict[str, Path] = {}
    for pkg, sub in ASSET_PACKAGES.items():
        for r in roots:
            d = r / pkg / sub
            if d.is_dir():
                found[pkg] = d.resolve()
                break
    return found


def open_stores(paths: Sequence[str | Path | tuple[str, str | Path]], *, geoid: str | None = None,
                max_error: float = 1.0, cmap: str = "auto",
                decode_bytes: int = 512 << 20, mesher: str = "tin") -> dict[str, ServedStore]:
    """Open each store (read-only) and its tile sources, keyed by name (the file's stem,
    or the name of a ``(name, path)`` pair); a one-line :class:`UsageError` for a
    duplicate, reserved or unusable name."""
    import geoterrain

    out: dict[str, ServedStore] = {}
    try:
        for item in paths:
            name, p = (item[0], Path(item[1])) if isinstance(item, tuple) else \
                (Path(item).stem, Path(item))
            if not NAME_RE.match(name) or name in RESERVED:
                raise UsageError(f"{p}: cannot serve a store named {name!r} (names are "
                                 "letters, digits, . _ -, and not " + ", ".join(sorted(RESERVED))
                                 + "); rename the file")
            if name in out:
                raise UsageError(f"two stores are named {name!r}; rename one of them")
            t = geoterrain.open(p, cache_bytes=decode_bytes)
            try:
                out[name] = ServedStore(name, t, WebTiler(t, cmap),
                                        QuantizedMeshTiles(t, max_error=max_error, geoid=geoid,
                                                           mesher=mesher))
                out[name].qmesh.layer(name)  # every level's tiles, found before any request
            except BaseException:
                t.close()
                raise
    except BaseException:
        for s in out.values():
            s.terrain.close()
        raise
    if not out:
        raise UsageError("give at least one store to serve")
    return out


# -------------------------------------------------------------------- negotiation
def _accept(header: str | None) -> list[tuple[str, dict, float]]:
    """An Accept header's media ranges: (type, params, q)."""
    out = []
    for part in (header or "").split(","):
        bits = [b.strip() for b in part.split(";") if b.strip()]
        if not bits:
            continue
        params = {}
        for b in bits[1:]:
            k, _, v = b.partition("=")
            params[k.strip().lower()] = v.strip().strip('"')
        try:
            q = float(params.pop("q", "1"))
        except ValueError:
            q = 1.0
        out.append((bits[0].lower(), params, q))
    return out


def negotiate_terrain(accept: str | None, query_ext: str | None) -> tuple[str, ...] | None:
    """The extensions to put in a quantized-mesh tile, or None when the client accepts no
    form of it (→ 406). Cesium asks ``application/vnd.quantized-mesh;extensions=a-b-c``;
    a client that takes any type (or none named) gets the ``?extensions=`` it names, else
    all of them.

    Examples
    --------
    >>> negotiate_terrain("application/vnd.quantized-mesh;extensions=octvertexnormals-"
    ...                   "metadata,application/octet-stream;q=0.9", None)
    ('octvertexnormals', 'metadata')
    >>> negotiate_terrain(None, None), negotiate_terrain("text/html", None)
    (('octvertexnormals', 'watermask', 'metadata'), None)
    """
    ranges = [r for r in _accept(accept) if r[2] > 0]

    def pick(text: str | None) -> tuple[str, ...]:
        asked = [e for e in (text or "").split("-") if e]
        return tuple(e for e in QM_EXTENSIONS if e in asked)

    for typ, params, _ in sorted(ranges, key=lambda r: -r[2]):
        if typ == QM_TYPE:
            return pick(params.get("extensions", query_ext or ""))
        if typ in ("application/octet-stream", "*/*", "application/*"):
            return pick(query_ext) if query_ext is not None else QM_EXTENSIONS
    return None if ranges or (accept or "").strip() else QM_EXTENSIONS


def _gzip_ok(header: str | None) -> bool:
    for part in (header or "").split(","):
        bits = [b.strip() for b in part.split(";")]
        if bits[0].lower() in ("gzip", "*"):
            q = next((b[2:] for b in bits[1:] if b.startswith("q=")), "1")
            try:
                return float(q) > 0
            except ValueError:
                return True
    return False


def _etag(body: bytes) -> str:
    return '"' + hashlib.blake2b(body, digest_size=12).hexdigest() + '"'


# -------------------------------------------------------------------- the app
def create_app(stores: Sequence[str | Path] | dict[str, ServedStore], *,
               cache_bytes: int = 256 << 20, assets: str | Path | None = None,
               geoid: str | None = None, max_error: float = 1.0, cmap: str = "auto",
               mesher: str = "tin") -> Starlette:
    """The ASGI app serving ``stores`` (paths, or :func:`open_stores`' result).

    ``cache_bytes``: the budget of finished tiles kept in memory; ``assets``: a
    ``node_modules`` folder holding cesium, maplibre-gl and pmtiles (:func:`find_assets`);
    ``geoid``, ``max_error``, ``mesher``: as ``tiles --format quantized-mesh``; ``cmap``:
    the relief's palette. The app's ``state`` holds ``stores``, ``cache`` and ``counters``.
    """
    from geoterrain.serve.pages import cesium_page, index_page, maplibre_page

    served = stores if isinstance(stores, dict) else open_stores(
        stores, geoid=geoid, max_error=max_error, cmap=cmap, mesher=mesher)
    cache = ByteCache(cache_bytes)
    libs = find_assets(assets)
    counters = {"requests": 0, "errors_4xx": 0, "errors_5xx": 0, "started": time.time()}

    def stats() -> dict:
        return {"cache": cache.stats(), "requests": counters["requests"],
                "errors_4xx": counters["errors_4xx"], "errors_5xx": counters["errors_5xx"],
                "stores": {n: {"stored_tiles": len(s.terrain.tile_info),
                               "decoded_tiles": s.terrain.decoded_tiles,
                               "decoded_normals": s.terrain.decoded_normals,
                               "bytes_read": s.terrain.bytes_read,
                               "tiles_built": dict(s.built)} for n, s in served.items()},
                "assets": sorted(libs)}

    # ---------------------------------------------------------- builders (threads)
    def build(store: ServedStore, kind: str, z: int, x: int, y: int, fmt: str
              ) -> tuple[bytes, dict]:
        """The tile's canonical bytes (terrain: not gzipped, normals and water mask) and
        what its headers need."""
        if kind == "terrain":
            data, bound, _ = store.qmesh.tile(z, x, y)
            # the declared bound, rounded up to 0.1 mm (as the tile set's geoterrain.json)
            return data, {"x-declared-error": f"{math.ceil(bound * 1e4) / 1e4:.4f}"}
        if kind in ENCODINGS:
            return encode_image(store.web.dem_tile(kind, z, x, y), "png"), {}
        return encode_image(store.web.image(kind, z, x, y), fmt), {}

    def cached_tile(store: ServedStore, kind: str, z: int, x: int, y: int, fmt: str
                    ) -> tuple[bytes, dict]:
        key = (store.name, kind, z, x, y, fmt, "raw")
        hit = cache.get(key)
        if hit is not None:
            return hit
        with store.lock:  # one builder per terrain; a waiter finds the tile cached
            hit = cache.get(key)
            if hit is not None:
                return hit
            body, meta = build(store, kind, z, x, y, fmt)
            store.count(kind)
            cache.put(key, body, meta)
        return body, meta

    def terrain_variant(store: ServedStore, z: int, x: int, y: int,
                        exts: tuple[str, ...], gz: bool) -> tuple[bytes, dict]:
        key = (store.name, "terrain", z, x, y, exts, gz)
        hit = cache.get(key)
        if hit is not None:
            return hit
        data, meta = cached_tile(store, "terrain", z, x, y, "")
        core, blocks = split_extensions(data)
        parts = [core]
        for e in exts:
            if e == "metadata":
                parts.append(metadata_block(store.qmesh.metadata(z, x, y)))
            elif e in blocks:
                parts.append(blocks[e])
        body = b"".join(parts)
        ctype = QM_TYPE + (";extensions=" + "-".join(exts) if exts else "")
        headers = {"content-type": ctype, **meta,
                   "vary": "Accept, Accept-Encoding"}
        if gz:
            body = gzip.compress(body, compresslevel=6, mtime=0)
            headers["content-encoding"] = "gzip"
        headers["etag"] = _etag(body)
        cache.put(key, body, headers)
        return body, headers

    # ---------------------------------------------------------- routing
    def parse(request: Request) -> list[str]:
        raw = request.scope.get("raw_path") or request.url.path.encode()
        raw = raw.split(b"?", 1)[0].decode("latin-1")
        if re.search(r"%(2[eEfF]|5[cC]|00)", raw) or "\\" in raw or "\x00" in raw:
            raise HTTPProblem(400, "malformed path: encoded '.', '/' or '\\' is not allowed")
        path = unquote(raw)
        segs = path.split("/")[1:]
        if any(s in (".", "..") for s in segs) or "//" in path:
            raise HTTPProblem(400, "malformed path: '.', '..' and empty segments are not allowed")
        return segs

    def tile_xyz(segs: list[str], ext_re: str) -> tuple[int, int, int, str]:
        z, x, last = segs
        m = re.fullmatch(r"([0-9]{1,9})\.(" + ext_re + ")", last)
        if not (INT_RE.match(z) and INT_RE.match(x) and m):
            raise HTTPProblem(400, f"malformed tile path {'/'.join(segs)!r}: expected "
                                   f"{{z}}/{{x}}/{{y}}.{ext_re.replace('|', ' or .')} with "
                                   "integer z, x, y")
        return int(z), int(x), int(m.group(1)), m.group(2)

    def ok(body: bytes, ctype: str, request: Request, cache_control: str = "no-cache",
           extra: dict | None = None) -> Response:
        headers = {"cache-control": cache_control, **(extra or {})}
        headers.setdefault("etag", _etag(body))
        if request.headers.get("if-none-match") == headers["etag"]:
            return Response(status_code=304, headers={
                k: v for k, v in headers.items() if k != "content-type"})
        if "content-type" in headers:
            ctype = headers.pop("content-type")
        return Response(b"" if request.method == "HEAD" else body, media_type=ctype,
                        headers={**headers, "content-length": str(len(body))})

    def static(pkg: str, rest: list[str], request: Request) -> Response:
        base = libs.get(pkg)
        if base is None:
            raise HTTPProblem(404, f"the npm package {pkg} is not installed: npm install "
                                   f"{pkg} and start the server with --assets node_modules")
        if not rest or any(not s for s in rest):
            raise HTTPProblem(404, "not found")
        p = (base / "/".join(rest)).resolve()
        if not p.is_relative_to(base) or not p.is_file():
            raise HTTPProblem(404, "not found")
        data = p.read_bytes()
        ctype = mimetypes.guess_type(p.name)[0] or "application/octet-stream"
        return ok(data, ctype, request, "public, max-age=86400")

    def tilejson(store: ServedStore, product: str, request: Request) -> Response:
        w = store.web
        enc = {"terrain-rgb": "mapbox", "terrarium": "terrarium"}.get(product)
        base = str(request.base_url).rstrip("/")
        seg = "rgb" if product == "terrain-rgb" else product
        doc = {"tilejson": "3.0.0", "name": f"{store.name} {product}", "scheme": "xyz",
               "tiles": [f"{base}/{store.name}/{seg}/{{z}}/{{x}}/{{y}}.png"],
               "bounds": list(w.bounds), "center": [*w.center, max(w.max_zoom - 3, 0)],
               "minzoom": 0, "maxzoom": w.max_zoom, "tileSize": 256,
               "attribution": "geoterrain"}
        if enc:
            doc["encoding"] = enc
        return ok(json.dumps(doc).encode(), "application/json", request)

    async def tile(store: ServedStore, segs: list[str], request: Request) -> Response:
        if segs[0] == "layer.json" and len(segs) == 1:
            doc = store.qmesh.layer(store.name)
            return ok(json.dumps(doc).encode(), "application/json", request)
        if len(segs) == 1 and segs[0].endswith(".json"):
            product = PRODUCT_ALIASES.get(segs[0][:-5])
            if product is None:
                raise HTTPProblem(404, f"no TileJSON {segs[0]!r}; products: rgb, terrarium, "
                                       + ", ".join(IMAGERY))
            return tilejson(store, product, request)
        if len(segs) == 3:  # {z}/{x}/{y}.terrain
            z, x, y, _ = tile_xyz(segs, "terrain")
            if not store.qmesh.exists(z, x, y):
                raise HTTPProblem(404, f"no terrain tile {z}/{x}/{y}: outside the data or "
                                       f"over nodata (levels 0..{store.qmesh.max_zoom}, "
                                       "see layer.json)")
            exts = negotiate_terrain(request.headers.get("accept"),
                                     request.query_params.get("extensions"))
            if exts is None:
                raise HTTPProblem(406, "a quantized-mesh tile: accept "
                                       "application/vnd.quantized-mesh or */*")
            gz = _gzip_ok(request.headers.get("accept-encoding"))
            body, headers = await run_in_threadpool(terrain_variant, store, z, x, y, exts, gz)
            return ok(body, QM_TYPE, request, TILE_CACHE_CONTROL, dict(headers))
        tms = segs[0] == "tms"
        if tms:
            segs = segs[1:]
        if len(segs) == 4 and segs[0] in PRODUCT_ALIASES:
            kind = PRODUCT_ALIASES[segs[0]]
            z, x, y, fmt = tile_xyz(segs[1:], "png" if kind in ENCODINGS else "png|webp")
            if tms and z < 31 and y < (1 << z):
                y = (1 << z) - 1 - y
            if not store.web.exists(z, x, y):
                raise HTTPProblem(404, f"no {segs[0]} tile {'/'.join(segs[1:])}: outside the "
                                       f"data or the world (zooms 0..24)")
            body, _ = await run_in_threadpool(cached_tile, store, kind, z, x, y, fmt)
            return ok(body, f"image/{fmt}", request, TILE_CACHE_CONTROL)
        if segs and segs[0] in PRODUCT_ALIASES or tms:
            raise HTTPProblem(400, f"malformed tile path {'/'.join(segs)!r}: expected "
                                   f"{store.name}/PRODUCT/{{z}}/{{x}}/{{y}}.png")
        raise HTTPProblem(404, f"no such resource under {store.name}/")

    async def endpoint(request: Request) -> Response:
        counters["requests"] += 1
        if request.method == "OPTIONS":
            return Response(status_code=204, headers={"access-control-max-age": "86400"})
        try:
            segs = parse(request)
            head = segs[0] if segs else ""
            if head in ("", "index.html") and len(segs) == 1:
                return ok(index_page(served).encode(), "text/html; charset=utf-8", request)
            if head == "cesium.html" and len(segs) == 1:
                return ok(cesium_page(served, "cesium" in libs).encode(),
                          "text/html; charset=utf-8", request)
            if head == "maplibre.html" and len(segs) == 1:
                return ok(maplibre_page(served, "maplibre-gl" in libs).encode(),
                          "text/html; charset=utf-8", request)
            if head == "stores.json" and len(segs) == 1:
                doc = [s.describe() for s in served.values()]
                return ok(json.dumps(doc).encode(), "application/json", request)
            if head == "stats.json" and len(segs) == 1:
                return Response(json.dumps(stats()), media_type="application/json",
                                headers={"cache-control": "no-store"})
            if head == "lib" and len(segs) >= 2:
                return static(segs[1], segs[2:], request)
            if head in served and len(segs) >= 2:
                return await tile(served[head], segs[1:], request)
            if head == "favicon.ico":
                return Response(status_code=204)
            raise HTTPProblem(404, f"not found; stores: {', '.join(served)} (see /)")
        except HTTPProblem as exc:
            counters["errors_4xx"] += 1
            return Response(str(exc) + "\n", status_code=exc.status, media_type="text/plain",
                            headers={"cache-control": "no-store"})
        except GeoterrainError as exc:
            counters["errors_5xx"] += 1
            log.error("%s: %s", request.url.path, exc)
            return Response(f"{exc}\n", status_code=500, media_type="text/plain")

    async def cors(scope, receive, send):
        async def send_cors(message):
            if message["type"] == "http.response.start":
                have = {k.lower() for k, _ in message.get("headers", [])}
                message["headers"] = list(message.get("headers", [])) + [
                    (k.encode(), v.encode()) for k, v in CORS.items() if k.encode() not in have]
            await send(message)
        await inner(scope, receive, send_cors if scope["type"] == "http" else send)

    inner = Starlette(routes=[Route("/{path:path}", endpoint,
                                    methods=["GET", "HEAD", "OPTIONS"])])
    inner.state.stores, inner.state.cache, inner.state.counters = served, cache, counters
    inner.state.stats = stats
    return ServerApp(cors, inner.state)


class ServerApp:
    """The ASGI app: Starlette's, with CORS headers added to every response (404s and
    405s included). ``state`` holds ``stores``, ``cache``, ``counters`` and ``stats()``."""

    def __init__(self, asgi, state):
        self._asgi, self.state = asgi, state

    async def __call__(self, scope, receive, send):
        await self._asgi(scope, receive, send)


def asgi_get(app, path: str, headers: dict[str, str] | None = None, method: str = "GET"
             ) -> tuple[int, dict[str, str], bytes]:
    """One request to an ASGI ``app`` in this process, ``path`` sent as it is (no client
    normalises it): (status, headers with lower-case names, body).

    Examples
    --------
    >>> asgi_get(create_app([t.path]), "/stats.json")[0]
    200
    """
    import asyncio

    raw, _, query = path.partition("?")
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1",
             "method": method, "scheme": "http", "path": unquote(raw),
             "raw_path": raw.encode("latin-1"), "query_string": query.encode("latin-1"),
             "root_path": "", "server": ("127.0.0.1", 80), "client": ("127.0.0.1", 1),
             "headers": [(k.lower().encode(), v.encode()) for k, v in (headers or {}).items()]
             + [(b"host", b"127.0.0.1")]}
    out: dict = {"body": b""}

    async def receive():
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message):
        if message["type"] == "http.response.start":
            out["status"] = message["status"]
            out["headers"] = {k.decode().lower(): v.decode() for k, v in message["headers"]}
        elif message["type"] == "http.response.body":
            out["body"] += message.get("body", b"")

    asyncio.run(app(scope, receive, send))
    return out["status"], out["headers"], out["body"]

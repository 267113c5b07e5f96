"""`geoterrain serve`: tile bytes against the DEM, HTTP behaviour, safety, the cache's
budget, decodes and concurrency (a server on 127.0.0.1 or the app in process).

The DEM: a 129² ridged terrain in EPSG:4326 at 3″ (1.5 km of relief). Expected heights are
computed here from the GeoTIFF (rasterio) and pyproj, never by the tiler's code.
"""

from __future__ import annotations

import concurrent.futures
import gzip
import http.client
import json
import math
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hst

import geoterrain
from tests.conftest import write_tif

pytest.importorskip("starlette")
pytest.importorskip("uvicorn")

from geoterrain.serve.app import asgi_get, create_app  # noqa: E402

SPACING = 1 / 1200


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("serve")
    z = generate("ridged", 129, seed=6).astype(np.float32)
    z = (z - z.min()) / (z.max() - z.min()) * 1500.0 + 20.0
    tif = write_tif(d / "ridge.tif", z, crs="EPSG:4326", origin=(10.0, 46.0), spacing=SPACING)
    store = geoterrain.preprocess(tif, d / "ridge.geoterrain", tile_size=32)
    return tif, store


@pytest.fixture()
def app(dem):
    return create_app([dem[1]], cache_bytes=64 << 20)


def _dem_array(tif):
    import rasterio

    with rasterio.open(tif) as src:
        return src.read(1).astype(np.float64), src.transform


def _bilinear_at(tif, lon, lat):
    """The DEM's bilinear surface at lon/lat (pixel centres at integers); NaN outside."""
    h, tr = _dem_array(tif)
    i = (np.asarray(lat) - tr.f) / tr.e - 0.5  # north-up: row, column of pixel centres
    j = (np.asarray(lon) - tr.c) / tr.a - 0.5
    H, W = h.shape
    out = np.full(i.shape, np.nan)
    ok = (i >= 0) & (i <= H - 1) & (j >= 0) & (j <= W - 1)
    i0 = np.minimum(np.floor(i[ok]).astype(int), H - 2)
    j0 = np.minimum(np.floor(j[ok]).astype(int), W - 2)
    u, v = i[ok] - i0, j[ok] - j0
    out[ok] = (h[i0, j0] * (1 - u) * (1 - v) + h[i0, j0 + 1] * (1 - u) * v
               + h[i0 + 1, j0] * u * (1 - v) + h[i0 + 1, j0 + 1] * u * v)
    return out


def _png(body):
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(body)))


def _max_zoom_tile(app, name):
    """The max-zoom XYZ tile holding the DEM's centre."""
    st = app.state.stores[name]
    z = st.web.max_zoom
    lon, lat = st.web.center
    n = 1 << z
    x = int((lon + 180) / 360 * n)
    y = int((1 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2 * n)
    return z, x, y


# ------------------------------------------------------------------ tile contents
@pytest.mark.parametrize("encoding,seg,step", [("terrain-rgb", "rgb", 0.1),
                                               ("terrarium", "terrarium", 1 / 256)])
def test_dem_tiles_are_exact_to_the_encoding_step(app, dem, encoding, seg, step):
    from pyproj import Transformer

    from geoterrain.export.webtiles import decode_heights

    z, x, y = _max_zoom_tile(app, "ridge")
    status, headers, body = asgi_get(app, f"/ridge/{seg}/{z}/{x}/{y}.png")
    assert status == 200 and headers["content-type"] == "image/png"
    got = decode_heights(_png(body), encoding)
    # pixel k at k/256 of the tile (its top-left corner), EPSG:3857 → lon/lat by pyproj
    size = 2 * math.pi * 6378137.0 / (1 << z)
    k = np.arange(256) / 256.0
    mx, my = np.meshgrid(-math.pi * 6378137.0 + (x + k) * size,
                         math.pi * 6378137.0 - (y + k) * size)
    lon, lat = Transformer.from_crs(3857, 4326, always_xy=True).transform(mx, my)
    want = _bilinear_at(dem[0], lon, lat)
    ok = np.isfinite(want)
    assert ok.mean() > 0.1  # the DEM covers part of the tile
    err = np.abs(got[ok] - want[ok])
    assert err.max() <= step / 2 + 1e-6, err.max()
    assert np.all(got[~ok] == 0.0)  # outside the DEM: 0 m


@pytest.mark.parametrize("mesher", ["rtin", "tin"])
def test_terrain_tiles_hold_their_declared_error_and_share_edges(dem, mesher):
    """Tiles cut on request (rtin, or --mesher tin), decoded by quantized-mesh-tile: within
    their declared error at every DEM sample they cover, edge vertices shared exactly."""
    import io

    from matplotlib.tri import LinearTriInterpolator, Triangulation
    from quantized_mesh_tile.terrain import TerrainTile

    from geoterrain.export.qmeshformat import QMAX, split_extensions, tile_rect

    app = create_app([dem[1]], cache_bytes=64 << 20, mesher=mesher)
    st = app.state.stores["ridge"]
    assert st.qmesh.mesher == mesher
    z = st.qmesh.max_zoom
    tiles = sorted(st.qmesh.level_tiles(z))
    h, tr = _dem_array(dem[0])
    ii, jj = np.meshgrid(np.arange(h.shape[0]), np.arange(h.shape[1]), indexing="ij")
    slon, slat = tr.c + tr.a * (jj + 0.5), tr.f + tr.e * (ii + 0.5)
    lo, hi = st.qmesh.hrange
    meshes = {}
    for x, y in tiles:
        status, headers, body = asgi_get(app, f"/ridge/{z}/{x}/{y}.terrain",
                                         {"accept-encoding": "identity"})
        assert status == 200 and "content-encoding" not in headers
        declared = float(headers["x-declared-error"])
        core, ext = split_extensions(body)
        assert set(ext) == {"octvertexnormals", "watermask", "metadata"}
        # vertices (u, v, h) decoded by the quantized-mesh-tile package
        t = TerrainTile()
        t.fromBytesIO(io.BytesIO(core), hasLighting=False, hasWatermask=False)
        w, s, e, n = tile_rect(z, x, y)
        u, v = np.array(t.u, float), np.array(t.v, float)
        lon, lat = w + (e - w) * u / QMAX, s + (n - s) * v / QMAX
        hz = lo + (hi - lo) * np.array(t.h, float) / QMAX
        meshes[(x, y)] = (lon, lat, hz)
        tri = Triangulation(lon, lat, np.array(t.indices).reshape(-1, 3))
        inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n)
        on = tri.get_trifinder()(slon[inside], slat[inside]) >= 0
        mz = LinearTriInterpolator(tri, hz)(slon[inside][on], slat[inside][on])
        err = np.abs(np.asarray(mz) - h[inside][on])
        assert on.mean() > 0.9
        assert err.max() <= declared + 1e-6, (x, y, err.max(), declared)
    # neighbours share their edge vertices exactly
    shared = 0
    for (x, y), (lon, lat, hz) in meshes.items():
        if (x + 1, y) in meshes:
            e = tile_rect(z, x, y)[2]
            lon2, lat2, hz2 = meshes[(x + 1, y)]
            a = sorted(zip(lat[np.isclose(lon, e)], hz[np.isclose(lon, e)], strict=True))
            b = sorted(zip(lat2[np.isclose(lon2, e)], hz2[np.isclose(lon2, e)], strict=True))
            assert np.allclose(a, b, rtol=0, atol=1e-9) and len(a) > 2
            shared += 1
    assert shared > 0


def test_imagery_tiles_xyz_tms_png_webp(app):
    z, x, y = _max_zoom_tile(app, "ridge")
    for what in ("relief", "hillshade", "slope", "error"):
        status, headers, body = asgi_get(app, f"/ridge/{what}/{z}/{x}/{y}.png")
        assert status == 200 and headers["content-type"] == "image/png"
        img = _png(body)
        assert img.shape == (256, 256, 4) and img[..., 3].max() == 255
        assert img[img[..., 3] == 255][:, :3].std() > 1  # not one flat colour
    tms = (1 << z) - 1 - y
    a = asgi_get(app, f"/ridge/relief/{z}/{x}/{y}.png")[2]
    assert asgi_get(app, f"/ridge/tms/relief/{z}/{x}/{tms}.png")[2] == a
    status, headers, webp = asgi_get(app, f"/ridge/relief/{z}/{x}/{y}.webp")
    assert status == 200 and headers["content-type"] == "image/webp"
    assert np.array_equal(_png(webp), _png(a))  # lossless
    # hillshade is render's shading factor f in [0.35, 1.25] as grey 255 · f / 1.25
    hs = _png(asgi_get(app, f"/ridge/hillshade/{z}/{x}/{y}.png")[2])
    on = hs[..., 3] == 255
    assert (hs[on][:, 0] == hs[on][:, 1]).all() and (hs[on][:, 0] == hs[on][:, 2]).all()
    assert hs[on][:, 0].min() >= math.floor(255 * 0.35 / 1.25)


# ------------------------------------------------------------------ HTTP behaviour
@pytest.mark.fast
def test_layer_json_tilejson_cors_etag_and_negotiation(app):
    status, headers, body = asgi_get(app, "/ridge/layer.json")
    layer = json.loads(body)
    assert status == 200 and layer["format"] == "quantized-mesh-1.0"
    assert set(layer["extensions"]) == {"octvertexnormals", "watermask", "metadata"}
    tj = json.loads(asgi_get(app, "/ridge/terrarium.json")[2])
    assert tj["encoding"] == "terrarium" and tj["tiles"][0].endswith("/ridge/terrarium/"
                                                                     "{z}/{x}/{y}.png")
    z = layer["maxzoom"]
    r = layer["available"][z][0]
    path = f"/ridge/{z}/{r['startX']}/{r['startY']}.terrain"
    cesium = ("application/vnd.quantized-mesh;extensions=octvertexnormals-watermask-metadata,"
              "application/octet-stream;q=0.9,*/*;q=0.01")
    status, headers, body = asgi_get(app, path, {"accept": cesium,
                                                 "accept-encoding": "gzip, deflate"})
    assert status == 200 and headers["content-encoding"] == "gzip"
    assert headers["content-type"].startswith("application/vnd.quantized-mesh;extensions=")
    assert "Accept" in headers["vary"] and headers["cache-control"].startswith("public")
    raw = gzip.decompress(body)
    # only the extensions asked for
    from geoterrain.export.qmeshformat import split_extensions

    _, h2, b2 = asgi_get(app, path, {"accept": "application/vnd.quantized-mesh;"
                                     "extensions=octvertexnormals"})
    assert h2["content-type"] == "application/vnd.quantized-mesh;extensions=octvertexnormals"
    assert set(split_extensions(b2)[1]) == {"octvertexnormals"}
    assert split_extensions(b2)[0] == split_extensions(raw)[0]
    assert asgi_get(app, path, {"accept": "text/html"})[0] == 406
    # ETag → 304, and every answer carries CORS
    s304, h304, b304 = asgi_get(app, path, {"accept": cesium, "accept-encoding": "gzip",
                                            "if-none-match": headers["etag"]})
    assert s304 == 304 and b304 == b""
    for p in (path, "/ridge/nothing", "/ridge/rgb/x/1/1.png", "/stats.json", "/"):
        assert asgi_get(app, p)[1]["access-control-allow-origin"] == "*"
    assert asgi_get(app, "/", method="POST")[1]["access-control-allow-origin"] == "*"
    status, headers, _ = asgi_get(app, "/ridge/layer.json", method="OPTIONS")
    assert status == 204 and "GET" in headers["access-control-allow-methods"]
    status, headers, body = asgi_get(app, "/ridge/rgb.json", method="HEAD")
    assert status == 200 and body == b"" and int(headers["content-length"]) > 0


BAD_PATHS = [
    "/../../../../etc/passwd", "/ridge/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd",
    "/ridge/%2e%2e%2f%2e%2e%2fetc%2fpasswd", "/ridge/rgb/..%2f..%2f..%2fetc/passwd",
    "/lib/cesium/../../../../../etc/passwd", "/lib/cesium/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
    "/lib/cesium/..%5c..%5c..%5cetc%5cpasswd", "/lib/cesium/%252e%252e/etc/passwd",
    "//etc/passwd", "/etc/passwd", "/ridge//etc/passwd", "/%2fetc%2fpasswd",
    "/lib/cesium//etc/passwd", "/lib/cesium/%00", "/ridge/./layer.json", "/./stats.json",
    "/ridge/rgb/99999/0/0.png", "/ridge/99999/0/0.terrain", "/ridge/rgb/3/999999999/0.png",
    "/ridge/rgb/10/0/999999999.png", "/ridge/1000000000000/1/1.terrain",
    "/ridge/rgb/-1/0/0.png", "/ridge/rgb/1.5/0/0.png", "/ridge/rgb/1e3/0/0.png",
    "/ridge/relief/40/1/1.png", "/ridge/tms/relief/99/1/1.png", "/ridge/rgb/0/0/0.jpg",
    "/ridge/relief/0/0/0.png/extra", "/ridge/" + "9" * 5000 + "/0/0.terrain",
    "/lib/nope/x.js", "/lib/../etc/passwd", "/ridge/layer.json/..",
]


def _live(app):
    """A uvicorn server for ``app`` on 127.0.0.1 (any free port) in a thread."""
    import uvicorn

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    server = uvicorn.Server(uvicorn.Config(app, log_level="error", lifespan="off"))
    th = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    th.start()
    t0 = time.time()
    while not server.started and time.time() - t0 < 20:
        time.sleep(0.05)
    return server, th, sock.getsockname()[1]


def _raw_get(port, path, headers=None):
    """GET ``path`` exactly as written (no client normalises it)."""
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        c.putrequest("GET", path, skip_accept_encoding=True)
        for k, v in (headers or {}).items():
            c.putheader(k, v)
        c.endheaders()
        r = c.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        c.close()


@pytest.mark.fast
def test_paths_outside_the_stores_absurd_zooms_and_huge_xy_never_escape(dem, tmp_path):
    # an assets folder with a link that points outside it
    root = tmp_path / "node_modules" / "cesium" / "Build" / "Cesium"
    root.mkdir(parents=True)
    (root / "Cesium.js").write_text("// ok")
    secret = tmp_path / "secret.txt"
    secret.write_text("SECRET")
    (root / "leak.txt").symlink_to(secret)
    app = create_app([dem[1]], assets=tmp_path / "node_modules")
    server, th, port = _live(app)
    try:
        seen = []
        for p in BAD_PATHS + ["/lib/cesium/leak.txt"]:
            for status, _, body in (asgi_get(app, p), _raw_get(port, p)):
                seen.append(status)
                assert status in (400, 404), (p, status, body[:80])
                assert b"root:" not in body and b"SECRET" not in body
                assert body.count(b"\n") <= 1  # one line
        assert _raw_get(port, "/lib/cesium/Cesium.js")[0] == 200
        assert 400 in seen and 404 in seen
        assert app.state.counters["errors_5xx"] == 0
    finally:
        server.should_exit = True
        th.join(10)


_SEGMENTS = ["..", ".", "", "%2e%2e", "%2E%2e%2F", "..%2f", "%5c..", "%00", "%252e%252e",
             "etc", "passwd", "secret.txt", "ridge.tif", "ridge", "ridge.geoterrain", "lib",
             "cesium", "rgb", "terrarium", "relief", "hillshade", "slope", "error", "tms",
             "layer.json", "stats.json", "cesium.html", "0.png", "1.webp", "0.terrain",
             "9" * 40]


@given(segs=hst.lists(hst.one_of(hst.sampled_from(_SEGMENTS),
                                 hst.integers(-3, 10**15).map(str)), max_size=7),
       absolute=hst.booleans())
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
def test_any_path_is_answered_without_a_500_or_a_file_outside_the_stores(dem, segs,
                                                                          absolute):
    # a file beside the store, which a traversal from it would reach
    (dem[1].parent / "secret.txt").write_text("SECRET")
    app = _fuzz_app(dem)
    path = ("//" if absolute else "/") + "/".join(segs)
    status, _, body = asgi_get(app, path)
    assert status in (200, 400, 404), (path, status, body[:80])
    assert b"SECRET" not in body and b"root:" not in body, path
    if status != 200:
        assert body.count(b"\n") <= 1, path  # one line
    assert app.state.counters["errors_5xx"] == 0


_APPS: dict = {}


def _fuzz_app(dem):
    """One app for all the examples (its cache keeps the tiles already built)."""
    if dem[1] not in _APPS:
        _APPS[dem[1]] = create_app([dem[1]])
    return _APPS[dem[1]]


# ------------------------------------------------------------------ cache, decodes
def test_cache_stays_within_its_budget(dem):
    app = create_app([dem[1]], cache_bytes=200_000)
    st = app.state.stores["ridge"]
    n = 0
    for z in range(st.web.max_zoom - 2, st.web.max_zoom + 1):
        xs, ys = st.web.tile_range(z)
        for what in ("relief", "rgb", "slope"):
            for x in xs:
                for y in ys:
                    assert asgi_get(app, f"/ridge/{what}/{z}/{x}/{y}.png")[0] == 200
                    n += 1
                    assert app.state.cache.used <= 200_000
    c = app.state.cache.stats()
    assert c["peak_bytes"] <= c["budget_bytes"] == 200_000
    assert c["evictions"] > 0 and n > 4


@pytest.mark.fast
def test_only_the_tiles_asked_for_are_decoded(dem):
    import rasterio
    from pyproj import Transformer

    from geoterrain.export.webtiles import merc_tile_bounds

    app = create_app([dem[1]])
    st = app.state.stores["ridge"]
    t = st.terrain
    assert t.decoded_tiles == 0  # opening decodes nothing
    z, x, y = _max_zoom_tile(app, "ridge")
    assert asgi_get(app, f"/ridge/rgb/{z}/{x}/{y}.png")[0] == 200
    # the level-0 store tiles under the web tile (its box in DEM samples), and ancestors
    w, s, e, n = merc_tile_bounds(z, x, y)
    lon, lat = Transformer.from_crs(3857, 4326, always_xy=True).transform([w, e], [s, n])
    with rasterio.open(dem[0]) as src:
        rows, cols = rasterio.transform.rowcol(src.transform, lon, lat)
    T = t.grid.tile_samples - 1
    r0, r1 = max(min(rows) - 1, 0) // T, (max(rows) + 1) // T
    c0, c1 = max(min(cols) - 1, 0) // T, (max(cols) + 1) // T
    under = {(0, cx, cy) for cy in range(r0, r1 + 1) for cx in range(c0, c1 + 1)
             if (0, cx, cy) in t.tile_info}
    need = set(under)
    for key in under:
        need |= set(t.grid.ancestors(*key))
    assert 0 < t.decoded_tiles <= len(need) < len(t.tile_info)
    assert st.built == {"terrain-rgb": 1}
    stats = json.loads(asgi_get(app, "/stats.json")[2])
    assert stats["stores"]["ridge"]["decoded_tiles"] == t.decoded_tiles


def test_concurrent_requests_on_127_0_0_1(dem):
    """200 requests, 32 at a time, over 40 distinct tiles: every answer 200, each tile
    built once, the cache within budget; p95 latency printed."""
    app = create_app([dem[1]], cache_bytes=8 << 20)
    st = app.state.stores["ridge"]
    z = st.web.max_zoom - 1
    xs, ys = st.web.tile_range(z)
    kinds = ("rgb", "relief", "hillshade", "terrarium", "slope")
    paths = [f"/ridge/{k}/{z}/{x}/{y}.png" for k in kinds for x in xs for y in ys][:40]
    server, th, port = _live(app)
    try:
        def one(p):
            t0 = time.perf_counter()
            status, _, body = _raw_get(port, p)
            return status, time.perf_counter() - t0

        with concurrent.futures.ThreadPoolExecutor(32) as pool:
            res = list(pool.map(one, [paths[i % len(paths)] for i in range(200)]))
    finally:
        server.should_exit = True
        th.join(10)
    assert all(s == 200 for s, _ in res)
    lat = np.array([d for _, d in res])
    print(f"\n200 requests: p50 {np.median(lat) * 1e3:.0f} ms, "
          f"p95 {np.percentile(lat, 95) * 1e3:.0f} ms")
    assert sum(st.built.values()) == len(paths)  # each distinct tile built once
    assert app.state.cache.stats()["peak_bytes"] <= 8 << 20


# ------------------------------------------------------------------ the command
def test_serve_command_prints_its_url_first_and_errors_in_one_line(dem):
    proc = subprocess.Popen([sys.executable, "-m", "geoterrain.cli.main", "serve",
                             str(dem[1]), "--port", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:") and url.endswith("/")
        port = int(url.rsplit(":", 1)[1].strip("/"))
        status, _, body = _raw_get(port, "/stores.json")
        assert status == 200 and json.loads(body)[0]["name"] == "ridge"
    finally:
        proc.terminate()
        proc.wait(20)
    for args, code in (([str(dem[1]) + ".missing"], 2), ([str(dem[1]), "--port", "70000"], 2),
                       ([str(dem[1]), "--cache", "12"], 2)):
        r = subprocess.run([sys.executable, "-m", "geoterrain.cli.main", "serve", *args],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == code and "Traceback" not in r.stderr
        errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error")]
        assert len(errors) == 1 and r.stderr.strip().endswith(errors[0]), r.stderr


@pytest.mark.fast
def test_serve_command_usage_errors_in_process(dem, tmp_path):
    from click.testing import CliRunner

    from geoterrain.cli.main import cli

    for args in ([str(tmp_path / "missing.geoterrain")], [str(dem[1]), "--cache", "12"],
                 [str(dem[1]), "--max-error", "0"]):
        r = CliRunner().invoke(cli, ["serve", *args], catch_exceptions=False)
        assert r.exit_code == 2 and "Traceback" not in r.output
        assert r.stderr.strip().splitlines()[-1].startswith("Error")


# ------------------------------------------------- the served set is the written one
def _void_store(d, **opts):
    """A 129² fBm at 2″ with a nodata corner that holds whole tiles of zooms 11 and 12 (two
    specks of data inside it), and a void: ``opts`` go to preprocess."""
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", 129, seed=7) * 0.05).astype(np.float32)
    z[:85, :85] = -9999.0
    z[10:12, 15:18] = z[30:33, 50:52] = 50.0
    z[95:115, 100:120] = -9999.0
    tif = write_tif(d / "v.tif", z, crs="EPSG:4326", origin=(138.4267, 35.5437),
                    spacing=1 / 1800, nodata=-9999)
    return geoterrain.preprocess(tif, d / "v.geoterrain", tile_size=32, **opts)


@pytest.mark.parametrize("mesher,opts", [
    pytest.param("tin", {}, marks=pytest.mark.fast, id="tin"),
    pytest.param("rtin", {}, marks=pytest.mark.fast, id="rtin"),
    pytest.param("tin", {"codec_error": 0.5}, marks=pytest.mark.fast, id="tin-lossy"),
    pytest.param("rtin", {"codec_error": 0.5}, marks=pytest.mark.slow, id="rtin-lossy"),
    pytest.param("tin", {"root_grid": True}, marks=pytest.mark.slow, id="tin-root-grid"),
    pytest.param("rtin", {"root_grid": True}, marks=pytest.mark.fast, id="rtin-root-grid")])
def test_the_served_tile_set_is_the_written_one_over_nodata(tmp_path, mesher, opts):
    """Every tile a client may ask for over the DEM's box, at every zoom, from a live
    server on 127.0.0.1: a tile the writer wrote comes back as the written file, byte for
    byte (gzip, normals and water mask); one it left out (over the nodata corner or the
    void) is a 404, never a flat tile; layer.json's availability is the writer's."""
    from geoterrain.export.qmesh import write_tileset
    from geoterrain.serve.app import open_stores

    store = _void_store(tmp_path, **opts)
    with geoterrain.open(store) as t:
        write_tileset(t, tmp_path / "w", mesher=mesher)
    out = tmp_path / "w"
    written = {tuple(int(v) for v in (p.parent.parent.name, p.parent.name, p.stem)): p
               for p in out.glob("*/*/*.terrain")}
    layer = json.loads((out / "layer.json").read_text())
    app = create_app(open_stores([("v", store)], mesher=mesher))
    server, th, port = _live(app)
    hdr = {"Accept": "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask",
           "Accept-Encoding": "gzip"}
    got: dict[tuple[int, int, int], int] = {}
    try:
        status, _, body = _raw_get(port, "/v/layer.json")
        assert status == 200
        assert json.loads(body)["available"] == layer["available"]
        w, s, e, n = layer["bounds"]
        for z in range(layer["maxzoom"] + 1):
            size = 180.0 / (1 << z)
            xs = range(int((w + 180) // size), math.ceil((e + 180) / size))
            ys = range(int((s + 90) // size), math.ceil((n + 90) / size))
            for k in {(z, x, y) for x in xs for y in ys} | {k for k in written if k[0] == z}:
                status, _, body = _raw_get(port, "/v/{}/{}/{}.terrain".format(*k), hdr)
                got[k] = status
                if k in written:
                    assert status == 200 and body == written[k].read_bytes(), k
                else:
                    assert status == 404, k
    finally:
        server.should_exit = True
        th.join(10)
    # not vacuous: tiles over the nodata left out at several zooms, data tiles at every zoom
    assert {k[0] for k, v in got.items() if v == 404} == {11, 12}
    assert {k[0] for k, v in got.items() if v == 200} == set(range(layer["maxzoom"] + 1))

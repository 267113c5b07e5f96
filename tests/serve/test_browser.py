"""The served pages in headless Chromium, offline on 127.0.0.1 (marked ``browser``: `make
test-browser`): the CesiumJS globe and the MapLibre map of srtm1_japan from
`geoterrain serve`.

- Cesium: no failed request, no console error; ``sampleTerrainMostDetailed`` at five DEM
  samples within the declared error of the finest tile holding each (its
  ``X-Declared-Error``); the screenshot differs clearly from the same view over the plain
  ellipsoid and shows the hillshade imagery (neutral greys with relief in them).
- MapLibre: ``map.queryTerrainElevation`` at five points (max-zoom pixel corners, where
  MapLibre reads a DEM pixel as it is) within the encoding's step × the exaggeration of
  the DEM's bilinear surface there (rasterio, pyproj).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

import geoterrain
from tests.conftest import real_dem
from tests.serve.cdp import MODULES, Page, chromium_or_skip

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def japan(tmp_path_factory):
    tif = real_dem("srtm1_japan.tif")
    d = tmp_path_factory.mktemp("japan")
    return tif, geoterrain.preprocess(tif, d / "japan.geoterrain")


@pytest.fixture(scope="module")
def server(japan):
    import socket

    import uvicorn

    from geoterrain.serve.app import create_app

    app = create_app([japan[1]], assets=MODULES)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    srv = uvicorn.Server(uvicorn.Config(app, log_level="error", lifespan="off"))
    th = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    th.start()
    while not srv.started:
        time.sleep(0.05)
    yield app, f"http://127.0.0.1:{sock.getsockname()[1]}/"
    srv.should_exit = True
    th.join(10)


def _dem(tif):
    import rasterio

    with rasterio.open(tif) as src:
        return src.read(1).astype(np.float64), src.transform


def _clean(page: Page) -> None:
    assert not page.failed, page.failed[:10]
    assert not page.errors, page.errors[:10]


def test_cesium_page_from_serve(japan, server, tmp_path):
    chromium = chromium_or_skip("cesium")
    import imageio.v3 as iio

    from geoterrain.export.qmeshformat import tile_rect

    app, base = server
    h, tr = _dem(japan[0])
    st = app.state.stores["japan"]
    zmax = st.qmesh.max_zoom
    # five DEM samples spread over the data (peaks, slopes, the coast)
    ij = [(150, 200), (300, 700), (434, 442), (600, 300), (800, 820)]
    pts = [(tr.c + tr.a * (j + 0.5), tr.f + tr.e * (i + 0.5)) for i, j in ij]
    with Page(chromium, tmp_path / "p1") as page:
        page.open(base + "cesium.html?store=japan&imagery=hillshade")
        page.wait("window.geoterrainReady === true || window.geoterrainError", 400)
        assert page.eval("window.geoterrainError || ''") == ""
        page.screenshot(tmp_path / "terrain.png")
        got = page.eval("Cesium.sampleTerrainMostDetailed(window.geoterrainTerrain, %s"
                        ".map((p) => Cesium.Cartographic.fromDegrees(p[0], p[1])))"
                        ".then((s) => s.map((c) => c.height))" % [list(p) for p in pts])
        _clean(page)
    for (i, j), (lon, lat), g in zip(ij, pts, got, strict=True):
        size = 180.0 / (1 << zmax)
        x, y = int((lon + 180) // size), int((lat + 90) // size)
        w, s, e, n = tile_rect(zmax, x, y)
        assert w <= lon <= e and s <= lat <= n
        from geoterrain.serve.app import asgi_get

        status, headers, _ = asgi_get(app, f"/japan/{zmax}/{x}/{y}.terrain")
        declared = float(headers["x-declared-error"])
        print(f"({i}, {j}): Cesium {g:.2f} m, DEM {h[i, j]:.0f} m, declared {declared:.2f} m")
        assert abs(g - h[i, j]) <= declared, (i, j, g, h[i, j], declared)
    with Page(chromium, tmp_path / "p2") as page:
        page.open(base + "cesium.html?store=japan&imagery=hillshade&terrain=off")
        page.wait("window.geoterrainReady === true || window.geoterrainError", 400)
        page.screenshot(tmp_path / "ellipsoid.png")
        _clean(page)
    a = iio.imread(tmp_path / "terrain.png")[..., :3].astype(float)
    b = iio.imread(tmp_path / "ellipsoid.png")[..., :3].astype(float)
    diff = np.abs(a - b).mean()
    # the hillshade: neutral greys (the page's background and the globe's base are tinted)
    grey = (np.abs(a[..., 0] - a[..., 1]) < 4) & (np.abs(a[..., 1] - a[..., 2]) < 4) \
        & (a.sum(-1) > 60)
    print(f"mean |terrain − ellipsoid| {diff:.1f}; hillshade greys {grey.mean():.2f} of "
          f"the picture, their std {a[grey].std():.1f}")
    assert diff > 10  # the relief changes the picture clearly
    assert grey.mean() > 0.2 and a[grey][:, 0].std() > 15  # the hillshade's greys, shaded


def _web_point(z, x, y, k, r):
    """lon/lat of pixel corner (k, r) of XYZ tile (z, x, y)."""
    n = 1 << z
    lon = (x + k / 256) / n * 360 - 180
    lat = math.degrees(math.atan(math.sinh(math.pi * (1 - 2 * (y + r / 256) / n))))
    return lon, lat


def _dem_bilinear(tif, lon, lat):
    h, tr = _dem(tif)
    i, j = (lat - tr.f) / tr.e - 0.5, (lon - tr.c) / tr.a - 0.5
    i0, j0 = int(math.floor(i)), int(math.floor(j))
    u, v = i - i0, j - j0
    return (h[i0, j0] * (1 - u) * (1 - v) + h[i0, j0 + 1] * (1 - u) * v
            + h[i0 + 1, j0] * u * (1 - v) + h[i0 + 1, j0 + 1] * u * v)


def maplibre_elevations(page, tif, st, base_url, exaggeration, step):
    """Open the map page and check five queryTerrainElevation answers; returns them."""
    page.open(base_url)
    page.wait("window.geoterrainReady === true", 300)
    z = st["maxzoom"]
    lon0, lat0 = st["center"]
    n = 1 << z
    cx = int((lon0 + 180) / 360 * n)
    cy = int((1 - math.asinh(math.tan(math.radians(lat0))) / math.pi) / 2 * n)
    picks = [(cx, cy, 40, 60), (cx - 1, cy + 1, 128, 128), (cx + 1, cy - 1, 200, 30),
             (cx - 2, cy - 2, 77, 190), (cx + 2, cy + 2, 20, 220)]
    out = []
    for x, y, k, r in picks:
        lon, lat = _web_point(z, x, y, k, r)
        q = page.eval(f"""new Promise((res) => {{
            const m = window.geoterrainView;
            m.jumpTo({{center: [{lon}, {lat}], zoom: {z + 1.5}, pitch: 0, bearing: 0}});
            const done = () => res(m.queryTerrainElevation([{lon}, {lat}]));
            m.once("idle", done);
            setTimeout(() => {{ if (m.loaded()) done(); }}, 20000);
        }})""")
        want = _dem_bilinear(tif, lon, lat)
        print(f"({lon:.5f}, {lat:.5f}): MapLibre {q:.3f} m, DEM × {exaggeration:g} "
              f"{want * exaggeration:.3f} m")
        assert abs(q - want * exaggeration) <= step * exaggeration, (lon, lat, q, want)
        out.append(q)
    return out


ELEVATIONS: dict[str, list[float]] = {}  # the served map's answers, for the static one


def test_maplibre_page_from_serve(japan, server, tmp_path):
    chromium = chromium_or_skip("maplibre-gl")
    app, base = server
    st = app.state.stores["japan"].describe()
    with Page(chromium, tmp_path / "p") as page:
        page.open(base + "maplibre.html?store=japan")
        page.wait("window.geoterrainReady === true", 300)
        page.screenshot(tmp_path / "overview.png")
        ELEVATIONS["serve"] = maplibre_elevations(
            page, japan[0], st, base + "maplibre.html?store=japan&exaggeration=1.5", 1.5, 0.1)
        _clean(page)


class _RangeHandler:
    """A plain static file server that answers Range requests (as object storage does)."""

    @staticmethod
    def make(root):
        import functools
        import http.server
        import os

        class H(http.server.SimpleHTTPRequestHandler):
            def send_head(self):
                rng = self.headers.get("Range")
                path = self.translate_path(self.path)
                if not rng or not os.path.isfile(path):
                    return super().send_head()
                a, b = rng.split("=", 1)[1].split("-")
                size = os.path.getsize(path)
                a, b = int(a), min(int(b) if b else size - 1, size - 1)
                fh = open(path, "rb")  # noqa: SIM115 - closed by copyfile's caller
                fh.seek(a)
                self.send_response(206)
                self.send_header("Content-Type", self.guess_type(path))
                self.send_header("Content-Range", f"bytes {a}-{b}/{size}")
                self.send_header("Content-Length", str(b - a + 1))
                self.end_headers()
                import io

                data = fh.read(b - a + 1)
                fh.close()
                return io.BytesIO(data)

            def log_message(self, *args):
                pass

        srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                              functools.partial(H, directory=str(root)))
        threading.Thread(target=srv.serve_forever, daemon=True).start()
        return srv


def test_maplibre_reads_the_pmtiles_from_a_static_host(japan, tmp_path):
    chromium = chromium_or_skip("maplibre-gl", "pmtiles")
    import json

    from pmtiles.reader import MmapSource, Reader

    from geoterrain.serve.site import write_site

    site = tmp_path / "site"
    with geoterrain.open(japan[1]) as t:
        figs = write_site(t, site, imagery=("relief",), assets=MODULES, name="japan")
    assert figs["lib"] == ["maplibre-gl", "pmtiles"]
    with open(site / "japan.terrain-rgb.pmtiles", "rb") as fh:
        assert Reader(MmapSource(fh)).header()["max_zoom"] == figs["max_zoom"]
    st = json.loads((site / "japan.json").read_text())
    srv = _RangeHandler.make(site)
    base = f"http://127.0.0.1:{srv.server_address[1]}/"
    try:
        with Page(chromium, tmp_path / "p") as page:
            got = maplibre_elevations(page, japan[0], st, base + "index.html?exaggeration=1.5",
                                      1.5, 0.1)
            page.screenshot(tmp_path / "static.png")
            _clean(page)
            assert any(".pmtiles" in u for u in page.requests)
    finally:
        srv.shutdown()
    if "serve" in ELEVATIONS:  # the same elevations as the served map's
        assert np.allclose(got, ELEVATIONS["serve"], atol=1e-6), (got, ELEVATIONS["serve"])


def test_view_web_follows_the_camera(japan, tmp_path):
    """`geoterrain view --web`: a drag moves the camera and the LOD changes (the status
    line's triangle count), with no console error and no failed request."""
    chromium = chromium_or_skip()
    pytest.importorskip("trame")
    pytest.importorskip("trame_vtk")
    import re
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "geoterrain.cli.main", "view", str(japan[1]),
                             "--web", "--port", "0", "--size", "900x560"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), proc.stderr.read()[-2000:]

        def triangles(text):
            return int(re.search(r"([\d,]+) triangles", text).group(1).replace(",", ""))

        status = ("(() => { const e = document.getElementById('status');"
                  " return e && e.textContent.includes('triangles') && e.textContent; })()")
        with Page(chromium, tmp_path / "p", size=(900, 600)) as page:
            page.open(url)
            first = page.wait(status, 180)
            sel0 = int(page.eval("document.getElementById('selections').textContent"))
            time.sleep(2)
            page.screenshot(tmp_path / "before.png")
            page.drag(450, 420, 450, 180, steps=15)  # tilt up: the far terrain comes in
            page.wait(f"Number(document.getElementById('selections').textContent) > {sel0}",
                      60)
            time.sleep(3)
            after = page.eval("document.getElementById('status').textContent")
            page.screenshot(tmp_path / "after.png")
            _clean(page)
        print(f"before: {first}\nafter:  {after}")
        assert triangles(after) != triangles(first)
    finally:
        proc.terminate()
        proc.wait(30)

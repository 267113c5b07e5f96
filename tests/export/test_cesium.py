"""A real client: CesiumJS in headless Chromium loads a quantized-mesh tile set, offline.

Needs Debian's ``chromium``, Node with npm, and the npm package ``cesium``
(``make browser`` installs them; the package goes to ``.browser/node_modules``, or
set ``GEOTERRAIN_CESIUM`` to a folder holding ``Build/Cesium``). Skipped, with the
reason, when any is missing.

The tiles, a minimal page and a single-image imagery layer are served from
127.0.0.1; no Cesium ion. The page points the camera at the DEM, waits for
``globe.tilesLoaded``, samples the terrain at three points with
``sampleTerrainMostDetailed`` and reports back in the DOM; Chromium's console
log must show no tile request or decode error, and the screenshot must differ
clearly from the same view over the plain ellipsoid.
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

import geoterrain
from tests.conftest import write_tif

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.browser


def _cesium_dir() -> Path | None:
    for d in (os.environ.get("GEOTERRAIN_CESIUM"), ROOT / ".browser" / "node_modules" / "cesium"):
        if d and (Path(d) / "Build" / "Cesium" / "Cesium.js").is_file():
            return Path(d) / "Build" / "Cesium"
    return None


def _requirements():
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium; "
                    "or `make browser`)")
    if shutil.which("node") is None:
        pytest.skip("Node.js is not installed (`make browser` installs it)")
    cesium = _cesium_dir()
    if cesium is None:
        pytest.skip("the npm package cesium is not installed (`make browser`)")
    return chromium, cesium


PAGE = """<!doctype html><html><head><meta charset="utf-8">
<link rel="icon" href="data:,"><script src="/cesium/Cesium.js"></script>
<link href="/cesium/Widgets/widgets.css" rel="stylesheet">
<style>html,body,#c{margin:0;width:100%;height:100%;overflow:hidden}</style></head>
<body><div id="c"></div><pre id="result"></pre><script>
window.CESIUM_BASE_URL = "/cesium/";
const P = __PARAMS__;
(async () => {
  const out = {errors: []};
  try {
    const terrain = P.terrain
      ? await Cesium.CesiumTerrainProvider.fromUrl("/tiles",
          {requestVertexNormals: true, requestWaterMask: true})
      : new Cesium.EllipsoidTerrainProvider();
    const viewer = new Cesium.Viewer("c", {
      terrainProvider: terrain,
      baseLayer: Cesium.ImageryLayer.fromProviderAsync(
        Cesium.SingleTileImageryProvider.fromUrl("/img.png",
          {rectangle: Cesium.Rectangle.fromDegrees(-180, -90, 180, 90)})),
      animation: false, timeline: false, baseLayerPicker: false, geocoder: false,
      homeButton: false, sceneModePicker: false, navigationHelpButton: false,
      fullscreenButton: false, infoBox: false, selectionIndicator: false,
      skyBox: false, skyAtmosphere: false,
      contextOptions: {webgl: {preserveDrawingBuffer: true}}});
    viewer.scene.globe.enableLighting = false;
    viewer.scene.globe.depthTestAgainstTerrain = true;
    viewer.camera.setView({
      destination: Cesium.Cartesian3.fromDegrees(P.lon, P.lat - P.back, P.alt),
      orientation: {heading: 0, pitch: Cesium.Math.toRadians(-20), roll: 0}});
    await new Promise((resolve) => {
      let n = 0;
      const check = () => {
        n += 1;
        if ((viewer.scene.globe.tilesLoaded && n > 10) || n > 600) resolve();
        else setTimeout(check, 100);
      };
      check();
    });
    out.tilesLoaded = viewer.scene.globe.tilesLoaded;
    if (P.terrain) {
      const pts = P.points.map((p) => Cesium.Cartographic.fromDegrees(p[0], p[1]));
      const s = await Cesium.sampleTerrainMostDetailed(terrain, pts);
      out.heights = s.map((c) => c.height);
    }
  } catch (e) {
    out.errors.push(String(e && e.stack || e));
  }
  document.getElementById("result").textContent = "RESULT" + JSON.stringify(out) + "END";
  document.title = "done";
})();
</script></body></html>"""


class _Handler(http.server.SimpleHTTPRequestHandler):
    def end_headers(self):
        if self.path.split("?")[0].endswith(".terrain"):
            self.send_header("Content-Encoding", "gzip")
            self.send_header("Content-Type", "application/vnd.quantized-mesh")
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def log_message(self, *args):
        pass


def _serve(root: Path):
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                          functools.partial(_Handler, directory=str(root)))
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    return srv


def _run_page(chromium: str, url: str, shot: Path) -> tuple[dict, list[str]]:
    """Open ``url`` in headless Chromium over the DevTools protocol (tornado's websocket
    client); wait for the page to report, collect the console, take a screenshot."""
    import base64
    import re
    import time
    import urllib.request

    from tornado.ioloop import IOLoop
    from tornado.websocket import websocket_connect

    proc = subprocess.Popen(
        [chromium, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--window-size=800,600",
         "--remote-debugging-port=0", f"--user-data-dir={shot.parent / ('p_' + shot.stem)}",
         "about:blank"], stderr=subprocess.PIPE, text=True)
    try:
        port = None
        t0 = time.time()
        while port is None and time.time() - t0 < 60:
            m = re.search(r"DevTools listening on ws://127.0.0.1:(\d+)/", proc.stderr.readline())
            port = m and int(m.group(1))
        assert port, "Chromium did not open its DevTools port"
        pages = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list").read())
        ws_url = next(p["webSocketDebuggerUrl"] for p in pages if p["type"] == "page")
        console: list[str] = []

        async def drive():
            ws = await websocket_connect(ws_url, max_message_size=1 << 28)
            ids = iter(range(1, 1 << 30))

            async def call(method, **params):
                i = next(ids)
                ws.write_message(json.dumps({"id": i, "method": method, "params": params}))
                while True:
                    msg = json.loads(await ws.read_message())
                    if msg.get("id") == i:
                        return msg.get("result", {})
                    if msg.get("method") == "Runtime.consoleAPICalled":
                        p = msg["params"]
                        console.append(p["type"] + ": " + " ".join(
                            str(a.get("value", a.get("description", ""))) for a in p["args"]))
                    elif msg.get("method") in ("Runtime.exceptionThrown", "Log.entryAdded"):
                        console.append("error: " + json.dumps(msg["params"])[:500])

            for m in ("Runtime.enable", "Log.enable", "Page.enable"):
                await call(m)
            await call("Page.navigate", url=url)
            t1 = time.time()
            while time.time() - t1 < 180:
                r = await call("Runtime.evaluate", expression="document.title")
                if r.get("result", {}).get("value") == "done":
                    break
                await call("Runtime.evaluate", expression="0", awaitPromise=False)
                time.sleep(0.5)
            r = await call("Runtime.evaluate",
                           expression="document.getElementById('result').textContent")
            png = await call("Page.captureScreenshot", format="png")
            shot.write_bytes(base64.b64decode(png["data"]))
            ws.close()
            return r["result"].get("value", "")

        text = IOLoop.current().run_sync(drive, timeout=300)
    finally:
        proc.kill()
        proc.wait()
    if "RESULT" not in text:
        pytest.fail(f"the page did not finish; console: {console[-20:]}")
    return json.loads(text.split("RESULT", 1)[1].split("END", 1)[0]), console


@pytest.mark.parametrize("mesher", ["rtin", "tin"])
def test_cesium_loads_the_tile_set(tmp_path, mesher):
    chromium, cesium = _requirements()
    import imageio.v3 as iio
    import rasterio

    from geoterrain.export.qmesh import write_tileset
    from geoterrain.ingest.synth import generate

    z = generate("ridged", 129, seed=6).astype(np.float32)
    z = (z - z.min()) / (z.max() - z.min()) * 1500.0  # 1.5 km of relief
    dem = write_tif(tmp_path / "dem.tif", z, crs="EPSG:4326", origin=(10.0, 46.0),
                    spacing=1 / 1200)
    site = tmp_path / "site"
    site.mkdir()
    with geoterrain.open(geoterrain.preprocess(dem, tmp_path / "d.geoterrain")) as t:
        stats = write_tileset(t, site / "tiles", mesher=mesher)
    declared = json.loads((site / "tiles" / "geoterrain.json").read_text())["declared_error"]
    worst = max(v for k, v in declared.items() if int(k.split("/")[0]) == stats["max_zoom"])
    (site / "cesium").symlink_to(cesium, target_is_directory=True)
    iio.imwrite(site / "img.png", np.full((128, 256, 3), 90, np.uint8))
    with rasterio.open(dem) as src:
        h = src.read(1)
        pts_ij = [(40, 40), (64, 70), (90, 100)]
        pts = [src.xy(i, j) for i, j in pts_ij]
        lon, lat = src.xy(64, 64)
    params = {"lon": lon, "lat": lat, "back": 0.12, "alt": 5000.0, "points": pts}
    srv = _serve(site)
    try:
        base = f"http://127.0.0.1:{srv.server_address[1]}"
        for name, terrain in (("terrain", True), ("ellipsoid", False)):
            page = PAGE.replace("__PARAMS__", json.dumps({**params, "terrain": terrain}))
            (site / f"{name}.html").write_text(page)
        res, log = _run_page(chromium, f"{base}/terrain.html", tmp_path / "terrain.png")
        flat, _ = _run_page(chromium, f"{base}/ellipsoid.html", tmp_path / "ellipsoid.png")
    finally:
        srv.shutdown()
    assert not res["errors"], res["errors"]
    assert res["tilesLoaded"]
    bad = [ln for ln in log if ln.startswith("error") or any(
        w in ln.lower() for w in ("failed", "terrain tile", "decode"))]
    assert not bad, bad
    # sampled heights within the finest tiles' declared error of the DEM
    for (i, j), got in zip(pts_ij, res["heights"], strict=True):
        assert abs(got - float(h[i, j])) <= worst + 0.5, (i, j, got, float(h[i, j]))
    a = iio.imread(tmp_path / "terrain.png")[..., :3].astype(float)
    b = iio.imread(tmp_path / "ellipsoid.png")[..., :3].astype(float)
    assert a.std() > 5  # not a blank picture
    assert np.abs(a - b).mean() > 10  # the relief changes the picture clearly

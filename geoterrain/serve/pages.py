"""The server's pages: an index, a CesiumJS globe and a MapLibre GL JS map.

Both pages load their library from ``lib/`` (a local npm install, served by the server or
copied beside a static site), so they work offline. Each reads its stores from a JSON
block in the page; ``?store=NAME`` picks one (default: the first), ``?imagery=`` the
imagery (relief, hillshade, slope, error), ``?terrain=off`` (Cesium) draws the plain
ellipsoid and ``?exaggeration=N`` scales heights. The camera opens on the data. When the
page is ready it sets ``window.geoterrainReady = true`` and keeps its viewer or map in
``window.geoterrainView``, so a test or a user's script can drive it.

Examples
--------
>>> "maplibre-gl.js" in maplibre_page({}, True)
True
"""

from __future__ import annotations

import html
import json

__all__ = ["cesium_page", "index_page", "maplibre_page", "MISSING"]

MISSING = """<p class="missing">The JavaScript package <b>{pkg}</b> is not installed where the
server looks. Install it once (<code>npm install {pkg}</code> in a folder) and start the server
with <code>--assets FOLDER/node_modules</code> (or <code>make browser</code> in a geoterrain
checkout).</p>"""

STYLE = """html,body{margin:0;height:100%;overflow:hidden;font:14px system-ui,sans-serif}
#map{position:absolute;inset:0}
#panel{position:absolute;top:8px;left:8px;z-index:9;background:rgba(255,255,255,.92);
padding:6px 10px;border-radius:4px;box-shadow:0 1px 4px rgba(0,0,0,.3)}
#panel select{font:inherit}.missing{margin:2em;max-width:40em}"""


def _stores_json(stores) -> str:
    docs = [s.describe() if hasattr(s, "describe") else s for s in stores.values()] \
        if isinstance(stores, dict) else list(stores)
    # </script> can never close the block: JSON escapes "/" here
    return json.dumps(docs).replace("</", "<\\/")


def index_page(stores) -> str:
    """The server's front page: each store with its links."""
    rows = []
    for name in stores:
        n = html.escape(name)
        rows.append(f'<li><b>{n}</b>: <a href="cesium.html?store={n}">globe</a> · '
                    f'<a href="maplibre.html?store={n}">map</a> · '
                    f'<a href="{n}/layer.json">layer.json</a> · '
                    f'<a href="{n}/rgb.json">Terrain-RGB TileJSON</a> · '
                    f'<a href="{n}/relief.json">relief TileJSON</a></li>')
    return ("<!doctype html><html><head><meta charset='utf-8'><title>geoterrain</title>"
            "<link rel='icon' href='data:,'></head><body><h1>geoterrain</h1><ul>"
            + "".join(rows) + "</ul><p><a href='stats.json'>server figures</a></p></body></html>")


CESIUM = r"""<!doctype html><html><head><meta charset="utf-8"><title>geoterrain · globe</title>
<link rel="icon" href="data:,"><script src="lib/cesium/Cesium.js"></script>
<link href="lib/cesium/Widgets/widgets.css" rel="stylesheet"><style>__STYLE__</style></head>
<body><div id="map"></div><div id="panel"><select id="store"></select>
<select id="imagery"><option>relief</option><option>hillshade</option><option>slope</option>
<option>error</option></select></div>
<script id="stores" type="application/json">__STORES__</script><script>
window.CESIUM_BASE_URL = "lib/cesium/";
const STORES = JSON.parse(document.getElementById("stores").textContent);
const Q = new URLSearchParams(location.search);
const S = STORES.find((s) => s.name === Q.get("store")) || STORES[0];
const IMAGERY = Q.get("imagery") || "relief";
function choose(id, values, value, key) {
  const el = document.getElementById(id);
  if (id === "store") el.innerHTML = values.map((v) => `<option>${v}</option>`).join("");
  el.value = value;
  el.onchange = () => { Q.set(key, el.value); location.search = Q.toString(); };
}
choose("store", STORES.map((s) => s.name), S.name, "store");
choose("imagery", null, IMAGERY, "imagery");
(async () => {
  const [w, s, e, n] = S.bounds;
  const rect = Cesium.Rectangle.fromDegrees(w, s, e, n);
  const terrain = Q.get("terrain") === "off" ? new Cesium.EllipsoidTerrainProvider()
    : await Cesium.CesiumTerrainProvider.fromUrl(S.name,
        {requestVertexNormals: true, requestWaterMask: true, requestMetadata: true});
  const imagery = new Cesium.UrlTemplateImageryProvider({
    url: S.imagery[IMAGERY], tilingScheme: new Cesium.WebMercatorTilingScheme(),
    rectangle: rect, minimumLevel: 0, maximumLevel: S.maxzoom, credit: "geoterrain"});
  const viewer = new Cesium.Viewer("map", {
    terrainProvider: terrain, baseLayer: new Cesium.ImageryLayer(imagery),
    animation: false, timeline: false, baseLayerPicker: false, geocoder: false,
    homeButton: false, sceneModePicker: false, navigationHelpButton: false,
    fullscreenButton: false, infoBox: false, selectionIndicator: false,
    skyBox: false, skyAtmosphere: false,
    contextOptions: {webgl: {preserveDrawingBuffer: true}}});
  // outside the DEM the terrain tiles have no triangles: the page's background shows
  viewer.scene.globe.baseColor = Cesium.Color.fromCssColorString("#d8dde3");
  viewer.scene.backgroundColor = Cesium.Color.fromCssColorString("#3c4650");
  viewer.scene.globe.depthTestAgainstTerrain = true;
  viewer.scene.verticalExaggeration = Number(Q.get("exaggeration") || 1);
  // the camera opens on the data: south of its centre, looking north and down
  const span = Math.max(n - s, (e - w) * Math.cos((s + n) * Math.PI / 360));
  const top = S.heights[1];
  viewer.camera.setView({
    destination: Cesium.Cartesian3.fromDegrees((w + e) / 2, s - 0.55 * span,
                                               top + 0.75 * span * 111e3),
    orientation: {heading: 0, pitch: Cesium.Math.toRadians(-38), roll: 0}});
  window.geoterrainView = viewer;
  window.geoterrainTerrain = terrain;
  // ready: tiles were asked for, and none has been pending for a second
  let started = false, quiet = 0;
  viewer.scene.globe.tileLoadProgressEvent.addEventListener((n) => { if (n > 0) started = true; });
  const ready = () => {
    quiet = started && viewer.scene.globe.tilesLoaded ? quiet + 1 : 0;
    if (quiet >= 5) window.geoterrainReady = true;
    else setTimeout(ready, 200);
  };
  setTimeout(ready, 200);
})().catch((err) => { console.error(err); window.geoterrainError = String(err); });
</script></body></html>"""


MAPLIBRE = r"""<!doctype html><html><head><meta charset="utf-8"><title>geoterrain · map</title>
<link rel="icon" href="data:,"><script src="lib/maplibre-gl/maplibre-gl.js"></script>
__PMTILES__<link href="lib/maplibre-gl/maplibre-gl.css" rel="stylesheet">
<style>__STYLE__</style></head>
<body><div id="map"></div><div id="panel"><select id="store"></select>
<select id="imagery"><option>relief</option><option>hillshade</option><option>slope</option>
<option>error</option></select></div>
<script id="stores" type="application/json">__STORES__</script><script>
const STORES = JSON.parse(document.getElementById("stores").textContent);
const Q = new URLSearchParams(location.search);
const S = STORES.find((s) => s.name === Q.get("store")) || STORES[0];
const IMAGERY = Q.get("imagery") || "relief";
const EXAGGERATION = Number(Q.get("exaggeration") || 1);
function choose(id, values, value, key) {
  const el = document.getElementById(id);
  if (id === "store") el.innerHTML = values.map((v) => `<option>${v}</option>`).join("");
  el.value = value;
  el.onchange = () => { Q.set(key, el.value); location.search = Q.toString(); };
}
choose("store", STORES.map((s) => s.name), S.name, "store");
choose("imagery", null, IMAGERY, "imagery");
if (window.pmtiles) maplibregl.addProtocol("pmtiles", new pmtiles.Protocol().tile);
const DIR = location.href.replace(/[?#].*$/, "").replace(/[^/]*$/, "");  // the page's folder
const abs = (u) => /^[a-z]+:\/\//.test(u) ? u : DIR + u;  // keeps {z}/{x}/{y} as they are
function source(url, extra) {  // a PMTiles archive or an XYZ template
  const s = {tileSize: 256, bounds: S.bounds, minzoom: S.minzoom, maxzoom: S.maxzoom, ...extra};
  if (url.startsWith("pmtiles://")) s.url = "pmtiles://" + abs(url.slice(10));
  else s.tiles = [abs(url)];
  return s;
}
const dem = S.encodings["terrain-rgb"] ? ["terrain-rgb", "mapbox"] : ["terrarium", "terrarium"];
const map = new maplibregl.Map({
  container: "map", bounds: S.bounds, fitBoundsOptions: {padding: 20}, pitch: 55,
  maxPitch: 85, attributionControl: {compact: true},
  style: {version: 8, sources: {
      dem: source(S.encodings[dem[0]], {type: "raster-dem", encoding: dem[1]}),
      imagery: source(S.imagery[IMAGERY], {type: "raster", attribution: "geoterrain"})},
    layers: [{id: "background", type: "background", paint: {"background-color": "#d8dde3"}},
             {id: "imagery", type: "raster", source: "imagery"}],
    terrain: {source: "dem", exaggeration: EXAGGERATION}}});
map.addControl(new maplibregl.NavigationControl({visualizePitch: true}));
map.addControl(new maplibregl.ScaleControl());
map.addControl(new maplibregl.TerrainControl({source: "dem", exaggeration: EXAGGERATION}));
window.geoterrainView = map;
map.on("error", (e) => console.error(e.error ? e.error.message || e.error : e));
map.once("idle", () => { window.geoterrainReady = true; });
</script></body></html>"""


def _page(template: str, stores, have_lib: bool, pkg: str, pmtiles: bool = False) -> str:
    page = template.replace("__STYLE__", STYLE).replace("__STORES__", _stores_json(stores))
    page = page.replace("__PMTILES__", '<script src="lib/pmtiles/pmtiles.js"></script>\n'
                        if pmtiles else "")
    if not have_lib:
        page = page.replace("<body>", "<body>" + MISSING.format(pkg=pkg), 1)
    return page


def cesium_page(stores, have_lib: bool = True) -> str:
    """The CesiumJS globe: quantized-mesh terrain and an imagery layer of the store."""
    return _page(CESIUM, stores, have_lib, "cesium")


def maplibre_page(stores, have_lib: bool = True, pmtiles: bool = False) -> str:
    """The MapLibre map: 3-D terrain from Terrain-RGB tiles and an imagery layer;
    ``pmtiles``: the sources are ``pmtiles://`` archives (a static site)."""
    return _page(MAPLIBRE, stores, have_lib, "maplibre-gl", pmtiles)

"""`geoterrain tiles --format pmtiles`: archives read back by the pmtiles package's reader,
tile for tile the bytes `geoterrain serve` answers; the static page and its libraries."""

from __future__ import annotations

import json

import numpy as np
import pytest

import geoterrain
from tests.conftest import write_tif

pytest.importorskip("pmtiles")


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    from geoterrain.ingest.synth import generate

    d = tmp_path_factory.mktemp("pm")
    z = generate("fbm", 129, seed=2).astype(np.float32)
    z = (z - z.min()) / (z.max() - z.min()) * 800.0 + 300.0
    tif = write_tif(d / "hills.tif", z, crs="EPSG:32633", origin=(500000.0, 5100000.0),
                    spacing=30.0)
    return geoterrain.preprocess(tif, d / "hills.geoterrain", tile_size=32)


class _Result:
    def __init__(self, r):
        self.returncode, self.stdout, self.stderr = r.exit_code, r.stdout, r.stderr


def _cli(*args):
    from click.testing import CliRunner

    from geoterrain.cli.main import cli

    return _Result(CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False))


def test_pmtiles_read_back_tile_for_tile(store, tmp_path):
    from pmtiles.reader import MmapSource, Reader, all_tiles
    from pmtiles.tile import TileType

    from geoterrain.serve.app import asgi_get, create_app

    site = tmp_path / "site"
    r = _cli("tiles", store, "-o", site, "--format", "pmtiles", "--encoding", "terrarium",
             "--imagery", "relief,slope", "--assets", tmp_path)
    assert r.returncode == 0, r.stderr
    figs = json.loads(r.stdout)
    names = sorted(p.name for p in site.iterdir())
    assert names == ["hills.json", "hills.relief.pmtiles", "hills.slope.pmtiles",
                     "hills.terrarium.pmtiles", "index.html"]
    assert "npm install maplibre-gl pmtiles" in r.stderr  # no libraries in --assets
    app = create_app([store])
    web = app.state.stores["hills"].web
    want = {(z, x, y) for z in range(web.max_zoom + 1)
            for x in web.tile_range(z)[0] for y in web.tile_range(z)[1]}
    for product in ("terrarium", "relief", "slope"):
        with open(site / f"hills.{product}.pmtiles", "rb") as fh:
            get = MmapSource(fh)
            rd = Reader(get)
            h = rd.header()
            assert h["tile_type"] == TileType.PNG and h["max_zoom"] == web.max_zoom
            assert h["clustered"] and h["addressed_tiles_count"] == len(want)
            meta = rd.metadata()
            assert meta["name"] == "hills"
            if product == "terrarium":
                assert meta["encoding"] == "terrarium"
            got = dict(all_tiles(get))
            assert set(got) == want
            seg = "terrarium" if product == "terrarium" else product
            for z, x, y in sorted(want)[:: max(1, len(want) // 12)]:
                status, _, body = asgi_get(app, f"/hills/{seg}/{z}/{x}/{y}.png")
                assert status == 200 and body == got[(z, x, y)] == rd.get(z, x, y)
    assert figs["tiles"] == 3 * len(want)
    page = (site / "index.html").read_text()
    assert "pmtiles://hills.terrarium.pmtiles" in page and "lib/pmtiles/pmtiles.js" in page
    # an existing archive is kept unless --overwrite
    again = _cli("tiles", store, "-o", site, "--format", "pmtiles", "--encoding", "terrarium",
                 "--imagery", "none")
    assert again.returncode == 2 and "exists" in again.stderr and "Traceback" not in again.stderr
    assert _cli("tiles", store, "-o", site, "--format", "pmtiles", "--imagery", "none",
                "--encoding", "terrarium", "--overwrite").returncode == 0
    bad = _cli("tiles", store, "-o", tmp_path / "x", "--format", "pmtiles", "--imagery", "rgb")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1

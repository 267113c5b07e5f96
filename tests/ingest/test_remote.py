"""Rasters over HTTP (issue 45): a local server on 127.0.0.1 serves Cloud-Optimised GeoTIFFs
with range requests and counts the bytes it sends.

A COG by URL preprocesses to the local file's store, whole and streamed; the streamed
preprocess fetches each block once (every pass then reads the local copy), so the bytes
sent stay within 1.2× those of the store's grid (the COG's full-resolution blocks: its
overviews are never read). A text file of URLs is a mosaic. A 404, a truncated response
and a mosaic with an unreadable tile each give one line naming the source, and leave no
store and no partial file.
"""

from __future__ import annotations

import re
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from geoterrain.cli.main import cli
from geoterrain.exceptions import InputError
from geoterrain.preprocessing.pipeline import preprocess
from geoterrain.preprocessing.streaming import preprocess_streaming
from tests.ingest.test_mosaic import split, store_contents
from tests.preprocessing.test_streaming import _assert_same_store


class _Handler(BaseHTTPRequestHandler):
    """Files of ``server.root`` with HTTP range requests; ``server.sent`` counts the body
    bytes sent; the files named in ``root/.truncate`` have their bodies cut short."""

    def log_message(self, *args):  # quiet
        pass

    def _file(self) -> Path | None:
        p = self.server.root / self.path.split("?")[0].lstrip("/")
        return p if p.is_file() else None

    def do_HEAD(self):
        self._serve(body=False)

    def do_GET(self):
        self._serve(body=True)

    def _serve(self, body: bool) -> None:
        p = self._file()
        if p is None:
            self.send_error(404)
            return
        data = p.read_bytes()
        start, end = 0, len(data) - 1
        m = re.match(r"bytes=(\d+)-(\d*)", self.headers.get("Range", ""))
        if m:
            start = int(m.group(1))
            end = min(int(m.group(2)) if m.group(2) else end, len(data) - 1)
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{end}/{len(data)}")
        else:
            self.send_response(200)
        self.send_header("Content-Length", str(end - start + 1))
        self.send_header("Accept-Ranges", "bytes")
        self.end_headers()
        if not body:
            return
        chunk = data[start:end + 1]
        cut = self.server.root / ".truncate"
        if cut.exists() and p.name in cut.read_text().split():
            chunk = chunk[:len(chunk) // 3]
            self.close_connection = True
        with self.server.sent.get_lock():
            self.server.sent.value += len(chunk)
        self.wfile.write(chunk)


def _serve(root: str, sent, port) -> None:
    # the server in its own process: GDAL's requests from the test process block it
    srv = ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    srv.root, srv.sent = Path(root), sent
    port.value = srv.server_address[1]
    srv.serve_forever()


class Server:
    """The served folder ``root``, the base ``url``, and the body bytes ``sent`` so far."""

    def __init__(self, root: Path, url: str, sent) -> None:
        self.root, self.url, self._sent = root, url, sent

    @property
    def sent(self) -> int:
        return self._sent.value

    @sent.setter
    def sent(self, v: int) -> None:
        self._sent.value = v

    def truncate(self, name: str) -> None:
        (self.root / ".truncate").write_text(name)


@pytest.fixture
def server(tmp_path):
    """A range-request server on 127.0.0.1 over ``tmp_path / "www"``, in its own process:
    (base URL, :class:`Server`)."""
    import multiprocessing
    import time

    ctx = multiprocessing.get_context("spawn")
    root = tmp_path / "www"
    root.mkdir()
    sent, port = ctx.Value("q", 0), ctx.Value("i", 0)
    proc = ctx.Process(target=_serve, args=(str(root), sent, port), daemon=True)
    proc.start()
    deadline = time.monotonic() + 60
    while not port.value and time.monotonic() < deadline:
        time.sleep(0.05)
    url = f"http://127.0.0.1:{port.value}"
    yield url, Server(root, url, sent)
    proc.kill()
    proc.join()


def _cog(path: Path, n: int = 700, overviews: bool = False, seed: int = 1) -> Path:
    from geoterrain.ingest.synth import generate

    z = (generate("fbm", n, seed=seed) * 0.3 + 500).astype(np.float32)
    prof = dict(driver="COG", width=n, height=n, count=1, dtype="float32",
                crs="EPSG:32633", transform=rasterio.transform.from_origin(5e5, 5e6, 10, 10),
                compress="deflate", blocksize=256, overviews="AUTO" if overviews else "NONE")
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(z, 1)
    return path


def test_a_cog_by_url_is_the_local_file_s_store(tmp_path, server):
    url, srv = server
    _cog(srv.root / "dem.tif")
    ref = preprocess(srv.root / "dem.tif", tmp_path / "ref.gt", tile_size=32)
    _assert_same_store(ref, preprocess(f"{url}/dem.tif", tmp_path / "a.gt", tile_size=32))
    _assert_same_store(ref, preprocess_streaming(f"{url}/dem.tif?s=1", tmp_path / "b.gt",
                                                 tile_size=32, band=32))


@pytest.mark.parametrize("overviews", [False, True])
def test_a_streamed_url_reads_its_grid_s_blocks_once(tmp_path, server, overviews):
    """Bytes sent ≤ 1.2 × the full-resolution COG's size (header and blocks), though the
    streamed passes read the raster many times, and its overviews are not read."""
    url, srv = server
    _cog(srv.root / "dem.tif", overviews=overviews)
    need = _cog(tmp_path / "grid_only.tif").stat().st_size  # the same blocks, no overviews
    srv.sent = 0
    preprocess_streaming(f"{url}/dem.tif?o={overviews}", tmp_path / "b.gt", tile_size=32,
                         band=16)
    assert srv.sent <= 1.2 * need, (srv.sent, need)
    _no_leftovers_but(tmp_path, "b.gt")


def _no_leftovers_but(folder: Path, keep: str) -> None:
    assert [p.name for p in folder.iterdir() if "partial" in p.name] == []
    assert (folder / keep).exists()


def test_a_text_file_of_urls_is_a_mosaic(tmp_path, server):
    url, srv = server
    merged = _cog(tmp_path / "merged.tif", n=300)
    tiles = split(merged, srv.root)
    lst = tmp_path / "tiles.txt"
    lst.write_text("# a STAC search's assets\n" + "".join(f"{url}/{p.name}\n" for p in tiles))
    ref = store_contents(preprocess([str(p) for p in tiles], tmp_path / "ref.gt"))
    assert store_contents(preprocess(str(lst), tmp_path / "a.gt")) == ref
    assert store_contents(preprocess_streaming(str(lst), tmp_path / "b.gt", band=16)) == ref


@pytest.mark.parametrize("streamed", [False, True])
def test_a_404_is_one_line_naming_the_url_and_leaves_nothing(tmp_path, server, streamed):
    url, _ = server
    out = tmp_path / "out"
    out.mkdir()
    run = preprocess_streaming if streamed else preprocess
    with pytest.raises(InputError, match=re.escape(f"{url}/missing.tif")) as e:
        run(f"{url}/missing.tif", out / "x.gt")
    assert "\n" not in str(e.value)
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("streamed", [False, True])
def test_a_truncated_response_is_one_line_and_leaves_nothing(tmp_path, server, streamed):
    url, srv = server
    _cog(srv.root / "cut.tif")
    srv.truncate("cut.tif")
    out = tmp_path / "out"
    out.mkdir()
    run = preprocess_streaming if streamed else preprocess
    with pytest.raises(InputError, match="cut.tif") as e:
        run(f"{url}/cut.tif?t={streamed}", out / "x.gt")
    assert "\n" not in str(e.value)
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("streamed", [False, True])
def test_a_mosaic_with_an_unreadable_tile_is_one_line_and_leaves_nothing(tmp_path, streamed):
    """A tile whose header reads but whose data is cut short: the read names it."""
    merged = _cog(tmp_path / "merged.tif", n=300)
    tiles = split(merged, tmp_path / "tiles")
    data = tiles[2].read_bytes()
    tiles[2].write_bytes(data[:len(data) // 2])
    out = tmp_path / "out"
    out.mkdir()
    run = preprocess_streaming if streamed else preprocess
    with pytest.raises(InputError, match="tile_2") as e:
        run([str(p) for p in tiles], out / "x.gt")
    assert "\n" not in str(e.value)
    assert list(out.iterdir()) == []


def test_the_cli_takes_a_url_and_names_a_failed_one(tmp_path, server, monkeypatch):
    url, srv = server
    _cog(srv.root / "dem.tif", n=200)
    monkeypatch.chdir(tmp_path)
    run = CliRunner().invoke(cli, ["-q", "preprocess", f"{url}/dem.tif"])
    assert run.exit_code == 0, run.output
    assert (tmp_path / "dem.geoterrain").exists()  # named after the URL's file, here
    run = CliRunner().invoke(cli, ["-q", "preprocess", f"{url}/nope.tif", "-o", "n.gt"])
    assert run.exit_code == 1 and f"{url}/nope.tif" in run.output
    assert "Traceback" not in run.output and len(run.output.strip().splitlines()) == 1

"""`geoterrain serve` under concurrent requests on 127.0.0.1: latency, memory, cache, decodes.

Starts ``geoterrain serve STORE --port 0 --cache SIZE`` as its own process (a DEM is
preprocessed first), then sends a bounded loop of requests from a pool of client threads
(``--clients`` at a time, ``--requests`` in all, every URL on 127.0.0.1):

- cold: each tile of a mixed set (quantized-mesh, Terrain-RGB, relief, hillshade over the
  finest zooms; ``--tiles`` distinct) asked for several times in a shuffled order, so
  concurrent requests for one tile meet while it is being built;
- warm: the same loop again (every tile in the cache).

It reports the median and p95 latency of each pass, the server's peak RSS (VmHWM from
/proc), the cache's bytes against its budget, how many tiles were built (against the
distinct tiles asked for) and how many stored tiles were decoded (against the store's).

Run from the project root::

    python benchmarks/bench_serve.py [STORE_OR_DEM] [--requests 200] [--clients 32]
        [--tiles 60] [--cache 64M]

Default STORE_OR_DEM: ../shared/dems/srtm1_japan.tif.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import http.client
import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEM = ROOT.parent / "shared" / "dems" / "srtm1_japan.tif"


def get(port: int, path: str, headers: dict | None = None) -> tuple[int, int, float]:
    """(status, body bytes, seconds) of one GET on 127.0.0.1."""
    t0 = time.perf_counter()
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=300)
    try:
        c.request("GET", path, headers=headers or {})
        r = c.getresponse()
        body = r.read()
        return r.status, len(body), time.perf_counter() - t0
    finally:
        c.close()


def vm_hwm(pid: int) -> int:
    """Peak resident memory (bytes) of process ``pid``."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return 0


def tile_paths(port: int, name: str, count: int) -> list[str]:
    """``count`` distinct tile URLs over the finest zooms of the store's tile sets."""
    stores = json.loads(http_body(port, "/stores.json"))
    st = next(s for s in stores if s["name"] == name)
    layer = json.loads(http_body(port, f"/{name}/layer.json"))
    paths = []
    for z in range(layer["maxzoom"], -1, -1):
        for r in layer["available"][z]:
            for x in range(r["startX"], r["endX"] + 1):
                for y in range(r["startY"], r["endY"] + 1):
                    paths.append(f"/{name}/{z}/{x}/{y}.terrain")
        if len(paths) >= count // 2:
            break
    w, s, e, n = st["bounds"]
    for z in range(st["maxzoom"], -1, -1):
        k = 1 << z
        x0, x1 = int((w + 180) / 360 * k), int((e + 180) / 360 * k)

        def row(lat, k=k):
            phi = np.radians(lat)
            return int((1 - np.arcsinh(np.tan(phi)) / np.pi) / 2 * k)

        for x in range(x0, x1 + 1):
            for y in range(row(n), row(s) + 1):
                for kind in ("rgb", "relief", "hillshade"):
                    paths.append(f"/{name}/{kind}/{z}/{x}/{y}.png")
        if len(paths) >= count:
            break
    random.Random(1).shuffle(paths)
    return paths[:count]


def http_body(port: int, path: str) -> bytes:
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        c.request("GET", path)
        return c.getresponse().read()
    finally:
        c.close()


def run_pass(port: int, paths: list[str], requests: int, clients: int) -> dict:
    order = [paths[i % len(paths)] for i in range(requests)]
    random.Random(2).shuffle(order)
    hdr = {"Accept": "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask-"
                     "metadata,application/octet-stream;q=0.9,*/*;q=0.01",
           "Accept-Encoding": "gzip"}
    t0 = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(clients) as pool:
        res = list(pool.map(lambda p: get(port, p, hdr), order))
    wall = time.perf_counter() - t0
    lat = np.array([r[2] for r in res]) * 1e3
    bad = [r[0] for r in res if r[0] != 200]
    return {"requests": len(res), "not_200": len(bad), "wall_s": round(wall, 2),
            "p50_ms": round(float(np.median(lat)), 1),
            "p95_ms": round(float(np.percentile(lat, 95)), 1),
            "max_ms": round(float(lat.max()), 1), "MB": round(sum(r[1] for r in res) / 1e6, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", nargs="?", default=str(DEM))
    ap.add_argument("--requests", type=int, default=200)
    ap.add_argument("--clients", type=int, default=32)
    ap.add_argument("--tiles", type=int, default=60)
    ap.add_argument("--cache", default="64M")
    a = ap.parse_args()
    src = Path(a.source)
    if not src.is_file():
        sys.exit(f"{src}: no such file")
    name = src.stem
    proc = subprocess.Popen([sys.executable, "-m", "geoterrain.cli.main", "-q", "serve",
                             str(src), "--port", "0", "--cache", a.cache],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        url = proc.stdout.readline().strip()
        port = int(url.rsplit(":", 1)[1].strip("/"))
        rss0 = vm_hwm(proc.pid)
        paths = tile_paths(port, name, a.tiles)
        cold = run_pass(port, paths, a.requests, a.clients)
        warm = run_pass(port, paths, a.requests, a.clients)
        stats = json.loads(http_body(port, "/stats.json"))
        rss = vm_hwm(proc.pid)
    finally:
        proc.terminate()
        proc.wait(30)
    st = stats["stores"][name]
    print(f"load: {os.getloadavg()[0]:.2f} (1-min average), {os.cpu_count()} cores")
    print(f"{a.requests} requests per pass, {a.clients} at a time, {len(paths)} distinct "
          f"tiles (quantized-mesh, Terrain-RGB, relief, hillshade)")
    print("| pass | p50 ms | p95 ms | max ms | wall s | not 200 |")
    print("|---|---|---|---|---|---|")
    for label, r in (("cold (tiles built)", cold), ("warm (cached)", warm)):
        print(f"| {label} | {r['p50_ms']} | {r['p95_ms']} | {r['max_ms']} | {r['wall_s']} "
              f"| {r['not_200']} |")
    c = stats["cache"]
    print(f"server peak RSS {rss / 2**20:.0f} MiB (after start-up {rss0 / 2**20:.0f} MiB); "
          f"cache {c['bytes'] / 2**20:.1f} MiB, peak {c['peak_bytes'] / 2**20:.1f} MiB of "
          f"{c['budget_bytes'] / 2**20:.0f} MiB; tiles built {sum(st['tiles_built'].values())}"
          f" for {len(paths)} distinct asked; stored tiles decoded {st['decoded_tiles']} "
          f"of {stats['stores'][name].get('stored_tiles', '?')}")
    print(json.dumps({"cold": cold, "warm": warm, "stats": stats, "peak_rss": rss}))


if __name__ == "__main__":
    main()

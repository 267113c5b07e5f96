"""Peak memory and wall time of a large static mesh: streamed vs built in memory.

Makes (or reuses) an fBm store of ``--size``² samples, then writes the static mesh of
bound ``--max-error`` to a binary PLY twice, each in a fresh process:

- ``streamed``: ``geoterrain mesh STORE -o m.ply --max-error E`` (what the CLI does now:
  :func:`geoterrain.export.meshstream.write_static_mesh`);
- ``in-memory``: the whole mesh as one PolyData, then ``export.write_mesh`` (what the
  CLI did before, and still does for .vtp/.vtk).

Each process reports its own peak resident set (``VmHWM``,
:func:`geoterrain.core.memory.peak_rss`; ``ru_maxrss`` would count the parent's peak at exec);
with ``--check`` the two files are compared (same points, same triangles up to vertex
order, normals ≤ 1e-5).

Run from the project root::

    python benchmarks/bench_meshstream.py --size 4097 --max-error 0.1 --work /tmp/ms

The store (and the PLY files unless ``--keep``) stay in ``--work``; the 4097² store is
159 MB, each PLY about 0.8 GB at e = 0.1.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_RUN = """
import json, sys, time
sys.path.insert(0, {root!r})
t0 = time.perf_counter()
if {mode!r} == "streamed":
    from geoterrain.cli.main import cli
    try:
        cli.main(["-q", "mesh", {store!r}, "-o", {out!r}, "--max-error", {e!r},
                  "--overwrite"], standalone_mode=False)
    except SystemExit:
        pass
else:
    import geoterrain
    from geoterrain.export.meshfiles import write_mesh
    from geoterrain.export.meshdata import with_elevation
    with geoterrain.open({store!r}) as t:
        write_mesh(with_elevation(t, t.static_selection(float({e!r})).mesh), {out!r},
                   overwrite=True)
from geoterrain.core.memory import peak_rss  # VmHWM: not the parent's peak at exec
print(json.dumps({{"wall_s": time.perf_counter() - t0,
                  "max_rss_kb": peak_rss() // 1024}}))
"""


def measure(mode: str, store: Path, out: Path, e: float) -> dict:
    code = _RUN.format(root=str(ROOT), mode=mode, store=str(store), out=str(out), e=str(e))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def read_ply(path: Path):
    import numpy as np

    d = np.memmap(path, np.uint8, "r")
    head = bytes(d[:4096])
    i = head.index(b"end_header\n") + 11
    lines = head[:i].decode().split("\n")
    V = int(next(s for s in lines if s.startswith("element vertex")).split()[2])
    v = np.frombuffer(d[i:i + V * 24], "<f4").reshape(V, 6)
    f = np.frombuffer(d[i + V * 24:], np.dtype([("n", "u1"), ("i", "<i4", 3)]))["i"]
    return v, f


def same_mesh(a: Path, b: Path) -> bool:
    import numpy as np

    def canon(v, f):
        o = np.lexsort(v[:, :3].T[::-1])
        rank = np.empty(len(v), np.int64)
        rank[o] = np.arange(len(v))
        g = np.sort(rank[f], axis=1)
        return o, g[np.lexsort(g.T[::-1])]

    (va, fa), (vb, fb) = read_ply(a), read_ply(b)
    if len(va) != len(vb) or len(fa) != len(fb):
        return False
    (oa, ga), (ob, gb) = canon(va, fa), canon(vb, fb)
    return bool(np.array_equal(va[oa, :3], vb[ob, :3]) and np.array_equal(ga, gb)
                and np.abs(va[oa, 3:] - vb[ob, 3:]).max() < 1e-5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=4097)
    ap.add_argument("--max-error", type=float, default=0.1)
    ap.add_argument("--work", type=Path, default=Path("bench_meshstream"))
    ap.add_argument("--check", action="store_true", help="compare the two files")
    ap.add_argument("--keep", action="store_true", help="keep the PLY files")
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    store = a.work / f"fbm_{a.size}.geoterrain"
    if not store.exists():
        import geoterrain
        from geoterrain.ingest.synth import generate, write_geotiff

        t0 = time.perf_counter()
        dem = write_geotiff(a.work / f"fbm_{a.size}.tif", generate("fbm", a.size, seed=1))
        geoterrain.preprocess(dem, store)
        dem.unlink()
        print(f"store: {time.perf_counter() - t0:.0f} s")
    rows = {}
    for mode in ("streamed", "in-memory"):
        out = a.work / f"m_{mode}.ply"
        rows[mode] = measure(mode, store, out, a.max_error)
        r = rows[mode]
        print(f"{mode:9s}  peak RSS {r['max_rss_kb'] / 1e6:6.2f} GB ({r['max_rss_kb']} kB)  "
              f"wall {r['wall_s']:6.1f} s  file {out.stat().st_size / 1e6:.0f} MB")
    s, m = rows["streamed"], rows["in-memory"]
    print(f"ratio in-memory/streamed: RSS {m['max_rss_kb'] / s['max_rss_kb']:.1f}x, "
          f"wall {m['wall_s'] / s['wall_s']:.1f}x")
    if a.check:
        print("same mesh:", same_mesh(a.work / "m_streamed.ply", a.work / "m_in-memory.ply"))
    if not a.keep:
        for mode in rows:
            (a.work / f"m_{mode}.ply").unlink(missing_ok=True)


if __name__ == "__main__":
    main()

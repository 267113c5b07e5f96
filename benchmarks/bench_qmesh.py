"""quantized-mesh tile sets on rtin tiles against TIN tiles: bytes, time, declared errors.

    python benchmarks/bench_qmesh.py [--dem ../shared/dems/srtm1_japan.tif] [--runs 3]
    python benchmarks/bench_qmesh.py --baseline /work/main   # + main's writer, same run

The DEM is preprocessed into ``--workdir`` (by default a folder in the system temporary
directory, never the working folder); the tile sets are written there too and removed
after each run. Each run, alternating: ``write_tileset(mesher="rtin")`` then
``write_tileset(mesher="tin")`` in this process (compiled kernels warm: one untimed
warm-up set of each first), and with ``--baseline REPO`` the rtin writer of that
checkout (its own ``.venv``) as a process, timed inside it around ``write_tileset``
alone. Defaults as ``geoterrain tiles``: lattice 129, ``--max-error`` 1.

Prints, per writer, the median wall time and the bytes (the gzipped tiles, as
``geoterrain.json`` counts them; the same every run), the ratios TIN / rtin of the same
run, the load average before and after, and per level: tiles, bytes, triangles, the
largest declared error against the level's error (Cesium's; ``--max-error`` at max
zoom, where it is the vertex threshold, not a bound), and at max zoom the TIN's declared
error over rtin's, tile by tile (median, largest, and how many tiles are above rtin's).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, time
import geoterrain
from geoterrain.export.qmesh import write_tileset
with geoterrain.open(sys.argv[1]) as t:
    t0 = time.perf_counter()
    st = write_tileset(t, sys.argv[2], max_error=float(sys.argv[3]))
    print(json.dumps({"seconds": time.perf_counter() - t0, "bytes": st["bytes"]}))
"""


def _load() -> str:
    return open("/proc/loadavg").read().split(" ")[0]


def _write(store: Path, out: Path, mesher: str, max_error: float) -> tuple[float, dict]:
    import geoterrain
    from geoterrain.export.qmesh import write_tileset

    shutil.rmtree(out, ignore_errors=True)
    with geoterrain.open(store) as t:
        t0 = time.perf_counter()
        write_tileset(t, out, max_error=max_error, mesher=mesher)
        dt = time.perf_counter() - t0
    info = json.loads((out / "geoterrain.json").read_text())
    return dt, info


def _baseline(repo: Path, store: Path, out: Path, max_error: float) -> tuple[float, int]:
    shutil.rmtree(out, ignore_errors=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([str(repo / ".venv" / "bin" / "python"), "-c", CHILD, str(store),
                          str(out), str(max_error)], capture_output=True, text=True, cwd=repo,
                         env=env, check=True)
    got = json.loads(res.stdout.strip().splitlines()[-1])
    return got["seconds"], got["bytes"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dem", default=str(ROOT.parent / "shared" / "dems" / "srtm1_japan.tif"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--max-error", type=float, default=1.0)
    ap.add_argument("--baseline", help="a checkout whose rtin writer runs too (its .venv)")
    ap.add_argument("--workdir", default=None)
    a = ap.parse_args()
    import geoterrain

    work = Path(a.workdir or tempfile.mkdtemp(prefix="bench_qmesh_"))
    work.mkdir(parents=True, exist_ok=True)
    dem = Path(a.dem)
    store = work / f"{dem.stem}.geoterrain"
    if not store.exists():
        geoterrain.preprocess(dem, store)
    print(f"{dem.name}: {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, "
          f"{os.cpu_count()} CPUs, load {_load()} before")
    for m in ("rtin", "tin"):  # warm-up: compile (or load) the kernels, untimed
        _write(store, work / f"warm_{m}", m, a.max_error)
        shutil.rmtree(work / f"warm_{m}")
    times: dict[str, list[float]] = {"rtin": [], "tin": [], "main": []}
    infos: dict[str, dict] = {}
    main_bytes = None
    for r in range(a.runs):
        for m in ("rtin", "tin"):
            dt, infos[m] = _write(store, work / m, m, a.max_error)
            times[m].append(dt)
        if a.baseline:
            dt, main_bytes = _baseline(Path(a.baseline), store, work / "main", a.max_error)
            times["main"].append(dt)
        print(f"run {r + 1}: rtin {times['rtin'][-1]:.2f} s, tin {times['tin'][-1]:.2f} s"
              + (f", main {times['main'][-1]:.2f} s" if a.baseline else "")
              + f" (load {_load()})")
    med = {k: statistics.median(v) for k, v in times.items() if v}
    rb, tb = infos["rtin"]["bytes"], infos["tin"]["bytes"]
    print(f"\nload {_load()} after; medians of {a.runs} runs")
    print("| writer | bytes | seconds (median) | triangles |")
    print("|---|---|---|---|")
    if a.baseline:
        print(f"| main (rtin) | {main_bytes:,} | {med['main']:.2f} | |")
    for m in ("rtin", "tin"):
        print(f"| {m} | {infos[m]['bytes']:,} | {med[m]:.2f} | {infos[m]['triangles']:,} |")
    print(f"TIN / rtin: bytes {tb / rb:.3f}, time {med['tin'] / med['rtin']:.2f}"
          + (f"; TIN / main: bytes {tb / main_bytes:.3f}, time {med['tin'] / med['main']:.2f}"
             if a.baseline else ""))
    print("\n| level | tiles | rtin bytes | tin bytes | ratio | rtin max declared | "
          "tin max declared | level error | over (rtin / tin) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for z in sorted(infos["rtin"]["levels"], key=int):
        lr, lt = infos["rtin"]["levels"][z], infos["tin"]["levels"][z]
        print(f"| {z} | {lr['tiles']} | {lr['bytes']:,} | {lt['bytes']:,} | "
              f"{lt['bytes'] / max(lr['bytes'], 1):.2f} | {lr['max_declared']:.2f} | "
              f"{lt['max_declared']:.2f} | {lr['level_error']:.2f} | "
              f"{lr['over_level_error']} / {lt['over_level_error']} |")
    zmax = infos["rtin"]["max_zoom"]
    dr, dt_ = infos["rtin"]["declared_error"], infos["tin"]["declared_error"]
    keys = [k for k in dr if int(k.split("/")[0]) == zmax and k in dt_]
    ratio = sorted(dt_[k] / dr[k] for k in keys)
    print(f"\nmax zoom {zmax}, {len(keys)} tiles: TIN declared / rtin declared, median "
          f"{statistics.median(ratio):.3f}, largest {ratio[-1]:.3f}; TIN above rtin in "
          f"{sum(dt_[k] > dr[k] for k in keys)} tiles, by at most "
          f"{max(dt_[k] - dr[k] for k in keys):.3f} m")
    if not a.workdir:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())

"""Preprocess throughput, stage by stage, against pymartini in the same run.

Usage:
    python benchmarks/bench_preprocess.py [--size 4097] [--runs 5] [--codec-error EPS]
        [--geographic] [--skip-pymartini] [--dem PATH] [--baseline DIR]

``--dem PATH``: instead of the fBm, PATH's first band resampled bilinearly to ``--size``²
and written as the fBm is (float32, UTM, 10 m): a real relief, as the fBm is the
project's own and a ratio measured on it alone can flatter.

``--baseline DIR``: another tree of the project (``git archive main | tar -x -C DIR``),
run in the same alternation (ours, the baseline's, pymartini's, ...), with its ratio to
ours and whether its stores are byte-identical to ours (SHA-256 of the whole file).
``--baseline-env KEY=VALUE`` (repeatable) sets the baseline's environment (``DIR`` may
be this tree: ``--baseline . --baseline-env NUMPY_MADVISE_HUGEPAGE=1`` measures numpy's
huge pages, ``--baseline-env OMP_WAIT_POLICY=ACTIVE`` GNU OpenMP's spinning threads).

Each run is a fresh process (so peak memory is per run), ours and pymartini's
alternating. Prints a markdown table of medians: per-stage seconds from the store's
metadata (wall, and the process's CPU time over both cores: CPU / wall is the cores a stage
kept busy), total wall time of ``preprocess`` (after its module is imported, as
pymartini's clock starts after its import; the import is its own row), peak RSS, and
pymartini's Martini(N) + create_tile (which computes only the midpoint errors) with the
ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

# the environment as it was given: importing geoterrain (below) sets OMP_WAIT_POLICY in this
# process's, which a --baseline tree must not inherit
_ENV = dict(os.environ)

# Both sides are timed after their modules are imported (pymartini's import is outside
# its clock too); the import of the preprocess stack (numba, rasterio, pyproj) is
# reported on its own row.
PRE = """
import hashlib, json, os, sys, time
t0 = time.perf_counter()
import geoterrain
from geoterrain.preprocessing.pipeline import preprocess
t1 = time.perf_counter()
stages = {{}}
cpu = {{}}
c = [time.process_time()]


sys_t = {{}}
k = [os.times().system]


def tick(name, done, total):  # each stage's CPU (and system) time, at the end the clock reports
    now, ks = time.process_time(), os.times().system
    cpu[name] = now - c[0]
    sys_t[name] = ks - k[0]
    c[0], k[0] = now, ks


c0 = c[0]
p = preprocess(sys.argv[1], sys.argv[2], overwrite=True, codec_error={eps}, timings=stages,
               progress=tick)
wall = time.perf_counter() - t1
cpu_all = time.process_time() - c0
t = geoterrain.open(p)
from geoterrain.core.memory import peak_rss  # VmHWM: not the parent's peak at exec
peak = peak_rss() / 2**20
digest = hashlib.sha256(open(p, "rb").read()).hexdigest()
print(json.dumps({{"wall": wall, "import": t1 - t0, "stages": stages, "cpu": cpu, "sys": sys_t,
                  "cpu_all": cpu_all, "bytes": t.info()["size_bytes"], "peak_mb": peak,
                  "sha256": digest, "package": os.path.dirname(geoterrain.__file__)}}))
"""

MARTINI = """
import json, sys, time
import numpy as np, rasterio
from pymartini import Martini
with rasterio.open(sys.argv[1]) as s:
    z = s.read(1).astype(np.float32)
t0 = time.perf_counter()
m = Martini(z.shape[0])
tile = m.create_tile(z)
print(json.dumps({"wall": time.perf_counter() - t0}))
"""


def child(code: str, *args: str, tree: str | None = None, extra: dict | None = None
          ) -> tuple[dict, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    env = dict(_ENV, **(extra or {}))
    if tree:  # the baseline tree's package before this one's (an editable install)
        env["PYTHONPATH"] = os.path.abspath(tree)
    # `python -c` puts its working folder first on sys.path: a child started in this
    # repository would import this tree's package whatever PYTHONPATH says (so before
    # 2026-12-07 a --baseline run from the repository root measured this tree twice);
    # the baseline's child runs in its own tree
    out = subprocess.run([sys.executable, "-c", code, *args], check=True, capture_output=True,
                         text=True, env=env, cwd=os.path.abspath(tree) if tree else None).stdout
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return json.loads(out.strip().splitlines()[-1]), max(peak, before) / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=4097)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--codec-error", type=float, default=None)
    ap.add_argument("--geographic", action="store_true",
                    help="the fBm in EPSG:4326 at 1 arc-second (the curvilinear path)")
    ap.add_argument("--dem", default=None,
                    help="a real DEM resampled to --size² float32 instead of the fBm")
    ap.add_argument("--baseline", default=None, metavar="DIR",
                    help="another tree of the project, alternated with this one")
    ap.add_argument("--baseline-env", action="append", default=[], metavar="KEY=VALUE",
                    help="an environment variable of the baseline's runs (repeatable)")
    ap.add_argument("--skip-pymartini", action="store_true",
                    help="time ours only (Martini(16385) alone needs several GB)")
    a = ap.parse_args()
    from geoterrain.ingest.synth import generate, write_geotiff

    tmp = tempfile.TemporaryDirectory()  # removed at exit (a 16385² source is 1 GB)
    d = tmp.name
    src = os.path.join(d, "fbm.tif")
    geo = {"crs": "EPSG:4326", "origin": (10.0, 47.0), "spacing": 1 / 3600} \
        if a.geographic else {}
    if a.dem:
        import rasterio
        from rasterio.enums import Resampling

        with rasterio.open(a.dem) as s:  # the first band, bilinear to size²
            z = s.read(1, out_shape=(a.size, a.size), resampling=Resampling.bilinear)
        write_geotiff(src, z.astype(np.float32), **geo)
    else:
        write_geotiff(src, generate("fbm", a.size, seed=7), **geo)
    dst = os.path.join(d, "fbm.geoterrain")
    ours, theirs, peaks, base, loads = [], [], [], [], [os.getloadavg()[0]]
    for _ in range(a.runs):  # alternate to share the machine's drift
        r, _ = child(PRE.format(eps=a.codec_error), src, dst)
        ours.append(r)
        peaks.append(r["peak_mb"])  # this process's own peak
        if a.baseline:
            b, _ = child(PRE.format(eps=a.codec_error), src, dst, tree=a.baseline,
                         extra=dict(kv.split("=", 1) for kv in a.baseline_env))
            want = os.path.join(os.path.realpath(a.baseline), "geoterrain")
            if os.path.realpath(b["package"]) != want:
                sys.exit(f"the baseline imported {b['package']}, not {want}")
            base.append(b)
        if not a.skip_pymartini:
            m, _ = child(MARTINI, src)
            theirs.append(m["wall"])
        time.sleep(0.5)
        loads.append(os.getloadavg()[0])
    stages = ours[0]["stages"].keys()
    med = {s: statistics.median(r["stages"][s] for r in ours) for s in stages}
    wall = statistics.median(r["wall"] for r in ours)
    mart = statistics.median(theirs) if theirs else float("nan")
    where = "EPSG:4326, 1″" if a.geographic else "UTM, 10 m"
    what = f"{os.path.basename(a.dem)} resampled, float32" if a.dem else "fBm"
    print(f"\n{a.size}² {what} ({where}), codec_error={a.codec_error}, {a.runs} runs, medians; "
          f"load (1 min) {min(loads):.1f}–{max(loads):.1f}\n")

    def cpu(runs: list[dict], s: str) -> float:
        return statistics.median(r["cpu"].get(s, float("nan")) for r in runs)

    def ksys(runs: list[dict], s: str) -> float:
        return statistics.median(r["sys"].get(s, float("nan")) for r in runs)

    head = "| stage | wall s | CPU s | of it system s | CPU / wall |"
    if base:
        head += " baseline wall s | baseline CPU s | of it system s |"
    print(head)
    print("|---" * (head.count("|") - 1) + "|")
    bmed = {s: statistics.median(r["stages"][s] for r in base) for s in stages} if base else {}
    for s in stages:
        # a stage whose work ran on a thread during the ones before it takes ~0 s
        ratio = f"{cpu(ours, s) / med[s]:.2f}" if med[s] >= 0.005 else "–"
        row = f"| {s} | {med[s]:.2f} | {cpu(ours, s):.2f} | {ksys(ours, s):.2f} | {ratio} |"
        if base:
            row += f" {bmed[s]:.2f} | {cpu(base, s):.2f} | {ksys(base, s):.2f} |"
        print(row)
    cpu_all = statistics.median(r["cpu_all"] for r in ours)
    row = f"| (CPU of the whole preprocess, both cores) | | {cpu_all:.2f} | | |"
    if base:
        row += f" | {statistics.median(r['cpu_all'] for r in base):.2f} | |"
    print(row)
    err_stage = med.get("errors", 0) + med.get("radii", 0)
    print(f"| **preprocess total (wall, its module imported)** | **{wall:.2f}** |")
    imp = statistics.median(r["import"] for r in ours)
    print(f"| (import of geoterrain.preprocessing.pipeline, outside the total) | {imp:.2f} |")
    print(f"| pymartini Martini({a.size}) + create_tile | {mart:.2f} |")
    print(f"| ratio total / pymartini | {wall / mart:.2f} |")
    print(f"| ratio (errors + radii) / pymartini | {err_stage / mart:.2f} |")
    if base:
        bwall = statistics.median(r["wall"] for r in base)
        pairs = [o["wall"] / b["wall"] for o, b in zip(ours, base, strict=True)]
        same = all(r["sha256"] == ours[0]["sha256"] for r in ours + base)
        print(f"| baseline total ({a.baseline} {' '.join(a.baseline_env)}) | {bwall:.2f} |")
        print(f"| packages: ours {ours[0]['package']}, the baseline's {base[0]['package']} |")
        print(f"| baseline / pymartini | {bwall / mart:.2f} |")
        print(f"| ours / baseline (median; each pair's: {', '.join(f'{x:.2f}' for x in pairs)}) "
              f"| {wall / bwall:.2f} |")
        print(f"| stores byte-identical to the baseline's (SHA-256 of the file) | {same} |")
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"| throughput | {a.size ** 2 / wall / 1e6:.2f} M samples/s, "
          f"{a.size ** 2 / wall / cores / 1e6:.2f} M samples/s per core ({cores} cores) |")
    print(f"| peak RSS of a preprocess run (max over the runs) | {max(peaks):.0f} MB |")
    print(f"| store size | {ours[0]['bytes'] / 1e6:.1f} MB |")


if __name__ == "__main__":
    main()

"""The first run on an empty kernel cache: where numba's compile time goes (a script, not
a test).

Runs the commands of ``make demo`` in this process, with ``NUMBA_CACHE_DIR`` pointed at
an empty temporary folder, and records every compilation numba reports
(``numba.core.event``, "numba:compile"). Each kernel's time is its own: the time of the
kernels it compiles in turn (its callees) is taken off. Prints each command's CPU and wall
time, the total compile time, and the kernels that cost the most.

The whole-process figure a user sees is ``make demo`` itself on an empty cache::

    rm -rf /tmp/empty && mkdir /tmp/empty
    /usr/bin/time -v env NUMBA_CACHE_DIR=/tmp/empty make demo

Usage: ``python benchmarks/bench_first_run.py [--top 30]`` (from the project root; the
demo's outputs go to a temporary folder).

``--processes``: each command in a process of its own, as ``make demo`` runs them, on one
shared empty cache. A kernel compiled by one command is then loaded from the cache by the
next, but numba's own library functions (``np.empty``, ``min``, string formatting, …) are
not cached: each command compiles again those its new kernels use. Prints per command
its CPU, its compile CPU and how much of it numba's own functions took, and any kernel
compiled by two commands (a cache index that missed). A baseline tree runs the same way
with ``PYTHONPATH=BASE`` (``geoterrain/`` with ``cli/`` copied into it).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def demo_commands(out: str) -> list[list[str]]:
    """The Makefile's demo, its outputs under ``out``."""
    store = f"{out}/fbm_513.geoterrain"
    return [
        ["preprocess", str(ROOT / "sample_dems" / "fbm_513.tif"), "-o", store, "--overwrite"],
        ["info", store],
        ["mesh", store, "-o", f"{out}/fbm_513.ply", "--max-error", "1", "--overwrite"],
        ["render", store, "-o", f"{out}/fbm_513.png", "--overwrite"],
        ["render", store, "-o", f"{out}/fbm_513_map.png", "--map", "--overwrite",
         "--water-level", "300"],
        ["export", store, "-o", f"{out}/fbm_513.glb", "--max-error", "5", "--print-size",
         "150", "--preview", f"{out}/fbm_513_print.png", "--overwrite"],
        ["export-raster", store, "--what", "hillshade", "-o", f"{out}/fbm_513_hillshade.tif",
         "--overwrite"],
    ]


def _child(cmd: list[str]) -> None:
    """One command in this process (``--child``): its compilations as JSON on stdout's
    last line (function, argument types, own CPU s) and the process's CPU."""
    from numba.core import event

    rows: list[list] = []
    stack: list[list] = []

    class Timer(event.Listener):
        def on_start(self, ev) -> None:
            stack.append([time.process_time(), 0.0])

        def on_end(self, ev) -> None:
            t0, callees = stack.pop()
            spent = time.process_time() - t0
            f = ev.data["dispatcher"].py_func
            rows.append([f"{f.__module__}.{f.__qualname__}", str(ev.data.get("args")),
                         spent - callees,
                         bool(ev.data["dispatcher"].targetoptions.get("parallel"))])
            if stack:
                stack[-1][1] += spent

    event.register("numba:compile", Timer())
    start = time.process_time()  # the interpreter, numba's import and the listener
    from geoterrain.cli.main import cli

    try:
        cli.main(cmd, prog_name="geoterrain", standalone_mode=False)
    except SystemExit:
        pass
    print(json.dumps({"rows": rows, "cpu": time.process_time(), "start": start}))


def _processes(json_out: str | None = None) -> None:
    """The demo's commands, each in a process of its own on one empty cache."""
    cache = tempfile.mkdtemp(prefix="numba-cache-")
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    print(f"load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores, cache {cache}")
    seen: dict[tuple[str, str], str] = {}
    twice = []
    tot = [0.0, 0.0, 0.0, 0.0, 0.0]
    print("| command | process CPU s | compile CPU s | of it numba's own | of it parallel "
          "kernels | specialisations |\n|---|---:|---:|---:|---:|---:|")
    record = []
    with tempfile.TemporaryDirectory() as out:
        for i, cmd in enumerate(demo_commands(out)):
            w0 = time.perf_counter()
            r = subprocess.run([sys.executable, __file__, "--child", json.dumps(cmd)],
                               env=env, capture_output=True, text=True, check=True)
            wall = time.perf_counter() - w0
            got = json.loads(r.stdout.strip().splitlines()[-1])
            comp = sum(x[2] for x in got["rows"])
            own = sum(x[2] for x in got["rows"] if x[0].startswith("numba."))
            par = sum(x[2] for x in got["rows"] if x[3])
            record.append({"command": cmd[0], "cpu": got["cpu"], "start": got["start"],
                           "wall": wall, "rows": got["rows"]})
            for name, sig, _, _ in got["rows"]:
                if not name.startswith("numba."):
                    if (name, sig) in seen:
                        twice.append((name, seen[(name, sig)], cmd[0]))
                    seen[(name, sig)] = f"{i + 1}:{cmd[0]}"
            for k, v in enumerate((got["cpu"], comp, own, par, len(got["rows"]))):
                tot[k] += v
            print(f"| {i + 1}:{cmd[0]} | {got['cpu']:.1f} | {comp:.1f} | {own:.1f} | "
                  f"{par:.1f} | {len(got['rows'])} |  (wall {wall:.1f} s, start "
                  f"{got['start']:.2f} s CPU)")
    shutil.rmtree(cache, ignore_errors=True)
    print(f"| all | {tot[0]:.1f} | {tot[1]:.1f} | {tot[2]:.1f} | {tot[3]:.1f} | "
          f"{tot[4]:.0f} |")
    if json_out:
        Path(json_out).write_text(json.dumps(record))
    print(f"kernels compiled by two commands: {len(twice)}"
          + "".join(f"\n  {n} ({a}, {b})" for n, a, b in twice))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--top", type=int, default=30, help="kernels listed (default 30)")
    ap.add_argument("--processes", action="store_true",
                    help="each command in a process of its own, as make demo runs them")
    ap.add_argument("--json", help="--processes: every compilation (command, function, "
                    "argument types, own CPU s, parallel) written to this file")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        _child(json.loads(args.child))
        return
    if args.processes:
        _processes(args.json)
        return
    cache = tempfile.mkdtemp(prefix="numba-cache-")
    os.environ["NUMBA_CACHE_DIR"] = cache  # before numba is imported
    from numba.core import event

    own: dict[tuple[str, str], float] = {}
    where: dict[tuple[str, str], str] = {}  # the command that compiled it
    stack: list[list] = []
    now = [""]

    class Timer(event.Listener):
        def on_start(self, ev) -> None:
            stack.append([time.process_time(), 0.0])

        def on_end(self, ev) -> None:
            t0, callees = stack.pop()
            spent = time.process_time() - t0
            f = ev.data["dispatcher"].py_func
            key = (f"{f.__module__}.{f.__qualname__}", str(ev.data.get("args")))
            own[key] = own.get(key, 0.0) + spent - callees
            where.setdefault(key, now[0])
            if stack:
                stack[-1][1] += spent

    event.register("numba:compile", Timer())
    from geoterrain.cli.main import cli

    print(f"load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores, cache {cache}")
    cpu_all, wall_all = time.process_time(), time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        for i, cmd in enumerate(demo_commands(out)):
            now[0] = f"{i + 1}:{cmd[0]}"
            c0, w0 = time.process_time(), time.perf_counter()
            try:
                cli.main(cmd, prog_name="geoterrain", standalone_mode=False)
            except SystemExit:
                pass
            print(f"{cmd[0]:>14}: CPU {time.process_time() - c0:6.1f} s, "
                  f"wall {time.perf_counter() - w0:6.1f} s", file=sys.stderr)
    total = sum(own.values())
    kernels = {k for k, _ in own}
    shutil.rmtree(cache, ignore_errors=True)
    print(f"\nall commands: CPU {time.process_time() - cpu_all:.1f} s, wall "
          f"{time.perf_counter() - wall_all:.1f} s; compiling: CPU {total:.1f} s, "
          f"{len(own)} specialisations of {len(kernels)} functions")
    per: dict[str, float] = {}
    for key, s in own.items():
        per[where[key]] = per.get(where[key], 0.0) + s
    print("compiling per command (CPU s): " + ", ".join(f"{k} {v:.1f}" for k, v in per.items()))
    print("\n| own compile CPU, s | command | function | argument types |\n|---:|---|---|---|")
    for (name, sig), s in sorted(own.items(), key=lambda kv: -kv[1])[:args.top]:
        print(f"| {s:.2f} | {where[(name, sig)]} | {name} | {sig[:90]} |")
    by_name: dict[str, list[float]] = {}
    for (name, _), s in own.items():
        by_name.setdefault(name, []).append(s)
    many = sorted(((sum(v), len(v), k) for k, v in by_name.items() if len(v) > 1), reverse=True)
    print(f"\nfunctions compiled more than once: {len(many)}, "
          f"{sum(t for t, _, _ in many):.1f} s CPU in all")
    for t, n, name in many:
        print(f"  {t:6.2f} s  {n}×  {name}")


if __name__ == "__main__":
    main()

"""Wall time of `geoterrain info STORE`, a whole process on a warm cache, and what it
imports.

    python benchmarks/bench_startup.py STORE [STORE ...] [--runs N] [--baseline-tree DIR]

Each store: the median, fastest and slowest of N runs of ``geoterrain info STORE``,
``info STORE --no-reference`` and ``info STORE --reference`` (the DEFLATE GeoTIFF
comparison, which decodes every level-0 tile), each a fresh ``python -m
geoterrain.cli.main`` process, after one unmeasured run of each (kernels compiled, files
in the page cache); wall and CPU time (user + system, of the child process: the machine
is shared, so the CPU time says what the command costs when a core is free). ``--variants``
picks the commands. ``--baseline-tree DIR``: another commit's ``geoterrain/`` with its
``cli/`` copied in as ``geoterrain/cli/`` (``git archive COMMIT geoterrain cli | tar -x -C
DIR; cp -r DIR/cli DIR/geoterrain/``), run in turns with this tree's for same-run ratios;
a tree from before ``--reference`` (issue 51) compares with its default there. Also says
whether numba, VTK, PyVista and pyproj were imported by this tree's ``info``.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _run(args: list[str], tree: str | None) -> tuple[float, float]:
    # from a folder without a geoterrain/ (python -m puts the working folder first on the
    # path), this tree's or the baseline's first on PYTHONPATH
    env = dict(os.environ)
    env["PYTHONPATH"] = (tree or ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "geoterrain.cli.main", "info", *args], env=env,
                   check=True, stdout=subprocess.DEVNULL, cwd=os.path.dirname(args[0]))
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def _imports() -> str:
    code = ("import sys, runpy; sys.argv = ['geoterrain', 'info', sys.argv[1]]\n"
            "try:\n    runpy.run_module('geoterrain.cli.main', run_name='__main__')\n"
            "except SystemExit:\n    pass\n"
            "print(*(m in sys.modules for m in ('numba', 'vtkmodules', 'pyvista', 'pyproj')), "
            "file=sys.stderr)")
    return code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--baseline-tree", help="another commit's geoterrain/ to compare with")
    ap.add_argument("--variants", default="default,no-reference,reference",
                    help="which of info, info --no-reference, info --reference to run")
    a = ap.parse_args()
    trees = {"this tree": None}
    if a.baseline_tree:
        trees["baseline"] = a.baseline_tree
    print(f"load {os.getloadavg()[0]:.2f}")
    print("| store | command | tree | median s | fastest | slowest | CPU median s |\n"
          "|---|---|---|---|---|---|---|")
    chosen = a.variants.split(",")
    variants = [v for k, v in (("default", []), ("no-reference", ["--no-reference"]),
                               ("reference", ["--reference"])) if k in chosen]
    for store in map(os.path.abspath, a.stores):
        for extra in variants:
            # a baseline from before --reference: its default compared
            argv = {k: [store, *([] if k == "baseline" and extra == ["--reference"] else extra)]
                    for k in trees}
            for k, tree in trees.items():
                _run(argv[k], tree)  # warm
            times: dict[str, list[float]] = {k: [] for k in trees}
            cpu: dict[str, list[float]] = {k: [] for k in trees}
            for _ in range(a.runs):  # in turns, so the load falls on both alike
                for k, tree in trees.items():
                    w, c = _run(argv[k], tree)
                    times[k].append(w)
                    cpu[k].append(c)
            med = {k: statistics.median(v) for k, v in times.items()}
            mc = {k: statistics.median(v) for k, v in cpu.items()}
            for k, v in times.items():
                ratio = f" ({med[k] / med['baseline']:.2f}×)" if "baseline" in med else ""
                print(f"| {os.path.basename(store)} | info {' '.join(argv[k][1:])} | {k} | "
                      f"{med[k]:.3f}{ratio} | {min(v):.3f} | {max(v):.3f} | {mc[k]:.3f}"
                      + (f" ({mc[k] / mc['baseline']:.2f}×) |" if "baseline" in mc else " |"))
    r = subprocess.run([sys.executable, "-c", _imports(), os.path.abspath(a.stores[0])],
                       capture_output=True, text=True, cwd=ROOT)
    flags = r.stderr.split()[-4:]
    print(f"\ninfo imports numba {flags[0]}, VTK {flags[1]}, PyVista {flags[2]}, "
          f"pyproj {flags[3]}; "
          f"load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()

"""A cold `geoterrain render` (kernels cached, store not yet opened), what its libraries
cost before any work, and which compiled kernels it loads (issue 51: ≤ 1.5 s for
1280×720 of the 4097² store).

    python benchmarks/bench_cold_render.py STORE [--runs N] [--baseline-tree DIR]
                                          [--no-overlays] [--kernels] [--no-floor]

Each run is a fresh ``python -m geoterrain.cli.main render STORE -o … --size 1280x720
--pixel-error 1 --strategy rtin``, after one unmeasured run (kernels compiled, files in the
page cache): wall and CPU time (user + system of the child). ``--baseline-tree DIR``:
another commit's ``geoterrain/`` with its ``cli/`` copied in as ``geoterrain/cli/`` (as
benchmarks/bench_startup.py), run in turns with this tree's for same-run ratios; the
pictures of the two trees are compared byte for byte. In the same turns, the floor: fresh
processes that only import the render's libraries (numpy; numba and the first call of a
cached kernel; Pillow; VTK's rendering modules; and PyVista, which a render loaded before
it drew on VTK alone), each row adding to the previous one, numba and VTK started as this
tree's command line starts them (``geoterrain/core/startup.py``), and numpy with numba as
numba starts by itself. ``--no-overlays``: in the same turns, this tree's render with
``--no-overlays`` (no colour bar, scale bar or north arrow; the overlays are drawn on
Pillow). ``--no-floor``: without the import-only processes. ``--kernels``: one more run
of this tree, listing the kernels it loads from numba's cache and the CPU time of each
load.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

_KERNEL = ("import numba\n@numba.njit(cache=True)\ndef bench_cold_render_kernel(a):\n"
           "    return a + 1\n")
# each adds to the previous: the render's libraries, in the order a render pays them, numba
# and VTK started as this tree's command line starts them (geoterrain/core/startup.py)
_START = ("try:\n    from geoterrain.core import startup\n    startup.install()\n"
          "except ImportError:\n    pass\n")
FLOOR = {
    "numpy": "import numpy",
    "+ numba, a cached kernel's first call": _START + "import numba, k; "
                                             "k.bench_cold_render_kernel(1)",
    "+ Pillow (the PNG, the overlays' text)": "import PIL.Image, PIL.ImageDraw, PIL.ImageFont, "
                                              "PIL.PngImagePlugin",
    "+ VTK's rendering modules (what a render loads)": "import vtkmodules.vtkRenderingOpenGL2, "
                                                       "vtkmodules.vtkRenderingCore, "
                                                       "vtkmodules.util.numpy_support",
    "+ PyVista (no longer loaded by a render)": "import pyvista",
}

LOADS = """
import runpy, sys, time
import numba.core.caching as C
try:  # this tree loads cached kernels without numba's context refresh: time that load
    from geoterrain.core import startup
    startup.install()
except ImportError:  # an older tree
    pass
loads = []
_orig = C.Cache.load_overload
def timed(self, sig, ctx):
    c0 = time.process_time()
    r = _orig(self, sig, ctx)
    loads.append((self._name.split(" at ")[0].replace("<function ", ""),
                  time.process_time() - c0))
    return r
C.Cache.load_overload = timed
sys.argv = ["geoterrain"] + sys.argv[1:]
try:
    runpy.run_module("geoterrain.cli.main", run_name="__main__")
except SystemExit:
    pass
print(f"{len(loads)} kernels loaded from numba's cache, {sum(c for _, c in loads):.3f} s CPU "
      f"(the first: {loads[0][1]:.3f} s, numba's runtime starting)" if loads else
      "no kernel loaded", file=sys.stderr)
for name, c in loads:
    print(f"  {1e3 * c:7.1f} ms  {name}", file=sys.stderr)
"""


def _timed(cmd: list[str], env: dict, cwd: str) -> tuple[float, float]:
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--baseline-tree", help="another commit's geoterrain/ to compare with")
    ap.add_argument("--no-overlays", action="store_true",
                    help="also this tree's render without overlays")
    ap.add_argument("--kernels", action="store_true", help="list the kernels loaded")
    ap.add_argument("--no-floor", action="store_true",
                    help="skip the import-only processes (half the run's time)")
    a = ap.parse_args()
    store = os.path.abspath(a.store)
    work = tempfile.mkdtemp(prefix="bench_cold_render")
    with open(os.path.join(work, "k.py"), "w") as fh:
        fh.write(_KERNEL)
    trees = {"this tree": ROOT}
    if a.baseline_tree:
        trees["baseline"] = os.path.abspath(a.baseline_tree)

    def env_for(tree: str | None) -> dict:
        env = dict(os.environ)
        env.pop("PYTHONDONTWRITEBYTECODE", None)  # as an installed tool runs
        env["PYTHONPATH"] = os.pathsep.join(p for p in (tree, work, env.get("PYTHONPATH"))
                                            if p)
        return env

    def render(name: str) -> list[str]:
        return [sys.executable, "-m", "geoterrain.cli.main", "-q", "render", store, "-o",
                os.path.join(work, f"{name.replace(' ', '_')}.png"), "--size", "1280x720",
                "--pixel-error", "1", "--strategy", "rtin", "--overwrite"]

    jobs = {name: (render(name), env_for(tree)) for name, tree in trees.items()}
    if a.no_overlays:
        jobs["this tree, --no-overlays"] = (render("no overlays") + ["--no-overlays"],
                                            env_for(ROOT))
    code = ""
    for name, c in ({} if a.no_floor else FLOOR).items():
        code += c + "\n"
        jobs[name] = ([sys.executable, "-c", code], env_for(ROOT))
    if not a.no_floor:  # numba's own start, for comparison
        jobs["numpy + numba as numba starts (no startup.install)"] = (
            [sys.executable, "-c", FLOOR["numpy"] + "\n" + FLOOR[
                "+ numba, a cached kernel's first call"].replace(_START, "")], env_for(None))
    for cmd, env in jobs.values():  # warm: kernels compiled and cached, files in memory
        _timed(cmd, env, work)
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in jobs}
    digests: dict[str, set] = {k: set() for k in trees}
    loads = []
    for run in range(a.runs):
        order = list(jobs) if run % 2 == 0 else list(jobs)[::-1]
        for name in order:
            loads.append(os.getloadavg()[0])
            times[name].append(_timed(*jobs[name], work))
            if name in trees:
                with open(jobs[name][0][7], "rb") as fh:
                    digests[name].add(hashlib.sha256(fh.read()).hexdigest())
    med = statistics.median
    print(f"{a.runs} runs each, in turns; load {min(loads):.1f}–{max(loads):.1f}\n")
    print("| process | wall median (fastest–slowest) s | CPU median s |\n|---|---|---|")
    for name, r in times.items():
        w = [x[0] for x in r]
        print(f"| {name} | {med(w):.2f} ({min(w):.2f}–{max(w):.2f}) | "
              f"{med(x[1] for x in r):.2f} |")
    if a.baseline_tree:
        n, b = times["this tree"], times["baseline"]
        same = len(digests["this tree"] | digests["baseline"]) == 1
        print(f"\nthis tree ÷ baseline: wall {med(x[0] for x in n) / med(x[0] for x in b):.3f}, "
              f"CPU {med(x[1] for x in n) / med(x[1] for x in b):.3f}; pictures "
              f"{'identical' if same else 'DIFFER'}")
    if a.kernels:
        subprocess.run([sys.executable, "-c", LOADS, *render("kernels")[3:]],
                       env=env_for(ROOT), cwd=work, check=True)


if __name__ == "__main__":
    main()

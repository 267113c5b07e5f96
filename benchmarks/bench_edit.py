"""Editing a store in place against preprocessing the edited DEM again, in the same run
(issue 52: a 65 × 65 window of a 4097² store).

Usage:
    python benchmarks/bench_edit.py [--size 4097] [--window 65] [--edits 5] [--runs 3]
        [--seed 0] [--int] [--baseline-tree DIR] [--wide]

Makes a fBm DEM (``geoterrain synth``; ``--int``: its heights rounded to whole metres,
an integer store like SRTM's), preprocesses it once, then alternates ``--runs`` times:
a full preprocess of the DEM in a fresh process, and an editing process that applies
``--edits`` random windows (a cut: −20 m, ``add``), each to a fresh copy of the store.
Each process is timed after its imports (the compiled kernels are on disk); the first
edit of a process also loads its kernels from numba's cache, so it is reported apart
from the next ones; a third child, the command line itself (``geoterrain edit STORE
--patch cut.tif --mode add --at R,C``, a fresh process from start to exit: its imports,
numba's start, the store's open, the patch read, the edit), is the first edit a user
waits for, and two more give its floor: a process that imports what any edit reads with
(numpy, rasterio, sqlite3, zstandard, click) and exits, and the same with numba. For
each edit: the rows and bytes it wrote (blobs and catalog), the
store's pages that differ afterwards (1 kB pages, compared with the copy before) and the
file's growth; and the time of the transaction apart (its syncs). ``--baseline-tree DIR``:
another commit's ``geoterrain/`` with its ``cli/`` copied in as ``geoterrain/cli/`` (as
benchmarks/bench_startup.py; run once beforehand, so its kernels are cached), whose two
children run in turns with this tree's in each run, for same-run ratios (a table at the
end). ``--wide``: also a root-grid store (``root_grid=True``) of the DEM's first
(size + 1) / 2 rows, a (size + 1) / 2 × size raster on 2 × 1 roots (issue 45 × 52: its
edit by tiles), preprocessed and edited by the same children in the same runs, the two
stores' order alternating from run to run; its tables follow the square's. Prints
markdown tables of medians and the ratios to the preprocess, in wall time and in CPU
time (the process's user + system time over all its threads: less sensitive to other
jobs on the machine than wall time, but it counts the preprocess's parallel work once
per core).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

PRE = """
import json, sys, time
t0 = time.perf_counter()
from geoterrain.preprocessing.pipeline import preprocess
t1, c1 = time.perf_counter(), time.process_time()
preprocess(sys.argv[1], sys.argv[2], overwrite=True, root_grid=sys.argv[3:] == ["roots"])
print(json.dumps({"wall": time.perf_counter() - t1, "cpu": time.process_time() - c1}))
"""

EDIT = """
import json, os, shutil, sys, time
import numpy as np
t0 = time.perf_counter()
import geoterrain
from geoterrain.preprocessing.edit import Patch, edit_terrain
store, work = sys.argv[1], sys.argv[2]
n, w, seed = (int(v) for v in sys.argv[3:6])

rng = np.random.default_rng(seed)
out = []
with geoterrain.open(store) as t0_:
    rows, cols = t0_.grid.rows, t0_.grid.cols
for k in range(n):
    p = os.path.join(work, f"e{k}.geoterrain")
    shutil.copy(store, p)
    os.sync()
    r, c = int(rng.integers(0, rows - w)), int(rng.integers(0, cols - w))
    t = geoterrain.open(p)
    t1, c1 = time.perf_counter(), time.process_time()
    res = edit_terrain(t, Patch(r, c, np.full((w, w), -20.0)), "add")
    wall, cpu = time.perf_counter() - t1, time.process_time() - c1
    t.close()
    a = np.fromfile(store, np.uint8)
    b = np.fromfile(p, np.uint8)
    m = min(a.size, b.size) // 1024 * 1024
    pages = int((a[:m].reshape(-1, 1024) != b[:m].reshape(-1, 1024)).any(axis=1).sum())
    pages += (max(a.size, b.size) - m + 1023) // 1024
    out.append({"wall": wall, "cpu": cpu, "write": res.write_seconds, "how": res.how,
                "why": res.why,
                "rows": res.rows,
                "bytes": res.bytes, "pages": pages, "growth": int(b.size - a.size),
                "size": int(a.size), "window": [r, c]})
    os.remove(p)
print(json.dumps(out))
"""


CLI = """
import sys
from geoterrain.cli.main import main
sys.argv[0] = "geoterrain"
main()
"""

FLOOR = "import numpy, rasterio, sqlite3, zstandard, click"


def process(args: list, tree: str | None = None, cwd: str | None = None) -> dict:
    """Wall and CPU time (user + system, the child's) of one fresh process, start to exit."""
    env = dict(os.environ)
    if tree is not None:
        env["PYTHONPATH"] = tree + os.pathsep + env.get("PYTHONPATH", "")
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True, env=env,
                   cwd=os.path.abspath(tree) if tree else cwd)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"wall": wall, "cpu": r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime}


def cli_edit(store: str, cut: str, a, work: str, run: int, tree: str | None = None) -> dict:
    """One `geoterrain edit` process on a fresh copy of ``store`` (a window of run ``run``)."""
    import sqlite3

    import numpy as np

    from geoterrain.store.catalog import META_ID, unpack_metadata

    p = os.path.join(work, "cli.geoterrain")
    shutil.copy(store, p)
    os.sync()
    rng = np.random.default_rng(1000 + a.seed + run)
    # the grid's shape from the metadata row alone: a baseline tree's store may be in a
    # schema this tree refuses (another commit's format)
    con = sqlite3.connect(f"file:{p}?mode=ro", uri=True)
    try:
        (data,) = con.execute("SELECT data FROM catalog WHERE id = ?", (META_ID,)).fetchone()
    finally:
        con.close()
    grid = unpack_metadata(data)["grid"]
    rows, cols = int(grid["rows"]), int(grid["cols"])
    at = f"{int(rng.integers(0, rows - a.window))},{int(rng.integers(0, cols - a.window))}"
    try:
        return process([sys.executable, "-c", CLI, "-q", "edit", p, "--patch", cut, "--mode",
                        "add", "--at", at], tree=tree, cwd=work)
    finally:
        os.remove(p)


def child(code: str, *args: str, tree: str | None = None):
    env = dict(os.environ)
    if tree is not None:  # another commit's geoterrain/ first on the path
        env["PYTHONPATH"] = tree + os.pathsep + env.get("PYTHONPATH", "")
    # `python -c` puts the working folder first on the path: run the baseline in its own
    # tree, or a run from this repository's root would import this tree's package as both
    out = subprocess.run([sys.executable, "-c", code, *args], check=True, capture_output=True,
                         text=True, env=env, cwd=os.path.abspath(tree) if tree else None)
    return json.loads(out.stdout.strip().splitlines()[-1])


def warm_up(store: str, work: str, window: int):
    """Compile (or load) an edit's kernels before the timed children run: one edit of a
    copy of ``store``, a ``window``² window away from the data's corner as the timed
    edits' are, so by tiles (an edit that reaches the corner goes to the whole grid when
    it lowers the store's largest δ, and left the by-tiles kernels to the first timed
    child to compile). Returns its :class:`~geoterrain.preprocessing.edit.EditResult`."""
    import numpy as np

    import geoterrain
    from geoterrain.preprocessing.edit import Patch, edit_terrain

    warm = os.path.join(work, "warm.geoterrain")
    shutil.copy(store, warm)
    try:
        with geoterrain.open(warm) as t:
            r, c = (t.grid.rows - window) // 2, (t.grid.cols - window) // 2
            return edit_terrain(t, Patch(r, c, np.full((window, window), -20.0)), "add")
    finally:
        os.remove(warm)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=4097)
    ap.add_argument("--window", type=int, default=65)
    ap.add_argument("--edits", type=int, default=5)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--int", action="store_true", help="integer heights (an SRTM-like store)")
    ap.add_argument("--baseline-tree", help="another commit's geoterrain/ to compare with")
    ap.add_argument("--wide", action="store_true",
                    help="also a (size+1)/2 × size root-grid store (2 × 1 roots)")
    a = ap.parse_args()
    import numpy as np

    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.pipeline import preprocess

    work = tempfile.mkdtemp(prefix="bench_edit")
    try:
        z = generate("fbm", a.size, seed=a.seed)
        if a.int:
            z = np.rint(z)
        dem = write_geotiff(os.path.join(work, "dem.tif"), z)
        store = os.path.join(work, "dem.geoterrain")
        preprocess(dem, store, overwrite=True)  # compiles what is not yet cached
        cut = write_geotiff(os.path.join(work, "cut.tif"), np.full((a.window, a.window), -20.0))
        cases = [Case(f"{a.size}² square", dem, store, False, cut)]
        if a.wide:
            half = (a.size + 1) // 2
            dw = write_geotiff(os.path.join(work, "wide.tif"), np.ascontiguousarray(z[:half]))
            sw = os.path.join(work, "wide.geoterrain")
            preprocess(dw, sw, overwrite=True, root_grid=True)
            cases.append(Case(f"{half} × {a.size} on 2 × 1 roots", dw, sw, True, cut))
        for c in cases:  # an edit's (serial) kernels
            res = warm_up(c.store, work, a.window)
            if res.how != "tiles":
                print(f"{c.name}: the warm-up edit went to the {res.how} ({res.why}); the "
                      "first timed edit by tiles may compile kernels", flush=True)
        base: dict = {"pre": [], "first": [], "next": [], "cli": []}
        a.cut = cut
        for run in range(a.runs):
            if a.baseline_tree and run % 2 == 0:
                _baseline(base, a, dem, work, run)
            for c in (cases if run % 2 == 0 else cases[::-1]):
                c.run(a, work, run)
            if a.baseline_tree and run % 2 == 1:  # in turns: the baseline second
                _baseline(base, a, dem, work, run)
        for c in cases:
            c.report(a)
        if a.baseline_tree:
            _compare(cases[0], base)
    finally:
        shutil.rmtree(work, ignore_errors=True)


class Case:
    """One store: its DEM, its preprocess and editing children's results."""

    def __init__(self, name: str, dem: str, store: str, roots: bool, cut: str):
        self.name, self.dem, self.store, self.roots, self.cut = name, dem, store, roots, cut
        self.pre: list = []
        self.first: list = []
        self.later: list = []
        self.cli: list = []  # `geoterrain edit` processes
        self.floor: list = []  # (imports, imports + numba) processes

    def run(self, a, work: str, run: int) -> None:
        self.pre.append(child(PRE, self.dem, os.path.join(work, "p.geoterrain"),
                              *(["roots"] if self.roots else [])))
        edits = child(EDIT, self.store, work, str(a.edits), str(a.window), str(a.seed + run))
        self.first.append(edits[0])
        self.later += edits[1:]
        self.cli.append(cli_edit(self.store, self.cut, a, work, run))
        self.floor.append((process([sys.executable, "-c", FLOOR], cwd=work),
                           process([sys.executable, "-c", FLOOR + ", numba"], cwd=work)))
        print(f"run {run}, {self.name}: preprocess {self.pre[-1]['wall']:.2f} s; edits "
              + ", ".join(f"{e['wall']:.3f} s ({e['how']})" for e in edits)
              + f"; `geoterrain edit` {self.cli[-1]['wall']:.3f} s"
              + f"; load {os.getloadavg()[0]:.1f}", flush=True)

    def report(self, a) -> None:
        pre, first, later = self.pre, self.first, self.later
        med = statistics.median
        p = med(e["wall"] for e in pre)
        pc = med(e["cpu"] for e in pre)
        size = first[0]["size"]
        print(f"\n{self.name}: fBm{' (integer heights)' if a.int else ''}, store "
              f"{size / 1e6:.1f} MB, {a.window}² windows, {a.runs} runs "
              f"({len(first) + len(later)} edits), load {os.getloadavg()[0]:.1f}\n")
        print("| | median s | × preprocess |\n|---|---|---|")
        print(f"| preprocess (fresh process, after imports) | {p:.2f} | 1 |")
        for name, es in (("first edit of a process (loads its kernels)", first),
                         ("next edits", later)):
            if es:
                w = med(e["wall"] for e in es)
                print(f"| {name} | {w:.3f} | {w / p:.3f} |")
                w = med(e["wall"] - e["write"] for e in es)
                print(f"| {name}: computing the rows | {w:.3f} | {w / p:.3f} |")
                w = med(e["write"] for e in es)
                print(f"| {name}: the transaction (synced) | {w:.3f} | {w / p:.3f} |")
        print(f"\n| CPU time (user + system, all threads) | median s | × preprocess |\n"
              f"|---|---|---|\n| preprocess | {pc:.2f} | 1 |")
        for name, es in (("first edit of a process", first), ("next edits", later)):
            if es:
                w = med(e["cpu"] for e in es)
                print(f"| {name} | {w:.3f} | {w / pc:.3f} |")
        print("\n| a fresh process, start to exit | wall s | CPU s | × preprocess wall / CPU |"
              "\n|---|---|---|---|")
        for name, es in (("`geoterrain edit` (the first edit a user waits for)", self.cli),
                         (f"floor: `python -c \"{FLOOR}\"`", [f[0] for f in self.floor]),
                         ("floor + numba", [f[1] for f in self.floor])):
            w, c = med(e["wall"] for e in es), med(e["cpu"] for e in es)
            print(f"| {name} | {w:.3f} | {c:.3f} | {w / p:.3f} / {c / pc:.3f} |")
        allx = first + later
        print("\n| per edit (median) | bytes | % of the store |\n|---|---|---|")
        for key, what in (("bytes", "rows written (blobs + catalog)"),
                          ("pages", "pages of the store changed (1 kB)"),
                          ("growth", "file growth")):
            v = med(e[key] * (1024 if key == "pages" else 1) for e in allx)
            print(f"| {what} | {v / 1e3:.1f} kB | {100 * v / size:.2f} % |")
        hows = {e["how"] + (f": {e['why']}" if e["why"] else "") for e in allx}
        print(f"\nhow: {', '.join(sorted(hows))}; rows: {med(e['rows'] for e in allx)}")
        w = max(e["bytes"] for e in allx)
        print(f"largest edit: {w / 1e3:.1f} kB written, {100 * w / size:.2f} % of the store")


def _compare(case: Case, base: dict) -> None:
    """This tree's square store against the baseline tree's, same run."""
    med = statistics.median
    print("\n| same run, in turns | preprocess wall / CPU s | first edit wall / CPU s "
          "(× preprocess) | next edits wall / CPU s (× preprocess) | `geoterrain edit` "
          "process wall / CPU s (× preprocess) |\n|---|---|---|---|---|")
    for name, r in (("this tree", {"pre": case.pre, "first": case.first, "next": case.later,
                                   "cli": case.cli}), ("baseline", base)):
        pw, pc = med(e["wall"] for e in r["pre"]), med(e["cpu"] for e in r["pre"])
        cells = [f"{pw:.2f} / {pc:.2f}"]
        for k in ("first", "next", "cli"):
            w, c = med(e["wall"] for e in r[k]), med(e["cpu"] for e in r[k])
            cells.append(f"{w:.3f} / {c:.3f} ({w / pw:.3f} / {c / pc:.3f})")
        print(f"| {name} | " + " | ".join(cells) + " |")


def _baseline(base: dict, a, dem: str, work: str, run: int) -> None:
    """The baseline tree's preprocess and editing processes of run ``run`` (same edits)."""
    tree = os.path.abspath(a.baseline_tree)
    # the baseline edits the store its own preprocess wrote (another commit may write, and
    # read, another store format than this tree's `store`)
    own = os.path.join(work, "baseline.geoterrain")
    base["pre"].append(child(PRE, dem, own, tree=tree))
    edits = child(EDIT, own, work, str(a.edits), str(a.window), str(a.seed + run), tree=tree)
    base["first"].append(edits[0])
    base["next"] += edits[1:]
    base["cli"].append(cli_edit(own, a.cut, a, work, run, tree=tree))
    print(f"run {run}, baseline: preprocess {base['pre'][-1]['wall']:.2f} s; edits "
          + ", ".join(f"{e['wall']:.3f} s" for e in edits), flush=True)


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"(bench took {time.perf_counter() - t0:.0f} s)")

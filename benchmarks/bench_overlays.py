"""What the default overlays (title, colour bar, scale bar, north arrow) cost a cold
render: the import of each way to draw them, and one compose of a 1280×720 picture.

    python benchmarks/bench_overlays.py STORE [--runs N] [--baseline-tree DIR]

In fresh processes, in turns (the order reversed every other run): the imports a
candidate adds to what a render has loaded anyway (numpy, Pillow, VTK's rendering
modules): Pillow's ImageDraw and ImageFont with a DejaVu face loaded; VTK's text and
scalar-bar actors (``vtkRenderingFreeType``, ``vtkRenderingAnnotation``); matplotlib's
figure and Agg canvas. Then ``compose`` of this tree (and of ``--baseline-tree DIR``, a
commit's ``geoterrain/`` with its ``cli/`` copied in as ``geoterrain/cli/``) on the
store's overview: the import of ``geoterrain.rendering.overlays``, the first layout
(its text measured) and the first compose, each alone (CPU). Medians; load printed.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

BASE = ("import time, numpy, PIL.Image, vtkmodules.vtkRenderingOpenGL2, "
        "vtkmodules.vtkRenderingCore\n")
IMPORTS = {
    "Pillow ImageDraw + ImageFont (a DejaVu face)":
        "import importlib.util, os\nfrom PIL import ImageDraw, ImageFont\n"
        "d = importlib.util.find_spec('matplotlib').submodule_search_locations[0]\n"
        "ImageFont.truetype(os.path.join(d, 'mpl-data/fonts/ttf/DejaVuSans.ttf'), 12)\n",
    "VTK text + scalar bar actors":
        "import vtkmodules.vtkRenderingFreeType, vtkmodules.vtkRenderingAnnotation\n"
        "vtkmodules.vtkRenderingAnnotation.vtkScalarBarActor()\n"
        "vtkmodules.vtkRenderingCore.vtkTextActor()\n",
    "matplotlib figure + Agg canvas":
        "import matplotlib.figure, matplotlib.backends.backend_agg\n",
}
TIMED = "c0 = time.process_time()\n{code}print(time.process_time() - c0)\n"

COMPOSE = """
import json, sys, time
import numpy as np
import geoterrain
import geoterrain.rendering.textures  # what overlays imports that a render needs anyway
c0 = time.process_time()
from geoterrain.rendering.overlays import compose, layout_for
c1 = time.process_time()
from geoterrain.rendering.scene import overview
with geoterrain.open(sys.argv[1]) as t:
    t.tile(t.grid.top_level, 0, 0)  # numba's first call, paid by any render, before
    c2 = time.process_time()
    layout_for(t, (1280, 720), title="Synthetic fBm")  # the text measured
    c3 = time.process_time()
    v = overview(t, (1280, 720), title="Synthetic fBm")
    img = np.full((720, 1280, 3), 200, np.uint8)
    c4 = time.process_time()
    compose(img, v, t, title="Synthetic fBm")
    c5 = time.process_time()
print(json.dumps({"import": c1 - c0, "layout": c3 - c2, "compose": c5 - c4,
                  "matplotlib": "matplotlib" in sys.modules}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--baseline-tree")
    a = ap.parse_args()
    jobs = {f"import: {k}": ([sys.executable, "-c", BASE + TIMED.format(code=c)], None)
            for k, c in IMPORTS.items()}
    trees = {"compose: this tree": ROOT}
    if a.baseline_tree:
        trees["compose: baseline"] = os.path.abspath(a.baseline_tree)
    for k, tree in trees.items():
        jobs[k] = ([sys.executable, "-c", COMPOSE, os.path.abspath(a.store)], tree)
    res: dict[str, list] = {k: [] for k in jobs}
    loads = []
    for run in range(a.runs + 1):  # the first, unmeasured: files in the page cache
        for k in (list(jobs) if run % 2 else list(jobs)[::-1]):
            cmd, tree = jobs[k]
            env = dict(os.environ)
            if tree:
                env["PYTHONPATH"] = tree
            loads.append(os.getloadavg()[0])
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True,
                                 cwd=tempfile.gettempdir()).stdout.strip().splitlines()[-1]
            if run:
                res[k].append(json.loads(out) if out.startswith("{") else float(out))
    med = statistics.median
    print(f"{a.runs} runs each, in turns; load {min(loads):.1f}–{max(loads):.1f}\n")
    print("| what | CPU median s |\n|---|---|")
    for k, r in res.items():
        if k.startswith("import"):
            print(f"| {k} | {med(r):.3f} |")
        else:
            print(f"| {k}: import overlays | {med(x['import'] for x in r):.3f} |")
            print(f"| {k}: first layout (its text measured) | "
                  f"{med(x['layout'] for x in r):.3f} |")
            print(f"| {k}: first compose, 1280×720 (matplotlib imported: "
                  f"{r[0]['matplotlib']}) | {med(x['compose'] for x in r):.3f} |")


if __name__ == "__main__":
    main()

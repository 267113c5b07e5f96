"""Static-mesh triangles against pymartini and pydelatin on DEMs that are not (2^n+1)²
(a script, not a test).

For each DEM and e ∈ {1, 5, 20, 100}:

- pymartini ``get_mesh(e)`` on the grid padded by repeating the last row and column (the
  padding Martini uses); its error is then measured over the valid samples;
- ours: ``static_selection(that measured error)``, with the padding replicated and the mesh
  clipped to the data (the default), and with the nodata padding of every other strategy
  (``rtin.EDGE_PADDING = False``);
- pydelatin's greedy TIN of the unpadded DEM at e, against ours at the same e.

Every error is measured by :func:`geoterrain.testing.measure.vertical_error` (barycentric, over the
valid samples, in grid space), independently of the code that selects the meshes.
Triangle counts are exact, so one run is enough.

Usage: ``python benchmarks/bench_triangles.py [DEM ...]`` (default: the Fuji tile and
srtm1_japan from ../shared/dems, and a synthetic 700 × 900 fBm).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.lod import rtin
from geoterrain.testing.measure import vertical_error

DEMS = Path(__file__).resolve().parents[1].parent / "shared" / "dems"
ERRORS = (1.0, 5.0, 20.0, 100.0)


def measure(t, Z: np.ndarray, valid: np.ndarray, e: float) -> tuple[int, float, int]:
    """Our static mesh at ``e``: triangles, measured max error, uncovered valid samples."""
    sel = t.static_selection(e)
    f = sel.surface_faces()
    err = vertical_error(np.asarray(sel.ij), f, np.asarray(sel.mesh.points)[:, 2], Z, valid)
    return len(f), err.max, err.n_uncovered_valid


def run(t, name: str) -> None:
    from pymartini import Martini

    try:
        from pydelatin import Delatin
    except ImportError:  # pragma: no cover
        Delatin = None
    g = t.grid
    N, H, W = g.size, g.rows, g.cols
    _, _, Zd = t.scene_xyz()  # (H, W), NaN where invalid
    Z = g.pad(Zd, np.nan)
    valid = np.isfinite(Z)
    zp = np.pad(Zd, ((0, N - H), (0, N - W)), mode="edge")
    tile = Martini(N).create_tile(zp.astype(np.float32).ravel())
    print(f"\n### {name}: {H}×{W} in {N}², {t.frame.kind} frame\n")
    print("| e | pymartini tris | its measured error | ours (replicated) tris | ratio | "
          "measured / uncovered | ours (nodata) tris | ratio | pydelatin tris at e | "
          "ours at e / pydelatin |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for e in ERRORS:
        mv, mf = tile.get_mesh(e)
        v = np.asarray(mv, np.int64).reshape(-1, 2)
        ij = np.stack([v[:, 1], v[:, 0]], 1)
        f = np.asarray(mf, np.int64).reshape(-1, 3)
        pm = vertical_error(ij, f, zp[ij[:, 0], ij[:, 1]].astype(float), Z, valid).max
        ours, err, unc = measure(t, Z, valid, pm)
        rtin.EDGE_PADDING = False
        try:
            nod = measure(t, Z, valid, pm)[0]
        finally:
            rtin.EDGE_PADDING = True
        cells = [f"{e:g}", f"{len(f)}", f"{pm:.3f}", f"{ours}", f"**{ours / len(f):.2f}**",
                 f"{err:.3f} / {unc}", f"{nod}", f"{nod / len(f):.2f}"]
        if Delatin is not None and np.isfinite(Zd).all():
            dl = Delatin(Zd.astype(np.float32), max_error=e)
            at_e = measure(t, Z, valid, e)[0]
            cells += [f"{len(dl.triangles)}", f"{at_e / len(dl.triangles):.2f}"]
        else:
            cells += ["–", "–"]
        print("| " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dems", nargs="*")
    a = ap.parse_args()
    d = tempfile.mkdtemp()
    dems = a.dems or [str(p) for p in (DEMS / "fuji_terrain_rgb.png",
                                       DEMS / "srtm1_japan.tif") if p.exists()]
    if not a.dems:
        from geoterrain.ingest.synth import generate, write_geotiff

        dems.append(write_geotiff(os.path.join(d, "fbm700x900.tif"),
                                  generate("fbm", 1025, seed=7)[:700, :900]))
    for k, dem in enumerate(dems):
        store = geoterrain.preprocess(dem, os.path.join(d, f"s{k}.geoterrain"))
        with geoterrain.open(store) as t:
            run(t, os.path.basename(str(dem)))


if __name__ == "__main__":
    main()

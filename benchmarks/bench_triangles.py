"""Static-mesh triangles against pymartini and pydelatin on DEMs that are not (2^n+1)²
(a script, not a test).

For each DEM and e ∈ {1, 5, 20, 100}:

- pymartini ``get_mesh(e)`` on the grid padded by repeating the last row and column (the
  padding Martini uses); its error is then measured over the valid samples;
- ours: ``static_selection(that measured error)``, with the padding replicated and the mesh
  clipped to the data (the default), and with the nodata padding of every other strategy
  (``rtin.EDGE_PADDING = False``);
- pydelatin's greedy TIN of the unpadded DEM at e, against ours at the same e;
- the TIN table (e ∈ {1, 5, 20}): pydelatin at e, its error measured, then our TIN
  (``static_selection(that measured error, mesher="tin")``, the whole seam: heights read,
  mesh, PolyData) at it: triangles, the TIN's measured error and uncovered samples, and
  the times, pydelatin's and ours alternating (``--repeat`` runs), medians. With
  ``--tin-meshers tin,tin-full`` each TIN mesher has its row, all timed in the same
  alternation (tin-full: the collapse pass unbounded).

Every error is measured by :func:`geoterrain.testing.measure.vertical_error` (barycentric, over the
valid samples, in grid space), independently of the code that selects the meshes.
Triangle counts are exact, so one run is enough; times are medians.

Usage: ``python benchmarks/bench_triangles.py [DEM ...] [--tin-only] [--fbm N] [--repeat R]
[--tin-meshers tin,tin-full] [--tin-errors 5,20]``
(default: the Fuji tile and srtm1_japan from ../shared/dems, and a synthetic fBm,
700 × 900 or N × N with ``--fbm N``, seed 7).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.lod import rtin
from geoterrain.testing.measure import vertical_error

DEMS = Path(__file__).resolve().parents[1].parent / "shared" / "dems"
ERRORS = (1.0, 5.0, 20.0, 100.0)
TIN_ERRORS = (1.0, 5.0, 20.0)


def measure(t, Z: np.ndarray, valid: np.ndarray, e: float) -> tuple[int, float, int]:
    """Our static mesh at ``e``: triangles, measured max error, uncovered valid samples."""
    sel = t.static_selection(e)
    f = sel.surface_faces()
    err = vertical_error(np.asarray(sel.ij), f, np.asarray(sel.mesh.points)[:, 2], Z, valid)
    return len(f), err.max, err.n_uncovered_valid


def run_tin(t, name: str, repeat: int, extra: bool = True, meshers=("tin",),
            errors=TIN_ERRORS) -> None:
    """Our TIN(s) against pydelatin at pydelatin's measured error: triangles and times."""
    from pydelatin import Delatin

    g = t.grid
    H, W = g.rows, g.cols
    _, _, Zd = t.scene_xyz()
    Z = g.pad(Zd, np.nan)
    valid = np.isfinite(Z)
    if not valid[:H, :W].all():
        print(f"\n### {name}: has nodata, pydelatin cannot take it\n")
        return
    z32 = Zd.astype(np.float32)
    print(f"\n### {name}: {H}×{W}, TIN against pydelatin (load {os.getloadavg()[0]:.2f}, "
          f"{time.strftime('%H:%M:%S', time.gmtime())} UTC)\n")
    print("| e | mesher | pydelatin tris | its measured error | TIN tris at it | ratio | TIN "
          "measured / uncovered | pydelatin ms | TIN ms | time ratio | TIN tris at e | rtin "
          "tris at e |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for e in errors:
        dl = Delatin(z32, max_error=e)
        v = np.asarray(dl.vertices)
        ij = np.stack([H - 1 - v[:, 1], v[:, 0]], 1).astype(np.int64)  # its y runs north
        f = np.asarray(dl.triangles, np.int64)
        pm = vertical_error(ij, f, Zd[ij[:, 0], ij[:, 1]], Z, valid).max
        td, to = [], {m: [] for m in meshers}
        sel = {}
        for _ in range(repeat):  # alternating, so all see the same load
            t0 = time.perf_counter()
            dl = Delatin(z32, max_error=e)
            td.append(time.perf_counter() - t0)
            for m in meshers:
                t0 = time.perf_counter()
                sel[m] = t.static_selection(pm, mesher=m)
                to[m].append(time.perf_counter() - t0)
        md = statistics.median(td) * 1e3
        for m in meshers:
            tf = sel[m].surface_faces()
            err = vertical_error(np.asarray(sel[m].ij), tf, np.asarray(sel[m].mesh.points)[:, 2],
                                 Z, valid)
            at_e = t.static_selection(e, mesher=m).stats["triangles"] if extra else "–"
            rt = t.static_selection(e).stats["triangles"] if extra else "–"
            mo = statistics.median(to[m]) * 1e3
            print("| " + " | ".join([
                f"{e:g}", m, f"{len(f)}", f"{pm:.6f}", f"{len(tf)}",
                f"**{len(tf) / len(f):.4f}**",
                f"{err.max:.6f} ({'≤' if err.max <= pm * (1 + 1e-12) else '>'} it) / "
                f"{err.n_uncovered_valid}",
                f"{md:.0f}", f"{mo:.0f}",
                f"**{mo / md:.2f}**", f"{at_e}", f"{rt}"]) + " |", flush=True)
    print(f"\n(load after: {open('/proc/loadavg').read().split()[0]}, "
          f"{time.strftime('%H:%M:%S', time.gmtime())} UTC)")


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
    ap.add_argument("--tin-only", action="store_true", help="only the TIN / pydelatin table")
    ap.add_argument("--fbm", type=int, default=0, help="the synthetic fBm's side (N × N)")
    ap.add_argument("--fbm-only", action="store_true", help="only the synthetic fBm")
    ap.add_argument("--no-extra", action="store_true",
                    help="without the TIN and rtin counts at e (two meshes fewer per e)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each (median)")
    ap.add_argument("--tin-meshers", default="tin",
                    help="the TIN meshers timed against pydelatin, comma-separated "
                         "(tin, tin-full)")
    ap.add_argument("--tin-errors", default="1,5,20",
                    help="the TIN table's errors, comma-separated (default 1,5,20)")
    a = ap.parse_args()
    d = tempfile.mkdtemp()
    dems = a.dems or [str(p) for p in (DEMS / "fuji_terrain_rgb.png",
                                       DEMS / "srtm1_japan.tif") if p.exists()
                      and not a.fbm_only]
    if not a.dems:
        from geoterrain.ingest.synth import generate, write_geotiff

        if a.fbm:
            dems.append(write_geotiff(os.path.join(d, f"fbm{a.fbm}.tif"),
                                      generate("fbm", a.fbm, seed=7)))
        else:
            dems.append(write_geotiff(os.path.join(d, "fbm700x900.tif"),
                                      generate("fbm", 1025, seed=7)[:700, :900]))
    for k, dem in enumerate(dems):
        # the square (pymartini and the edge-padded static mesh need it)
        store = geoterrain.preprocess(dem, os.path.join(d, f"s{k}.geoterrain"), root_grid=False)
        with geoterrain.open(store) as t:
            if not a.tin_only:
                run(t, os.path.basename(str(dem)))
            run_tin(t, os.path.basename(str(dem)), a.repeat, not a.no_extra,
                    tuple(m.strip() for m in a.tin_meshers.split(",") if m.strip()),
                    tuple(float(x) for x in a.tin_errors.split(",") if x.strip()))


if __name__ == "__main__":
    main()

"""Horizon culling: what it removes, what it loses (nothing), and what it saves.

Usage:
    python benchmarks/bench_occlusion.py --check [--views 104]
    python benchmarks/bench_occlusion.py --store fbm4097.geoterrain [--views 24] [--runs 3]

``--check``: low views (:func:`geoterrain.bench.harness.ground_views`) over synthetic DEMs and
the shared real ones (``../shared/dems``, when present), preprocessed with 16-sample
tiles. For each view the ray-march oracle (:func:`geoterrain.testing.reference.visible_samples`)
finds the valid samples the eye sees; every strategy checked must draw all of them
(the count lost must be 0). A level-0 tile is hidden when none of its samples in the
frustum is visible; the table gives how many of those culling removed.

``--store``: the same kind of views over a big store, each selected cold (the store
opened anew, so decoding counts) and warm, with culling on and off, alternating. Medians
of triangles, tiles decoded and selection time at τ = 1.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain import lod
from geoterrain.bench.harness import ground_views
from geoterrain.ingest.synth import generate
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import tile_index
from geoterrain.testing.measure import mesh_heights_on_grid
from geoterrain.testing.reference import visible_samples

DEMS = Path(__file__).resolve().parents[1] / ".." / "shared" / "dems"
REAL = ("fuji_terrain_rgb.png", "st_helens_terrain_rgb.png", "terrarium.png",
        "srtm3_pysheds.tif", "srtm1_japan.tif", "roi_epsg3089.tif")


def _synthetic(tmp: Path) -> list[tuple[str, Path]]:
    from geoterrain.ingest.synth import write_geotiff

    out = []
    for name, n, seed, holes in (("fbm 513²", 513, 2, False), ("fbm 257² with nodata", 257, 7,
                                                                  True)):
        z = generate("fbm", n, seed=seed)
        z = 600.0 * (z - z.min()) / np.ptp(z)
        if holes:
            z[80:110, 140:180] = -9999.0
            z[200:, :40] = -9999.0
        out.append((name, write_geotiff(tmp / f"s{n}.tif", z, spacing=30.0 if n > 300 else 10.0,
                                        nodata=-9999.0 if holes else None)))
    return out


def check(n_views: int, strategies: tuple[str, ...]) -> None:
    tmp = Path(tempfile.mkdtemp())
    sources = _synthetic(tmp) + [(n, DEMS / n) for n in REAL if (DEMS / n).is_file()]
    per = -(-n_views // len(sources))
    print(f"{per} views on each of {len(sources)} DEMs; strategies {', '.join(strategies)}\n")
    print("| DEM | views | lost visible samples | hidden level-0 tiles | culled | share |")
    print("|---|---|---|---|---|---|")
    tot = [0, 0, 0, 0]
    for name, src in sources:
        kw = {"pixel_size": 10.0} if str(src).endswith(".png") else {}
        t = geoterrain.open(geoterrain.preprocess(src, tmp / f"{Path(src).stem}.geoterrain",
                                                  tile_size=16, **kw))
        X, Y, Z = t.scene_xyz()
        valid = np.isfinite(Z)
        Zt = np.where(valid, Z, 0.0)
        P = np.stack([X, Y, Zt], -1)
        ix = tile_index(t)
        S = 1 << t.grid.t
        lost = hidden = culled = 0
        for view, (i, j) in ground_views(X, Y, Z, per, seed=len(name)):
            inside = valid & ((P @ view.planes[:, :3].T + view.planes[:, 3]) >= 0).all(-1)
            vis = visible_samples(Zt, valid, (float(i), float(j)), float(view.eye[2]), inside)
            for s in strategies:
                sel = lod.select(t, view, 1.0, s, reuse=False)
                f = sel.surface_faces()
                vz = np.asarray(sel.mesh.points)[:, 2] if len(f) else np.zeros(0)
                _, cov = mesh_heights_on_grid(sel.ij, f, vz, Z.shape)
                lost += int((vis & ~cov).sum())
            h = hidden_rows(t, view)
            for r in np.flatnonzero(ix.keys[:, 0] == 0):
                _, x, y = ix.keys[r]
                win = (slice(y * S, y * S + S + 1), slice(x * S, x * S + S + 1))
                if inside[win].any() and not vis[win].any():
                    hidden += 1
                    culled += bool(h[r])
        tot = [tot[0] + per, tot[1] + lost, tot[2] + hidden, tot[3] + culled]
        print(f"| {name} | {per} | {lost} | {hidden} | {culled} | "
              f"{culled / max(hidden, 1):.0%} |", flush=True)
    print(f"| **all** | {tot[0]} | {tot[1]} | {tot[2]} | {tot[3]} | "
          f"{tot[3] / max(tot[2], 1):.0%} |")


def savings(store: str, n_views: int, runs: int, strategies: tuple[str, ...]) -> None:
    t = geoterrain.open(store)
    X, Y, Z = t.scene_xyz()
    views = [v for v, _ in ground_views(X, Y, Z, n_views, seed=5, size=(1280, 720),
                                        fov_y_deg=30.0)]
    del X, Y, Z
    print(f"{store}: {n_views} low views × {runs} runs, 1280×720, τ = 1, medians over all "
          "of them\n")
    print("| strategy | culling | triangles | tiles decoded (cold) | cold ms | warm ms | "
          "tiles culled |")
    print("|---|---|---|---|---|---|---|")
    for s in strategies:
        rows = {True: [], False: []}
        for v in views:
            for _ in range(runs):
                for on in (True, False):  # alternate: the machine is shared and noisy
                    cold_t = geoterrain.open(store)
                    t0 = time.perf_counter()
                    sel = lod.select(cold_t, v, 1.0, s, reuse=False, occlusion=on)
                    cold = (time.perf_counter() - t0) * 1e3
                    t0 = time.perf_counter()
                    lod.select(cold_t, v, 1.0, s, reuse=False, occlusion=on)
                    warm = (time.perf_counter() - t0) * 1e3
                    n_cull = int(hidden_rows(cold_t, v).sum()) if on else 0
                    rows[on].append((sel.stats["triangles"], sel.stats["tiles_decoded"],
                                     cold, warm, n_cull))
                    cold_t.close()
        for on in (True, False):
            a = np.array(rows[on], np.float64)
            med = [statistics.median(a[:, k]) for k in range(5)]
            print(f"| {s} | {'on' if on else 'off'} | {med[0]:.0f} | {med[1]:.0f} | "
                  f"{med[2]:.1f} | {med[3]:.1f} | {med[4]:.0f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--store")
    ap.add_argument("--views", type=int, default=None)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--strategies", default="rtin,chunked")
    a = ap.parse_args()
    strategies = tuple(a.strategies.split(","))
    if not a.check and not a.store:
        ap.error("give --check and/or --store")
    if a.check:
        check(a.views or 104, strategies)
    if a.store:
        savings(a.store, a.views or 24, a.runs, strategies)


if __name__ == "__main__":
    sys.exit(main())

"""Cost of the metric bound on geographic grids (issue 16, item 5), before/after in one run.

For each DEM the store is built twice in this run: "before" with the metric term switched
off (δ and r as in grid-index space), "after" as preprocess builds it. Reported: the
radii-stage time (where the term is computed), static triangles at e ∈ {1, 5, 20}, rtin
triangles at τ = 1 over a short flight, and for projected/pixel DEMs whether δ and r are
bit-identical (they must be: the term is not computed there).

    PYTHONPATH=. python benchmarks/bench_metric.py [--size 513] [--views 6]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import geoterrain.preprocessing.pipeline as pp
from geoterrain.bench.harness import flight
from geoterrain.ingest.synth import generate
from geoterrain.preprocessing import levelblobs, surface
from geoterrain.terrain import Terrain

DEMS = Path(__file__).resolve().parents[1] / ".." / "shared" / "dems"


def _tif(path, z, crs, origin, spacing):
    import rasterio
    from rasterio.transform import from_origin

    with rasterio.open(path, "w", driver="GTiff", height=z.shape[0], width=z.shape[1], count=1,
                       dtype="float32", crs=crs,
                       transform=from_origin(*origin, spacing, spacing)) as dst:
        dst.write(z.astype(np.float32), 1)
    return path


def _build(src, dst, metric: bool):
    real = surface.metric_bounds  # called by surface.vertex_bounds and levelblobs.tile_blobs
    if not metric:
        surface.metric_bounds = levelblobs.metric_bounds = lambda d, r, *a, **k: (d, r)
    times: dict[str, float] = {}
    try:
        pp.preprocess(src, dst, overwrite=True, timings=times)
    finally:
        surface.metric_bounds = levelblobs.metric_bounds = real
    return Terrain(dst), times  # the store holds no timings


def _same_bounds(a: Terrain, b: Terrain) -> bool:
    return all(np.array_equal(a.tile_delta(*k), b.tile_delta(*k))
               and np.array_equal(a.tile_radius(*k), b.tile_radius(*k)) for k in a.tile_keys())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=513)
    ap.add_argument("--views", type=int, default=6)
    a = ap.parse_args()
    d = Path(tempfile.mkdtemp())
    z = generate("fbm", a.size, seed=7).astype(np.float64)
    z = (z - z.min()) / np.ptp(z) * 1500.0
    dems = {
        "synthetic 2°×2° at 60° N (EPSG:4326)": _tif(d / "g.tif", z, "EPSG:4326", (10.0, 61.0),
                                                      2.0 / (a.size - 1)),
        "synthetic UTM (EPSG:32633)": _tif(d / "u.tif", z, "EPSG:32633", (5e5, 5e6), 30.0),
    }
    for name in ("srtm1_japan.tif", "roi_epsg3089.tif"):
        if (DEMS / name).is_file():
            dems[name] = DEMS / name
    print("| DEM | kind | radii stage s (before → after) | static e=1 | e=5 | e=20 | "
          "rtin τ=1 (sum over views) | δ, r bit-identical |")
    print("|---|---|---|---|---|---|---|---|")
    for name, src in dems.items():
        tb, times_b = _build(src, d / "before.geoterrain", metric=False)
        ta, times_a = _build(src, d / "after.geoterrain", metric=True)
        X, Y, Z = ta.scene_xyz()
        ok = np.isfinite(Z)
        lo = [X[ok].min(), Y[ok].min(), Z[ok].min()]
        hi = [X[ok].max(), Y[ok].max(), Z[ok].max()]
        views = [v for _, v in flight(lo, hi, n_views=a.views)]
        cells = []
        for e in (1.0, 5.0, 20.0):
            nb = tb.static_selection(e).stats["triangles"]
            na = ta.static_selection(e).stats["triangles"]
            cells.append(f"{nb} → {na} ({na / nb:.3f}×)")
        rb = sum(tb.select(v, 1.0, "rtin", reuse=False).stats["triangles"] for v in views)
        ra = sum(ta.select(v, 1.0, "rtin", reuse=False).stats["triangles"] for v in views)
        sb = times_b["radii"]
        sa = times_a["radii"]
        same = _same_bounds(tb, ta)
        print(f"| {name} | {ta.frame.kind} | {sb:.2f} → {sa:.2f} | {' | '.join(cells)} | "
              f"{rb} → {ra} ({ra / rb:.3f}×) | {'yes' if same else 'no'} |", flush=True)
        if ta.frame.kind != "geographic":
            assert same, f"{name}: δ or r changed on an affine grid"


if __name__ == "__main__":
    main()

"""Store size per component against the lossless DEFLATE + predictor GeoTIFF (issue 12).

For every DEM of ``../shared/dems`` (skipped when absent), preprocess at the default
settings (lossless, t = 6, zstd 9) into a temporary folder and tabulate the bytes per
component (heights, δ, r, normals, index/other), the reference GeoTIFF of the same
heights (``COMPRESS=DEFLATE``, ``PREDICTOR=2``; 3 for floats) and the ratio. Target (issue
51): the store at most 1.0× the reference. ``GEOTERRAIN_TEST_DEMS`` names another folder
of DEMs, as for the tests.

Run from the project root::

    python benchmarks/bench_size.py [--tile-size 64] [--codec-error EPS] [--lod]

``--lod`` also prices the stored-bound format: the same store with δ and r rewritten
as version-1 blobs (every sample, float16 from the exact δ and r of the decoded
heights: the layout before the size levers) against the store as written, on 8
orbiting views at τ = 1 and 2 px (rtin): triangles (sum over the views) and ratio.
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import sqlite3
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import geoterrain  # noqa: E402
from geoterrain.ingest.units import tile_from_path  # noqa: E402
from geoterrain.store.size import size_report  # noqa: E402

DEMS = Path(os.environ.get("GEOTERRAIN_TEST_DEMS")
            or Path(__file__).resolve().parents[2] / "shared" / "dems")
NAMES = ("srtm3_pysheds.tif", "srtm1_japan.tif", "roi_epsg3089.tif", "fuji_terrain_rgb.png",
         "st_helens_terrain_rgb.png", "terrarium.png")


def exact_v1_copy(store: Path, dst: Path) -> Path:
    """``store`` with δ and r as version-1 blobs of the exact values (float16, rounded up)."""
    import zstandard

    from geoterrain.bounds.delta import vertex_errors
    from geoterrain.bounds.radii import vertex_radii
    from geoterrain.bounds.vertexdata import encode_bounds
    from geoterrain.store.keys import blob_key
    from geoterrain.store.reader import StoreReader
    from geoterrain.store.schema import blob_crc

    shutil.copy(store, dst)
    with geoterrain.open(store) as t:
        g = t.grid
        X, Y = t.frame.grid_xy(g.size)
        h, v = t.level_heights(0)
        Z = np.where(v, t.frame.z(h), np.nan)
        exact = {"delta": vertex_errors(Z, v), "radius": vertex_radii(X, Y, Z, v)}
        keys = list(t.tile_info)
    cctx = zstandard.ZstdCompressor(level=3)
    reader = StoreReader(dst)
    table = reader.table()
    reader.close()
    rowid = dict(zip(table.blobs.tolist(), table.ids.tolist(), strict=True))
    con = sqlite3.connect(dst)
    for k in keys:
        ix = np.ix_(g.tile_rows(k[0], k[2]), g.tile_cols(k[0], k[1]))
        for kind, a in exact.items():
            blob = encode_bounds(a[ix], cctx)
            con.execute("UPDATE blobs SET data=?, crc32=? WHERE rowid = ?",
                        (blob, blob_crc(k, kind, blob), rowid[blob_key(k, kind)]))
    con.commit()
    con.execute("VACUUM")
    con.close()
    return dst


def views(t, n=8):
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    r = float(np.linalg.norm(hi[:2] - lo[:2]))
    return [geoterrain.View(tuple(c + [0.6 * r * np.cos(a), 0.6 * r * np.sin(a), 0.3 * r]),
                            tuple(c), size=(1280, 720))
            for a in 2 * np.pi * np.arange(n) / n]


def lod_cost(store: Path, d: Path, name: str) -> str:
    old = exact_v1_copy(store, d / f"{name}.v1.geoterrain")
    out = []
    for tau in (1.0, 2.0):
        tri = []
        for s in (old, store):
            with geoterrain.open(s) as t:
                tri.append(sum(t.select(v, tau).stats["triangles"] for v in views(t)))
        out.append(f"τ={tau:g}: {tri[0]} → {tri[1]} ({tri[1] / tri[0]:.3f}×)")
    return f"{name}: v1 store {old.stat().st_size / 1e3:.1f} kB; " + "; ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tile-size", type=int, default=64)
    ap.add_argument("--codec-error", type=float, default=None)
    ap.add_argument("--lod", action="store_true", help="triangles against version-1 bounds")
    a = ap.parse_args()
    lod_lines = []
    logging.getLogger("geoterrain").setLevel(logging.ERROR)
    print("| DEM | samples | heights kB | δ kB | r kB | normals kB | index/other kB | store kB "
          "| GeoTIFF DEFLATE+pred kB | store / GeoTIFF |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for name in NAMES:
            src = DEMS / name
            if not src.exists():
                continue
            # PNG tiles without z/x/y in their name get 1 m pixels (sizes do not depend on it)
            px = 1.0 if src.suffix == ".png" and tile_from_path(src) is None else None
            # --lod compares with exact δ and r computed on the square's arrays
            store = geoterrain.preprocess(src, Path(d) / f"{name}.geoterrain",
                                          tile_size=a.tile_size, codec_error=a.codec_error,
                                          pixel_size=px, root_grid=not a.lod)
            with geoterrain.open(store) as t:
                r = size_report(t)
                n = t.grid.rows * t.grid.cols
            c = r["components"]
            kb = [c[k] / 1e3 for k in ("heights", "delta", "radius", "normals", "index/other")]
            print(f"| {name} | {n} | " + " | ".join(f"{v:.1f}" for v in kb)
                  + f" | {r['store_bytes'] / 1e3:.1f} | {r['geotiff_deflate_bytes'] / 1e3:.1f}"
                  f" ({r['geotiff_dtype']}) | {r['ratio']:.2f} |", flush=True)
            if a.lod:
                lod_lines.append(lod_cost(store, Path(d), name))
    for line in lod_lines:
        print(line)


if __name__ == "__main__":
    main()

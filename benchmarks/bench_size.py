"""Store size per component against the lossless DEFLATE + predictor GeoTIFF (issue 12).

For every DEM of ``../shared/dems`` (skipped when absent), preprocess at the default
settings (lossless, t = 6, zstd 9) into a temporary folder and tabulate the bytes per
component (heights, δ, r, normals, index/other), the reference GeoTIFF of the same
heights (``COMPRESS=DEFLATE``, ``PREDICTOR=2``; 3 for floats) and the ratio. Target: the
store at most 1.5× the reference.

Run from the project root::

    python benchmarks/bench_size.py [--tile-size 64] [--codec-error EPS]
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geoterrain  # noqa: E402
from geoterrain.storesize import size_report  # noqa: E402
from geoterrain.units import tile_from_path  # noqa: E402

DEMS = Path(__file__).resolve().parents[2] / "shared" / "dems"
NAMES = ("srtm3_pysheds.tif", "srtm1_japan.tif", "roi_epsg3089.tif", "fuji_terrain_rgb.png",
         "st_helens_terrain_rgb.png", "terrarium.png")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tile-size", type=int, default=64)
    ap.add_argument("--codec-error", type=float, default=None)
    a = ap.parse_args()
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
            store = geoterrain.preprocess(src, Path(d) / f"{name}.geoterrain",
                                          tile_size=a.tile_size, codec_error=a.codec_error,
                                          pixel_size=px)
            with geoterrain.open(store) as t:
                r = size_report(t)
                n = t.grid.rows * t.grid.cols
            c = r["components"]
            kb = [c[k] / 1e3 for k in ("heights", "delta", "radius", "normals", "index/other")]
            print(f"| {name} | {n} | " + " | ".join(f"{v:.1f}" for v in kb)
                  + f" | {r['store_bytes'] / 1e3:.1f} | {r['geotiff_deflate_bytes'] / 1e3:.1f}"
                  f" ({r['geotiff_dtype']}) | {r['ratio']:.2f} |")


if __name__ == "__main__":
    main()

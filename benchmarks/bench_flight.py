"""Runtime against measured error over the built-in flight, on a synthetic fbm DEM.

    python benchmarks/bench_flight.py --size 4097 --views 8 --plot flight.png -o flight.csv

Equivalent to ``geoterrain bench --synthetic SIZE``; prints the markdown summary table.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import geoterrain
from geoterrain.bench import harness as bench
from geoterrain.bench.report import format_table, plot, summarise, write_csv
from geoterrain.ingest.synth import generate, write_geotiff


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=4097, help="DEM side in samples (default 4097)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--tau", default="0.5,1,2,4,8")
    ap.add_argument("-o", "--output", help="tidy CSV")
    ap.add_argument("--plot", help="figure (PNG)")
    a = ap.parse_args()
    taus = tuple(float(v) for v in a.tau.split(","))
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        tif = write_geotiff(Path(d) / "fbm.tif", generate("fbm", a.size, seed=a.seed))
        t1 = time.perf_counter()
        store = geoterrain.preprocess(tif, Path(d) / "fbm.geoterrain")
        pre = time.perf_counter() - t1
        with geoterrain.open(store) as t:
            res = bench.run(t, n_views=a.views, taus=taus, source=f"fbm {a.size}²",
                            preprocess_s=round(pre, 3), store_bytes=os.path.getsize(store))
        if a.output:
            write_csv(res.rows, a.output)
        if a.plot:
            plot(res.rows, a.plot, title=f"fbm {a.size}² (seed {a.seed})")
        print(f"# fbm {a.size}²: preprocess {pre:.1f} s, bench {res.wall_s:.1f} s, "
              f"total {time.perf_counter() - t0:.1f} s")
        print(format_table(summarise(res.rows)))


if __name__ == "__main__":
    main()

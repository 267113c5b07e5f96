"""Time opening a store and checking its tile table (what every command does first).

    python benchmarks/bench_open.py STORE [--repeat N]

Prints the median and the fastest of N runs in this process of
``StoreReader(STORE).tiles()``: the schema and metadata checks, the tile table parsed,
every tile's numbers, and the blob keys checked against the tiles and the rowid range.
"""

from __future__ import annotations

import argparse
import statistics
import time

from geoterrain.store import StoreReader


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        r = StoreReader(a.store)
        n = len(r.tiles())
        times.append(time.perf_counter() - t0)
        r.close()
    print(f"{a.store}: {n} tiles, open + tiles() median {statistics.median(times):.3f} s, "
          f"fastest {min(times):.3f} s ({a.repeat} runs)")


if __name__ == "__main__":
    main()

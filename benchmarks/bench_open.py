"""Time opening a store and checking its tile table (what every command does first).

    python benchmarks/bench_open.py STORE [--repeat N]

Prints the median and the fastest of N runs in this process of
``StoreReader(STORE).tiles()`` (the schema and metadata checks, the tile table parsed,
every tile's numbers, and the blob keys checked against the tiles and the rowid range)
and of ``storecheck.check_store`` (the metadata's and every tile's rules), which
``geoterrain.open`` runs next.
"""

from __future__ import annotations

import argparse
import statistics
import time

from geoterrain.store.check import check_store
from geoterrain.store.database import StoreReader


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    times, checks = [], []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        r = StoreReader(a.store)
        tiles = r.tiles()
        t1 = time.perf_counter()
        check_store(a.store, r.metadata, tiles)
        times.append(t1 - t0)
        checks.append(time.perf_counter() - t1)
        r.close()
    print(f"{a.store}: {len(tiles)} tiles, open + tiles() median {statistics.median(times):.3f} s, "
          f"fastest {min(times):.3f} s; check_store median {statistics.median(checks):.3f} s, "
          f"fastest {min(checks):.3f} s ({a.repeat} runs)")


if __name__ == "__main__":
    main()

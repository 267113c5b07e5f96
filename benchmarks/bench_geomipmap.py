"""GeoMipMapping's δ_n: each block's exact value (the store's block table) against the
covering level-n tile's error (the bound stores without the table fall back to), on the
same views in the same run, and with morphing on (continuous block levels), with chunked
beside them (a script, not a test).

Each configuration runs ``geoterrain.bench.harness.run`` over its built-in 6-view flight on a
freshly opened store; "tile bound" hides the table (``Terrain.block_errors`` → None), so
``geomipmap`` takes the covering tiles' errors as it does on an older store. ρ is
measured by :func:`geoterrain.testing.measure.screen_space_error`, independently of the
selection. The three geomipmap modes rotate (each first in turn), ``--runs`` times each;
triangle counts are exact, select times are medians over every run and view.

Usage: ``PYTHONPATH=. python benchmarks/bench_geomipmap.py STORE [STORE ...]
[--taus 1,2,4] [--views 6] [--runs 2]``
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import geoterrain
from geoterrain.bench import harness as bench
from geoterrain.lod import geomipmap

MODES = ("tile bound", "exact", "exact, morph")


def run(store: str, mode: str, taus: tuple[float, ...], views: int) -> list[dict]:
    """bench rows of one configuration: one of ``MODES`` or ``chunked``."""
    with geoterrain.open(store) as t:
        if mode == "tile bound":
            t.block_errors = lambda: None  # as a store written before the table
        t.forget(geomipmap.__name__)
        strategy = "chunked" if mode == "chunked" else "geomipmap"
        return bench.run(t, n_views=views, taus=taus, strategies=(strategy,),
                         morph=mode.endswith("morph")).rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--taus", default="1,2,4")
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--runs", type=int, default=2)
    a = ap.parse_args(argv)
    taus = tuple(float(x) for x in a.taus.split(","))
    print("| store | τ | δ_n | triangles (median) | select ms (median) | ρ max px |")
    print("|---|---|---|---|---|---|")
    for store in a.stores:
        rows: dict[str, list[dict]] = {}
        for k in range(a.runs):  # rotating, each mode first in turn
            for mode in MODES[k % 3:] + MODES[:k % 3]:
                rows.setdefault(mode, []).extend(run(store, mode, taus, a.views))
        rows["chunked"] = run(store, "chunked", taus, a.views)
        for tau in taus:
            for mode in (*MODES, "chunked"):
                rs = [r for r in rows[mode] if r["tau"] == tau]
                name = "(chunked)" if mode == "chunked" else mode
                print(f"| {Path(store).name} | {tau:g} | {name} | "
                      f"{statistics.median(r['triangles'] for r in rs):,.0f} | "
                      f"{statistics.median(r['select_ms'] for r in rs):.1f} | "
                      f"{max(r['err_max'] for r in rs):.3f} |")


if __name__ == "__main__":
    main()

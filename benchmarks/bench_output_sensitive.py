"""Selection time against the store's size: the same view over a 1025² and an 8193² store.

The big DEM holds the small one in its top-left 1025² corner and is flat
elsewhere, so a view whose frustum sees only that corner asks for (nearly) the
same output from both stores. Selection time should follow the output, not the
store: the issue's target is < 20 % apart.

    python benchmarks/bench_output_sensitive.py [--dir DIR] [--views 12] [--runs 5]

Builds the two stores in DIR (default: a temporary folder) unless they exist.
Reports, per strategy, the median select time and triangles on each store and
their ratio; views alternate between the stores (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile

import numpy as np

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff


def build(d: str) -> tuple[str, str]:
    small, big = os.path.join(d, "small.geoterrain"), os.path.join(d, "big.geoterrain")
    if not (os.path.exists(small) and os.path.exists(big)):
        z = generate("fbm", 1025, seed=21).astype(np.float32)
        b = np.full((8193, 8193), z[-1, -1], np.float32)
        b[:1025, :1025] = z
        geoterrain.preprocess(write_geotiff(os.path.join(d, "small.tif"), z), small)
        geoterrain.preprocess(write_geotiff(os.path.join(d, "big.tif"), b), big)
    return small, big


def views(t, n: int) -> list[geoterrain.View]:
    """Oblique views aimed inside the 1025² corner, their frustum within it."""
    rng = np.random.default_rng(5)
    out = []
    for _ in range(n):
        i, j = rng.uniform(350, 675, 2)
        X, Y = t.frame.xy(np.array([i]), np.array([j]))
        target = np.array([X[0], Y[0], 0.0])
        h = rng.uniform(2500, 4000)
        az = rng.uniform(0, 2 * np.pi)
        eye = target + [0.3 * h * np.cos(az), 0.3 * h * np.sin(az), h]
        out.append(geoterrain.View(tuple(eye), tuple(target), size=(1280, 720)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir")
    ap.add_argument("--views", type=int, default=12)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--strategies", default="rtin,chunked")
    a = ap.parse_args()
    small, big = build(a.dir or tempfile.mkdtemp())
    ts, tb = geoterrain.open(small), geoterrain.open(big)
    vs, vb = views(ts, a.views), views(tb, a.views)
    print(f"{a.views} views inside the 1025² corner, 1280×720, τ = 1, median of {a.runs} runs\n")
    print("| strategy | 1025² ms | 8193² ms | ratio | 1025² triangles | 8193² triangles |")
    print("|---|---|---|---|---|---|")
    for s in a.strategies.split(","):
        for v1, v2 in zip(vs, vb, strict=True):  # warm: decode, compile
            ts.select(v1, 1.0, s, reuse=False)
            tb.select(v2, 1.0, s, reuse=False)
        ms_s, ms_b, tri_s, tri_b = [], [], [], []
        for _ in range(a.runs):
            for v1, v2 in zip(vs, vb, strict=True):
                r1 = ts.select(v1, 1.0, s, reuse=False)
                r2 = tb.select(v2, 1.0, s, reuse=False)
                ms_s.append(r1.stats["select_ms"])
                ms_b.append(r2.stats["select_ms"])
                tri_s.append(r1.stats["triangles"])
                tri_b.append(r2.stats["triangles"])
        a1, a2 = statistics.median(ms_s), statistics.median(ms_b)
        print(f"| {s} | {a1:.1f} | {a2:.1f} | {a2 / a1:.2f} | {statistics.median(tri_s):.0f} | "
              f"{statistics.median(tri_b):.0f} |")


if __name__ == "__main__":
    main()
